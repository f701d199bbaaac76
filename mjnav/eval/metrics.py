"""Episode metrics and their aggregate over a scenario set (spec §10), plus table writers.

Pure numpy. An episode is described by its sampled trajectory: positions and velocities at
the ``T + 1`` control instants ``t_k = k·t_c`` (``k = 0`` is the reset state), the control
period ``t_c`` and its :class:`~mjnav.tasks.core.Outcome` value.

Per episode (units in brackets):

* ``time_s`` = ``T·t_c`` [s]; ``distance_m`` = Σ‖p_{k+1} − p_k‖ [m];
* ``mean_speed`` = mean of ‖v_k‖ over k = 1..T (the instants after each step) [m/s];
* ``abs_acc_sum`` = Σ_k |(‖v_{k+1}‖ − ‖v_k‖)/t_c| over k = 0..T−1 — the speed-magnitude
  finite difference of the paper's Total Abs Acc [m/s² summed over steps];
* ``jerk_rms`` = RMS over k of ‖v_{k+2} − 2v_{k+1} + v_k‖/t_c² [m/s³] (0 for T < 2);
* ``heading_change`` = Σ|Δ direction of travel| between consecutive displacements longer than
  1 mm, a path-irregularity measure [rad];
* minimum clearances (gap between the robot's disc and the nearest wall/obstacle, and the
  nearest pedestrian) [m]; NaN when there was nothing of that kind;
* MPC solve times [ms], fallback and region-failure counts.

The aggregate follows the paper: rates over all episodes; time, distance, speed, Total Abs Acc
over **successful** episodes only (Total Abs Acc is their sum; ``abs_acc_per_episode`` the mean).
"""

from __future__ import annotations

import csv
import dataclasses
import math
from collections.abc import Iterable, Mapping, Sequence
from pathlib import Path
from typing import Any

import numpy as np

from mjnav.eval.intervals import rate_with_interval
from mjnav.eval.social import SOCIAL_COLUMNS

__all__ = [
    "COLUMNS",
    "EpisodeMetrics",
    "aggregate",
    "episode_metrics",
    "format_markdown",
    "rate_with_interval",
    "summary_row",
    "wilson",
    "write_csv",
]

_MIN_STEP = 1e-3  # m: displacements shorter than this carry no heading


@dataclasses.dataclass(frozen=True)
class EpisodeMetrics:
    """Metrics of one episode (see the module docstring for definitions and units)."""

    outcome: str
    steps: int
    time_s: float
    distance_m: float
    mean_speed: float
    abs_acc_sum: float
    jerk_rms: float
    heading_change: float
    min_clearance_obstacles: float = math.nan
    min_clearance_pedestrians: float = math.nan
    solve_times_ms: tuple[float, ...] = ()
    fallbacks: int = 0
    region_failures: int = 0
    scans: int = 0

    def to_dict(self) -> dict[str, Any]:
        """JSON-ready dict (NaN → None, solve times rounded to µs)."""
        out = dataclasses.asdict(self)
        out["solve_times_ms"] = [round(float(t), 3) for t in self.solve_times_ms]
        return {k: (None if isinstance(v, float) and math.isnan(v) else v) for k, v in out.items()}

    @classmethod
    def from_dict(cls, data: Mapping[str, Any]) -> EpisodeMetrics:
        """Inverse of :meth:`to_dict` (None → NaN; unknown keys ignored)."""
        names = {f.name for f in dataclasses.fields(cls)}
        kwargs = {k: (math.nan if v is None else v) for k, v in data.items() if k in names}
        kwargs["solve_times_ms"] = tuple(kwargs.get("solve_times_ms", ()))
        return cls(**kwargs)


def _norms(x: np.ndarray) -> np.ndarray:
    return np.hypot(x[..., 0], x[..., 1])


def _heading_change(positions: np.ndarray) -> float:
    steps = np.diff(positions, axis=0)
    steps = steps[_norms(steps) > _MIN_STEP]
    if len(steps) < 2:
        return 0.0
    heading = np.arctan2(steps[:, 1], steps[:, 0])
    turn = np.angle(np.exp(1j * np.diff(heading)))
    return float(np.sum(np.abs(turn)))


def _jerk_rms(velocities: np.ndarray, dt: float) -> float:
    if len(velocities) < 3:
        return 0.0
    jerk = _norms(np.diff(velocities, n=2, axis=0)) / dt**2
    return float(np.sqrt(np.mean(jerk**2)))


def _min_or_nan(values: np.ndarray | Sequence[float] | None) -> float:
    if values is None:
        return math.nan
    arr = np.asarray(values, dtype=np.float64).ravel()
    arr = arr[np.isfinite(arr)]
    return float(np.min(arr)) if arr.size else math.nan


