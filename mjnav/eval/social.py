"""Social-navigation metrics of one episode and their summary over a scenario set.

Pure numpy. The metrics are those crowd-navigation benchmarks report (CrowdNav, HuNavSim, SEAN,
SocNavBench, robot_sf), computed from an episode's trace (:class:`mjnav.eval.runner.EpisodeTrace`:
robot positions and velocities at the ``T + 1`` control instants ``t_k = k·t_c``, pedestrian
circles ``[x, y, r]`` padded with NaN) and the robot radius, start and goal. Every threshold is a
field of :class:`SocialThresholds` (one place, documented, in SI units).

Definitions (units in brackets). The *gap* to a pedestrian is the distance between the robot's
disc and the pedestrian's disc: centre distance − robot radius − pedestrian radius [m]; the gap
of an instant is the smallest over the pedestrians present.

* ``min_ped_distance_m``: smallest gap over the instants k = 0..T [m] (NaN without pedestrians).
* ``intrusion_*``, ``personal_*``, ``social_*``: the instants k = 1..T (after each step) whose gap
  is below ``intrusion_m``, ``personal_space_m`` and ``social_zone_m``: ``*_steps`` (count),
  ``*_time_s`` = count·t_c [s], ``*_share`` = count / T (NaN for T = 0). The zones are nested.
* ``near_misses``: distinct approach events: for one pedestrian, an event starts when the gap
  drops below ``near_miss_m`` and ends once it exceeds ``near_miss_m + near_miss_release_m``
  (hysteresis, so gap jitter around the threshold is one event); an event whose gap reached 0
  (a contact) is a collision, not a near miss.
* ``min_ttc_s``: smallest time to collision under constant velocities over the instants k = 0..T:
  for each pedestrian, the first t >= 0 at which the discs touch if both kept their current
  velocities (0 while they overlap) [s]. Robot velocities are the trace's; pedestrian velocities
  are backward finite differences of their positions (forward at k = 0). NaN when no pedestrian
  was on a collision course within ``ttc_horizon_s``.
* ``straight_line_m`` = max(‖goal − start‖ − goal tolerance, 0): the shortest way into the success
  disc around the goal, ignoring obstacles; ``path_length_m`` = Σ‖p_{k+1} − p_k‖ [m];
  ``path_efficiency`` = straight line ÷ travelled, capped at 1; ``spl`` = success × straight ÷
  max(travelled, straight) (Anderson et al. 2018, with the straight line as the shortest path).
* ``stopped_steps``, ``stopped_time_s`` [s], ``stopped_share``: instants k = 1..T with robot speed
  below ``stopped_speed`` (not moving).
* ``ped_speed_near`` / ``ped_speed_far`` [m/s] and ``ped_accel_near`` / ``ped_accel_far``
  [m/s²]: mean pedestrian speed and acceleration magnitude (finite differences) over the
  (pedestrian, instant) pairs whose gap to the robot is below / at least ``social_zone_m``. With
  a crowd that reacts to the robot, near − far is how much the robot disturbs the pedestrians;
  with the paper's non-reactive crowd it measures nothing but chance (a control).
* ``ped_turn_near`` / ``ped_turn_far`` [rad/s]: the path part of the disturbance: mean heading-change
  rate |dθ/dt| of the pedestrians, θ the direction of their finite-difference velocity and dθ the
  wrapped change between consecutive velocities (instants k = 2..T, as the acceleration), over the
  (pedestrian, instant) pairs near / far as above whose speed at both instants is at least
  ``turn_min_speed`` (a standing pedestrian has no heading). A pedestrian that swerves around the
  robot turns faster near it than far from it. Far samples also hold the turns at walls, obstacles,
  new goals and other pedestrians, which are not spread evenly over near and far, so the robot's
  effect is best read as near (reactive crowd) against near (the same crowd with ``reactive=false``,
  the control), same planner and episodes.

The summary (:func:`aggregate_social`) gives every rate with its 95 % Wilson interval
(``<rate>_lo``, ``<rate>_hi``): step shares pooled over all steps, episode rates over episodes.
"""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Iterable, Mapping, Sequence
from typing import Any

import numpy as np