def episode_metrics(
    positions: np.ndarray,
    velocities: np.ndarray,
    dt: float,
    outcome: str,
    *,
    obstacle_clearances: np.ndarray | Sequence[float] | None = None,
    pedestrian_clearances: np.ndarray | Sequence[float] | None = None,
    solve_times_ms: Sequence[float] = (),
    fallbacks: int = 0,
    region_failures: int = 0,
    scans: int = 0,
) -> EpisodeMetrics:
    """Metrics of one episode.

    Args:
        positions: (T+1, 2) robot positions at the control instants, metres.
        velocities: (T+1, 2) robot velocities at the same instants, m/s.
        dt: Control period t_c, seconds.
        outcome: ``success``, ``collision``, ``timeout`` (or ``running`` if cut short).
        obstacle_clearances: Per-step gaps to walls and static obstacles, metres.
        pedestrian_clearances: Per-step gaps to the nearest pedestrian, metres.
        solve_times_ms: Per-step MPC solve times, milliseconds.
        fallbacks: MPC fallbacks in the episode.
        region_failures: Failed convex-region computations in the episode.
        scans: Region computations in the episode (denominator of the failure rate).

    Returns:
        The :class:`EpisodeMetrics`.

    Raises:
        ValueError: On mismatched shapes, an empty trajectory or a non-positive ``dt``.
    """
    p = np.asarray(positions, dtype=np.float64)
    v = np.asarray(velocities, dtype=np.float64)
    if p.ndim != 2 or p.shape[1] != 2 or p.shape != v.shape or len(p) < 1:
        raise ValueError(f"positions and velocities must both be (T+1, 2), got {p.shape} and {v.shape}")
    if not dt > 0:
        raise ValueError(f"dt must be > 0, got {dt}")
    steps = len(p) - 1
    speed = _norms(v)
    return EpisodeMetrics(
        outcome=str(outcome),
        steps=steps,
        time_s=steps * dt,
        distance_m=float(np.sum(_norms(np.diff(p, axis=0)))),
        mean_speed=float(np.mean(speed[1:])) if steps else 0.0,
        abs_acc_sum=float(np.sum(np.abs(np.diff(speed)) / dt)),
        jerk_rms=_jerk_rms(v, dt),
        heading_change=_heading_change(p),
        min_clearance_obstacles=_min_or_nan(obstacle_clearances),
        min_clearance_pedestrians=_min_or_nan(pedestrian_clearances),
        solve_times_ms=tuple(float(t) for t in solve_times_ms),
        fallbacks=int(fallbacks),
        region_failures=int(region_failures),
        scans=int(scans),
    )


def _mean(values: Iterable[float]) -> float:
    arr = np.asarray(list(values), dtype=np.float64)
    arr = arr[np.isfinite(arr)]
    return float(np.mean(arr)) if arr.size else math.nan


def _clearance_stats(episodes: Sequence[EpisodeMetrics], field: str) -> tuple[float, float]:
    values = np.array([getattr(e, field) for e in episodes], dtype=np.float64)
    values = values[np.isfinite(values)]
    if not values.size:
        return math.nan, math.nan
    return float(np.min(values)), float(np.mean(values))


def _solve_stats(episodes: Sequence[EpisodeMetrics]) -> tuple[float, float]:
    arrays = [np.asarray(e.solve_times_ms, dtype=np.float64) for e in episodes]
    pooled = np.concatenate(arrays) if arrays else np.zeros(0)
    if not pooled.size:
        return math.nan, math.nan
    return float(np.median(pooled)), float(np.percentile(pooled, 99))


def _ratio(num: float, den: float) -> float:
    return num / den if den > 0 else math.nan


def aggregate(episodes: Sequence[EpisodeMetrics]) -> dict[str, float]:
    """Summary over a scenario set (spec §10).

    Args:
        episodes: Per-episode metrics.

    Returns:
        Dict with ``episodes``, ``success_rate``, ``collision_rate``, ``timeout_rate`` (fractions;
        every rate ``X`` comes with its 95 % Wilson interval ``X_lo``, ``X_hi``);
        over successes: ``time_s``, ``distance_m``, ``speed`` (means), ``total_abs_acc`` (sum),
        ``abs_acc_per_episode``, ``jerk_rms`` (means); ``min_clearance_obstacles`` /
        ``min_clearance_pedestrians`` (minimum over all episodes) and their ``mean_*`` (mean of
        the per-episode minima), metres; ``solve_ms_median``, ``solve_ms_p99`` (pooled steps);
        ``fallback_rate`` (per step) and ``region_failure_rate`` (per scan). NaN where undefined.
    """
    n = len(episodes)
    wins = [e for e in episodes if e.outcome == "success"]
    count = {k: sum(e.outcome == k for e in episodes) for k in ("success", "collision", "timeout")}
    obst_min, obst_mean = _clearance_stats(episodes, "min_clearance_obstacles")
    ped_min, ped_mean = _clearance_stats(episodes, "min_clearance_pedestrians")
    solve_median, solve_p99 = _solve_stats(episodes)
    steps, scans = sum(e.steps for e in episodes), sum(e.scans for e in episodes)
    return {
        "episodes": float(n),
        **rate_with_interval("success_rate", count["success"], n),
        **rate_with_interval("collision_rate", count["collision"], n),
        **rate_with_interval("timeout_rate", count["timeout"], n),
        "time_s": _mean(e.time_s for e in wins),
        "distance_m": _mean(e.distance_m for e in wins),
        "speed": _mean(e.mean_speed for e in wins),
        "total_abs_acc": float(sum(e.abs_acc_sum for e in wins)),
        "abs_acc_per_episode": _mean(e.abs_acc_sum for e in wins),
        "jerk_rms": _mean(e.jerk_rms for e in wins),
        "min_clearance_obstacles": obst_min,
        "mean_min_clearance_obstacles": obst_mean,
        "min_clearance_pedestrians": ped_min,
        "mean_min_clearance_pedestrians": ped_mean,
        "solve_ms_median": solve_median,
        "solve_ms_p99": solve_p99,
        **rate_with_interval("fallback_rate", sum(e.fallbacks for e in episodes), steps),
        **rate_with_interval("region_failure_rate", sum(e.region_failures for e in episodes), scans),
    }