from mjnav.eval.intervals import rate_with_interval

__all__ = [
    "COLLISION_KINDS",
    "PED_DISTURBANCE_KEYS",
    "SOCIAL_COLUMNS",
    "SocialMetrics",
    "SocialThresholds",
    "THRESHOLDS",
    "aggregate_social",
    "pedestrian_velocities",
    "social_metrics",
    "surface_gaps",
    "time_to_collision",
    "trace_social_metrics",
]

#: Collision kinds recorded per episode (``collision_kind`` of a JSONL record; None without one).
COLLISION_KINDS = ("pedestrian", "obstacle", "wall")


@dataclasses.dataclass(frozen=True)
class SocialThresholds:
    """Every threshold of the social metrics (SI units).

    Attributes:
        intrusion_m: Gap below which the robot intrudes on a pedestrian (CrowdNav's
            "discomfort distance"), metres.
        personal_space_m: Gap below which the robot is in a pedestrian's personal space (Hall's
            personal zone, 0.45 m), metres.
        social_zone_m: Gap below which the robot is in a pedestrian's social zone (1.2 m); also the
            near/far split of the pedestrian-disturbance metrics, metres.
        near_miss_m: Gap below which an approach counts as a near miss, metres.
        near_miss_release_m: Hysteresis: a near miss ends once the gap exceeds
            ``near_miss_m + near_miss_release_m``, metres.
        ttc_horizon_s: Collision courses further ahead than this are ignored, seconds.
        stopped_speed: Robot speed below which it is not moving, m/s.
        turn_min_speed: Pedestrian speed below which its heading is undefined: heading-change
            samples where it is slower (at either of the two instants) are left out of
            ``ped_turn_near`` / ``ped_turn_far``, m/s (a third of the default 0.3 m/s walk).
    """

    intrusion_m: float = 0.2
    personal_space_m: float = 0.45
    social_zone_m: float = 1.2
    near_miss_m: float = 0.2
    near_miss_release_m: float = 0.1
    ttc_horizon_s: float = 5.0
    stopped_speed: float = 0.05
    turn_min_speed: float = 0.1

    def __post_init__(self) -> None:
        """Raises ValueError unless 0 < intrusion <= personal space <= social zone and the rest > 0."""
        if not 0.0 < self.intrusion_m <= self.personal_space_m <= self.social_zone_m:
            raise ValueError(f"thresholds must satisfy 0 < intrusion <= personal space <= social zone, got {self}")
        if (min(self.near_miss_m, self.ttc_horizon_s, self.stopped_speed, self.turn_min_speed) <= 0
                or self.near_miss_release_m < 0):
            raise ValueError(f"near_miss_m, ttc_horizon_s, stopped_speed and turn_min_speed must be > 0, "
                             f"release >= 0, got {self}")


#: The thresholds evaluations use.
THRESHOLDS = SocialThresholds()


@dataclasses.dataclass(frozen=True)
class SocialMetrics:
    """Social metrics of one episode (definitions and units in the module docstring)."""

    steps: int
    min_ped_distance_m: float
    intrusion_steps: int
    intrusion_time_s: float
    intrusion_share: float
    personal_steps: int
    personal_time_s: float
    personal_share: float
    social_steps: int
    social_time_s: float
    social_share: float
    near_misses: int
    min_ttc_s: float
    straight_line_m: float
    path_length_m: float
    path_efficiency: float
    spl: float
    stopped_steps: int
    stopped_time_s: float
    stopped_share: float
    ped_speed_near: float
    ped_speed_far: float
    ped_accel_near: float
    ped_accel_far: float
    ped_turn_near: float = math.nan
    ped_turn_far: float = math.nan

    def to_dict(self) -> dict[str, Any]:
        """JSON-ready dict of Python numbers (NaN and infinities → None)."""
        out = {k: (v.item() if isinstance(v, np.generic) else v) for k, v in dataclasses.asdict(self).items()}
        return {k: (None if isinstance(v, float) and not math.isfinite(v) else v) for k, v in out.items()}

    @classmethod
    def from_dict(cls, data: Mapping[str, Any]) -> SocialMetrics:
        """Inverse of :meth:`to_dict` (None → NaN; unknown keys ignored)."""
        names = {f.name for f in dataclasses.fields(cls)}
        return cls(**{k: (math.nan if v is None else v) for k, v in data.items() if k in names})


def surface_gaps(positions: np.ndarray, pedestrians: np.ndarray, robot_radius: float) -> np.ndarray:
    """Gap between the robot's disc and each pedestrian's disc.

    Args:
        positions: (T+1, 2) robot positions, metres.
        pedestrians: (T+1, P, 3) pedestrian circles ``[x, y, r]``, metres; NaN rows are absent.
        robot_radius: Robot radius, metres.

    Returns:
        (T+1, P) gaps, metres (negative while overlapping, NaN where a pedestrian is absent).
    """
    d = pedestrians[:, :, :2] - positions[:, None, :]
    return np.hypot(d[..., 0], d[..., 1]) - pedestrians[:, :, 2] - robot_radius


def pedestrian_velocities(pedestrians: np.ndarray, dt: float) -> np.ndarray:
    """(T+1, P, 2) pedestrian velocities, m/s: backward differences, forward at k = 0 (zero for T = 0)."""
    xy = pedestrians[:, :, :2]
    if len(xy) < 2:
        return np.zeros_like(xy)
    diff = np.diff(xy, axis=0) / dt
    return np.concatenate([diff[:1], diff], axis=0)


def time_to_collision(rel_pos: np.ndarray, rel_vel: np.ndarray, reach: np.ndarray) -> np.ndarray:
    """First time t >= 0 at which ‖rel_pos + t·rel_vel‖ = reach (constant velocities).

    Args:
        rel_pos: (..., 2) pedestrian position minus robot position, metres.
        rel_vel: (..., 2) pedestrian velocity minus robot velocity, m/s.
        reach: (...) sum of the two radii, metres.

    Returns:
        (...) seconds: 0 where the discs overlap now, inf where they never touch (NaN stays NaN).
    """
    a = np.sum(rel_vel * rel_vel, axis=-1)
    b = np.sum(rel_pos * rel_vel, axis=-1)
    c = np.sum(rel_pos * rel_pos, axis=-1) - reach * reach
    disc = b * b - a * c
    with np.errstate(invalid="ignore", divide="ignore"):
        t = (-b - np.sqrt(np.maximum(disc, 0.0))) / a
    out = np.where((disc >= 0) & (a > 0) & (b < 0) & (t >= 0), t, np.inf)
    out = np.where(c <= 0, 0.0, out)
    return np.where(np.isnan(c), np.nan, out)


def _near_misses(gaps: np.ndarray, th: SocialThresholds) -> int:
    """Approach events below ``near_miss_m`` that never reached contact, over all pedestrians."""
    count = 0
    release = th.near_miss_m + th.near_miss_release_m
    for column in gaps.T:
        inside, lowest = False, math.inf
        for gap in column:
            if math.isnan(gap):
                continue
            if not inside and gap < th.near_miss_m:
                inside, lowest = True, gap
            elif inside:
                lowest = min(lowest, gap)
                if gap > release:
                    count += int(lowest > 0.0)
                    inside = False
        count += int(inside and lowest > 0.0)
    return count


def _zone_steps(closest: np.ndarray, limit: float) -> int:
    """Instants k = 1..T whose closest gap is below ``limit``."""
    return int(np.sum(closest[1:] < limit))


def _counted(name: str, count: int, steps: int, dt: float) -> dict[str, Any]:
    """``<name>_steps`` (count of instants), ``<name>_time_s`` (count·t_c, s), ``<name>_share`` (count / T)."""
    return {f"{name}_steps": count, f"{name}_time_s": count * dt,
            f"{name}_share": count / steps if steps else math.nan}


def _mean_where(values: np.ndarray, mask: np.ndarray) -> float:
    chosen = values[mask & np.isfinite(values)]
    return float(np.mean(chosen)) if chosen.size else math.nan