# (key, markdown label, markdown format); percentages are stored as fractions.
COLUMNS: tuple[tuple[str, str, str], ...] = (
    ("task", "Stage", "{}"),
    ("policy", "Method", "{}"),
    ("success_rate", "Success (%)", "pct"),
    ("collision_rate", "Collision (%)", "pct"),
    ("timeout_rate", "Timeout (%)", "pct"),
    ("time_s", "Time (s)", "{:.2f}"),
    ("distance_m", "Distance (m)", "{:.2f}"),
    ("speed", "Speed (m/s)", "{:.2f}"),
    ("total_abs_acc", "Total Abs Acc", "{:.1f}"),
    ("abs_acc_per_episode", "Abs Acc / ep.", "{:.1f}"),
    ("mean_min_clearance_obstacles", "Clear. obst. (m)", "{:.3f}"),
    ("mean_min_clearance_pedestrians", "Clear. ped. (m)", "{:.3f}"),
    ("solve_ms_median", "Solve p50 (ms)", "{:.2f}"),
    ("solve_ms_p99", "Solve p99 (ms)", "{:.2f}"),
    ("fallback_rate", "Fallback (%)", "pct"),
    ("region_failure_rate", "Region fail (%)", "pct"),
    ("episodes", "Episodes", "{:.0f}"),
)


def summary_row(summary: Mapping[str, float], task: str, policy: str) -> dict[str, Any]:
    """One table row: the aggregate plus the task and policy names."""
    return {"task": task, "policy": policy, **summary}


def _cell(value: Any, fmt: str) -> str:
    if isinstance(value, str) and fmt != "{}":  # a number as summary.csv holds it ("" for none)
        value = float(value) if value else None
    if value is None or (isinstance(value, float) and math.isnan(value)):
        return "–"
    if fmt == "pct":
        return f"{100.0 * value:.1f}"
    return fmt.format(value)


def _shown(row: Mapping[str, Any], key: str) -> Any:
    """The value of ``key`` as a table shows it: a planner that reads ground truth (``planner_privileged``
    non-empty) is marked "(privileged)" after its name."""
    value = row.get(key)
    return f"{value} (privileged)" if key == "policy" and row.get("planner_privileged") else value


def format_markdown(rows: Sequence[Mapping[str, Any]]) -> str:
    """A GitHub-markdown table of summary rows with the paper's columns, and the social metrics'
    (:data:`mjnav.eval.social.SOCIAL_COLUMNS`) before the episode count when a row has them; a
    privileged planner's method is marked "(privileged)"."""

    columns = COLUMNS
    if any(row.get("social_episodes") for row in rows):
        columns = (*COLUMNS[:-1], *SOCIAL_COLUMNS, COLUMNS[-1])
    header = "| " + " | ".join(label for _, label, _ in columns) + " |"
    rule = "|" + "|".join("---" for _ in columns) + "|"
    body = ["| " + " | ".join(_cell(_shown(row, key), fmt) for key, _, fmt in columns) + " |" for row in rows]
    return "\n".join([header, rule, *body]) + "\n"


def write_csv(rows: Sequence[Mapping[str, Any]], path: str | Path) -> None:
    """Write summary rows as CSV (machine keys, full precision, fractions not percent)."""
    keys = [key for key, _, _ in COLUMNS]
    extra = sorted({k for row in rows for k in row} - set(keys))
    with open(path, "w", newline="", encoding="utf-8") as f:
        writer = csv.DictWriter(f, fieldnames=keys + extra, restval="")
        writer.writeheader()
        for row in rows:
            writer.writerow({k: ("" if isinstance(v, float) and math.isnan(v) else v)
                             for k, v in row.items()})