def _turn_rates(vel: np.ndarray, speed: np.ndarray, dt: float, min_speed: float) -> np.ndarray:
    """(T+1, P) heading-change rates |dθ/dt|, rad/s, at k = 2..T (NaN elsewhere and where the pedestrian is
    slower than ``min_speed`` at k or k − 1): the wrapped angle between the velocities at k − 1 and k, ÷ dt."""
    turn = np.full_like(speed, np.nan)
    if len(vel) > 2:
        a, b = vel[1:-1], vel[2:]
        angle = np.abs(np.arctan2(a[..., 0] * b[..., 1] - a[..., 1] * b[..., 0], np.sum(a * b, axis=-1)))
        with np.errstate(invalid="ignore"):
            moving = (speed[1:-1] >= min_speed) & (speed[2:] >= min_speed)
        turn[2:] = np.where(moving, angle / dt, np.nan)
    return turn


def _disturbance(pedestrians: np.ndarray, gaps: np.ndarray, dt: float, th: SocialThresholds) -> dict[str, float]:
    """``ped_{speed,accel,turn}_{near,far}``: the pedestrians' mean speed, acceleration magnitude and
    heading-change rate near / far from the robot, m/s, m/s² and rad/s."""
    vel = pedestrian_velocities(pedestrians, dt)
    speed = np.hypot(vel[..., 0], vel[..., 1])
    accel = np.full_like(speed, np.nan)
    if len(vel) > 2:  # backward differences of the velocities from k = 2 on (k = 1 reuses the forward one)
        dv = np.diff(vel[1:], axis=0) / dt
        accel[2:] = np.hypot(dv[..., 0], dv[..., 1])
    turn = _turn_rates(vel, speed, dt, th.turn_min_speed)
    near, far = gaps < th.social_zone_m, gaps >= th.social_zone_m
    return {f"ped_{name}_{side}": _mean_where(values, mask)
            for name, values in (("speed", speed), ("accel", accel), ("turn", turn))
            for side, mask in (("near", near), ("far", far))}


def _path(positions: np.ndarray, start: np.ndarray, goal: np.ndarray, tolerance: float,
          success: bool) -> tuple[float, ...]:
    """(straight line, travelled, path efficiency, SPL)."""
    straight = max(float(np.hypot(*(np.asarray(goal, float) - np.asarray(start, float)))) - tolerance, 0.0)
    travelled = float(np.sum(np.hypot(*np.diff(positions, axis=0).T))) if len(positions) > 1 else 0.0
    longest = max(travelled, straight)
    if longest <= 0:  # start on the goal and never moved: nothing to be efficient about
        return straight, travelled, math.nan, float(success)
    efficiency = straight / longest
    return straight, travelled, efficiency, efficiency if success else 0.0


def social_metrics(
    positions: np.ndarray,
    velocities: np.ndarray,
    pedestrians: np.ndarray,
    dt: float,
    robot_radius: float,
    start: Sequence[float] | np.ndarray,
    goal: Sequence[float] | np.ndarray,
    outcome: str,
    goal_tolerance: float = 0.0,
    thresholds: SocialThresholds = THRESHOLDS,
) -> SocialMetrics:
    """Social metrics of one episode.

    Args:
        positions: (T+1, 2) robot positions at the control instants, metres.
        velocities: (T+1, 2) robot velocities at the same instants, m/s.
        pedestrians: (T+1, P, 3) pedestrian circles ``[x, y, r]``, metres (NaN = absent; P may be 0).
        dt: Control period t_c, seconds.
        robot_radius: Robot radius, metres.
        start: (2,) start position, metres.
        goal: (2,) goal position, metres.
        outcome: ``success``, ``collision``, ``timeout`` (or ``running``).
        goal_tolerance: Success distance to the goal, metres (``reward.goal_tolerance``).
        thresholds: The thresholds (default :data:`THRESHOLDS`).

    Returns:
        The :class:`SocialMetrics`.

    Raises:
        ValueError: On mismatched shapes or a non-positive ``dt``.
    """
    p, v = np.asarray(positions, np.float64), np.asarray(velocities, np.float64)
    peds = np.asarray(pedestrians, np.float64)
    peds = peds.reshape(len(p), -1, 3) if peds.size else np.zeros((len(p), 0, 3))
    if p.ndim != 2 or p.shape[1] != 2 or p.shape != v.shape or len(p) < 1 or len(peds) != len(p):
        raise ValueError(f"positions, velocities (T+1, 2) and pedestrians (T+1, P, 3) disagree: "
                         f"{p.shape}, {v.shape}, {np.shape(pedestrians)}")
    if not dt > 0:
        raise ValueError(f"dt must be > 0, got {dt}")
    th, steps = thresholds, len(p) - 1
    gaps = surface_gaps(p, peds, robot_radius)
    with np.errstate(all="ignore"):
        closest = np.nanmin(gaps, axis=1) if gaps.shape[1] else np.full(len(p), np.nan)
    closest = np.where(np.isnan(closest), np.inf, closest)
    speed = np.hypot(v[:, 0], v[:, 1])
    counted = {**_counted("intrusion", _zone_steps(closest, th.intrusion_m), steps, dt),
               **_counted("personal", _zone_steps(closest, th.personal_space_m), steps, dt),
               **_counted("social", _zone_steps(closest, th.social_zone_m), steps, dt),
               **_counted("stopped", int(np.sum(speed[1:] < th.stopped_speed)), steps, dt)}
    rel_vel = pedestrian_velocities(peds, dt) - v[:, None, :]
    ttc = time_to_collision(peds[:, :, :2] - p[:, None, :], rel_vel, peds[:, :, 2] + robot_radius)
    ttc = ttc[np.isfinite(ttc) & (ttc <= th.ttc_horizon_s)]
    straight, travelled, efficiency, spl = _path(p, np.asarray(start), np.asarray(goal), goal_tolerance,
                                               outcome == "success")
    return SocialMetrics(
        steps=steps,
        min_ped_distance_m=float(np.min(closest)) if np.isfinite(closest).any() else math.nan,
        near_misses=_near_misses(gaps, th),
        min_ttc_s=float(np.min(ttc)) if ttc.size else math.nan,
        straight_line_m=straight, path_length_m=travelled, path_efficiency=efficiency, spl=spl,
        **counted,
        **_disturbance(peds, gaps, dt, th),
    )


def trace_social_metrics(trace: Any, robot_radius: float, start: Sequence[float] | np.ndarray,
                         goal: Sequence[float] | np.ndarray, outcome: str, goal_tolerance: float = 0.0,
                         thresholds: SocialThresholds = THRESHOLDS) -> SocialMetrics:
    """:func:`social_metrics` of a :class:`mjnav.eval.runner.EpisodeTrace` (its ``control_period`` is t_c)."""
    return social_metrics(trace.positions, trace.velocities, trace.pedestrians, trace.control_period, robot_radius,
                          start, goal, outcome, goal_tolerance, thresholds)


# ---------------------------------------------------------------------------- summary

def _rate(out: dict[str, float], name: str, hits: int, n: int) -> None:
    """``out[name]`` = hits / n with its 95 % Wilson interval ``name_lo``, ``name_hi`` (NaN for n = 0)."""
    out.update(rate_with_interval(name, int(hits), int(n)))


def _finite_mean(values: Iterable[float]) -> float:
    arr = np.asarray([np.nan if x is None else x for x in values], dtype=np.float64)
    arr = arr[np.isfinite(arr)]
    return float(np.mean(arr)) if arr.size else math.nan


def aggregate_social(records: Sequence[Mapping[str, Any]]) -> dict[str, float]:
    """Summary of the social metrics over evaluation records (the runner's JSONL records).

    Args:
        records: Records with ``outcome``, and ``social`` (:meth:`SocialMetrics.to_dict`) and
            ``collision_kind`` where recorded (records of older evaluations have neither).

    Returns:
        ``social_episodes`` (records with social metrics); pooled step shares ``intrusion_share``,
        ``personal_share``, ``social_share``, ``stopped_share``; episode rates
        ``intrusion_episode_rate`` (any intrusion), ``near_miss_episode_rate``,
        ``ttc_course_rate`` (a collision course within the horizon), each with ``_lo``/``_hi``
        (95 % Wilson); ``collision_<kind>_rate`` with intervals over the records carrying
        ``collision_kind``; ``min_ped_distance_m`` (minimum) and ``mean_min_ped_distance_m``,
        ``near_misses_per_episode``, ``mean_min_ttc_s`` (episodes on a course), ``stopped_time_s``,
        ``path_efficiency`` (over successes), ``spl`` (over all), ``ped_speed_near`` / ``_far``,
        ``ped_accel_near`` / ``_far``, ``ped_turn_near`` / ``_far`` (means of the episodes' values). NaN where
        undefined.
    """
    social = [SocialMetrics.from_dict(r["social"]) for r in records if r.get("social")]
    wins = [s for s, r in zip(social, (r for r in records if r.get("social"))) if r.get("outcome") == "success"]
    n, steps = len(social), sum(s.steps for s in social)
    out: dict[str, float] = {"social_episodes": float(n)}
    for name in ("intrusion", "personal", "social", "stopped"):
        _rate(out, f"{name}_share", sum(getattr(s, f"{name}_steps") for s in social), steps)
    _rate(out, "intrusion_episode_rate", sum(s.intrusion_steps > 0 for s in social), n)
    _rate(out, "near_miss_episode_rate", sum(s.near_misses > 0 for s in social), n)
    _rate(out, "ttc_course_rate", sum(math.isfinite(s.min_ttc_s) for s in social), n)
    kinds = [r for r in records if "collision_kind" in r]
    for kind in COLLISION_KINDS:
        _rate(out, f"collision_{kind}_rate", sum(r["collision_kind"] == kind for r in kinds), len(kinds))
    distances = [s.min_ped_distance_m for s in social if math.isfinite(s.min_ped_distance_m)]
    out["min_ped_distance_m"] = min(distances) if distances else math.nan
    out["mean_min_ped_distance_m"] = _finite_mean(distances)
    out["near_misses_per_episode"] = _finite_mean(s.near_misses for s in social)
    out["mean_min_ttc_s"] = _finite_mean(s.min_ttc_s for s in social)
    out["stopped_time_s"] = _finite_mean(s.stopped_time_s for s in social)
    out["path_efficiency"] = _finite_mean(s.path_efficiency for s in wins)
    out["spl"] = _finite_mean(s.spl for s in social)
    for key in PED_DISTURBANCE_KEYS:
        out[key] = _finite_mean(getattr(s, key) for s in social)
    return out


#: Summary keys of the pedestrian disturbance (speed, acceleration, heading-change rate near / far from the robot).
PED_DISTURBANCE_KEYS = ("ped_speed_near", "ped_speed_far", "ped_accel_near", "ped_accel_far",
                        "ped_turn_near", "ped_turn_far")

#: Summary columns of the social metrics: (key, markdown label, format; ``pct`` = fraction shown in %).
SOCIAL_COLUMNS: tuple[tuple[str, str, str], ...] = (
    ("mean_min_ped_distance_m", "Min gap ped. (m)", "{:.3f}"),
    ("intrusion_share", f"Intrusion < {THRESHOLDS.intrusion_m:g} m (% steps)", "pct"),
    ("personal_share", f"Personal < {THRESHOLDS.personal_space_m:g} m (% steps)", "pct"),
    ("social_share", f"Social < {THRESHOLDS.social_zone_m:g} m (% steps)", "pct"),
    ("near_misses_per_episode", "Near misses / ep.", "{:.2f}"),
    ("mean_min_ttc_s", "Min TTC (s)", "{:.2f}"),
    ("path_efficiency", "Path eff.", "{:.3f}"),
    ("spl", "SPL", "{:.3f}"),
    ("stopped_time_s", "Stopped (s)", "{:.2f}"),
    ("ped_speed_near", f"Ped. speed < {THRESHOLDS.social_zone_m:g} m (m/s)", "{:.3f}"),
    ("ped_speed_far", "Ped. speed far (m/s)", "{:.3f}"),
    ("ped_turn_near", f"Ped. turn < {THRESHOLDS.social_zone_m:g} m (rad/s)", "{:.3f}"),
    ("ped_turn_far", "Ped. turn far (rad/s)", "{:.3f}"),
    ("collision_pedestrian_rate", "Coll. ped. (%)", "pct"),
    ("collision_obstacle_rate", "Coll. obst. (%)", "pct"),
    ("collision_wall_rate", "Coll. wall (%)", "pct"),
)
