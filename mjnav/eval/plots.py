"""Figures: the paper's per-episode navigation figure and training learning curves (matplotlib Agg).

:func:`plot_episode` draws, like the paper's comparison figure, the robot path (dark blue) with
its time labels (cyan, every ``label_every`` seconds), the pedestrians' paths (red) with theirs
(black), static obstacles (grey), walls, the start (blue disc) and the goal (green star).
:func:`plot_success_by_distance` draws success against the start-goal distance
(:func:`mjnav.eval.tables.success_by_distance`), one line per method.
:func:`plot_learning_curve` reads a training run's TensorBoard events (``episode/success`` and
``episode/return``, falling back to rsl-rl's ``Train/mean_reward``) and plots them against
environment steps (iteration × ``num_envs`` × ``steps_per_env`` from the run's ``config.yaml``).
"""

from __future__ import annotations

from collections.abc import Sequence
from pathlib import Path
from typing import TYPE_CHECKING

import matplotlib

matplotlib.use("Agg")

import matplotlib.pyplot as plt
import numpy as np
import yaml
from matplotlib.patches import Circle, Polygon, Rectangle

__all__ = ["draw_episode", "load_scalars", "plot_episode", "plot_grid", "plot_learning_curve",
           "plot_success_by_distance"]

if TYPE_CHECKING:
    from matplotlib.axes import Axes

    from mjnav.world.layout import Layout


def _time_labels(
    ax: Axes, path: np.ndarray, dt: float, every: float, color: str, offset: tuple[float, float]
) -> None:
    stride = max(1, round(every / dt))
    for k in range(stride, len(path), stride):
        if np.all(np.isfinite(path[k])):
            ax.annotate(f"{k * dt:.0f}", path[k], xytext=offset, textcoords="offset points", color=color,
                        fontsize=7, ha="center", va="center")
            ax.plot(*path[k], ".", color=color, ms=3)


def draw_episode(
    ax: Axes,
    positions: np.ndarray,
    pedestrians: np.ndarray,
    layout: Layout,
    arena_size: Sequence[float],
    dt: float = 0.1,
    label_every: float = 1.0,
    title: str = "",
    robot_radius: float = 0.225,
    plans: Sequence[dict[str, np.ndarray]] = (),
) -> None:
    """Draw one episode into ``ax`` (see :func:`plot_episode`); ``plans`` adds, per instant, the
    convex region (black dashed) and the reference trajectory robot -> Q_s -> Q_l (green dashed)."""
    hx, hy = 0.5 * float(arena_size[0]), 0.5 * float(arena_size[1])
    ax.add_patch(Rectangle((-hx, -hy), 2 * hx, 2 * hy, fill=False, lw=2, ec="black"))
    for poly in layout.obstacle_polygons:
        ax.add_patch(Polygon(np.asarray(poly), closed=True, fc="0.6", ec="0.3"))
    peds = np.asarray(pedestrians, dtype=float).reshape(len(pedestrians), -1, 3)
    for i in range(peds.shape[1]):
        track = peds[:, i, :2]
        ax.plot(track[:, 0], track[:, 1], "-", color="red", lw=1)
        last = peds[-1, i]
        if np.all(np.isfinite(last)):
            ax.add_patch(Circle(last[:2], last[2], fc="none", ec="red", lw=0.8))
        if not plans:
            _time_labels(ax, track, dt, label_every, "black", (0, 6))
    p = np.asarray(positions, dtype=float)
    for k, plan in enumerate(plans):
        ax.add_patch(Polygon(plan["polygon"], closed=True, fill=False, ls="--", lw=0.9, ec="black",
                             label="convex region" if k == 0 else None))
        ref = np.vstack([plan["position"], plan["q_s"], plan["q_l"]])
        ax.plot(ref[:, 0], ref[:, 1], "--", color="green", lw=1.2, label="reference (Q_s, Q_l)" if k == 0 else None)
        ax.plot(*plan["q_s"], "o", color="orange", ms=3)
        ax.plot(*plan["q_l"], "o", color="green", ms=3)
    ax.plot(p[:, 0], p[:, 1], "-", color="darkblue", lw=2, label="robot")
    if not plans:
        _time_labels(ax, p, dt, label_every, "c", (0, -8))
    ax.add_patch(Circle(p[-1], robot_radius, fc="none", ec="darkblue", lw=1.2))
    ax.plot(*layout.start, "o", color="royalblue", ms=8, label="start")
    ax.plot(*layout.goal, "*", color="green", ms=16, label="goal")
    ax.set_xlim(-hx - 0.3, hx + 0.3)
    ax.set_ylim(-hy - 0.3, hy + 0.3)
    ax.set_aspect("equal")
    ax.set_xlabel("x (m)")
    ax.set_ylabel("y (m)")
    ax.set_title(title, fontsize=9)
    ax.legend(loc="upper right", fontsize=6)


def plot_episode(
    positions: np.ndarray,
    pedestrians: np.ndarray,
    layout: Layout,
    arena_size: Sequence[float],
    out: str | Path,
    dt: float = 0.1,
    label_every: float = 1.0,
    title: str = "",
    robot_radius: float = 0.225,
    plans: Sequence[dict[str, np.ndarray]] = (),
) -> Path:
    """Write the qualitative figure of one episode as PNG.

    Args:
        positions: (T+1, 2) robot positions, metres.
        pedestrians: (T+1, P, 3) pedestrian circles ``[x, y, r]`` per step, metres (NaN = absent).
        layout: The episode's :class:`mjnav.world.layout.Layout` (start, goal, obstacle polygons).
        arena_size: Interior extent (x, y), metres.
        out: PNG path.
        dt: Time between samples, seconds.
        label_every: Spacing of the time labels, seconds.
        title: Figure title.
        robot_radius: Drawn robot radius at the end, metres.
        plans: Planning snapshots (world frame: ``position``, ``polygon``, ``q_s``, ``q_l``), drawn
            as the paper's qualitative figure (time labels are then left out).

    Returns:
        The written path.
    """
    hx, hy = 0.5 * float(arena_size[0]), 0.5 * float(arena_size[1])
    fig, ax = plt.subplots(figsize=(6, 6 * hy / hx if hx else 6), dpi=120)
    draw_episode(ax, positions, pedestrians, layout, arena_size, dt, label_every, title, robot_radius, plans)
    fig.tight_layout()
    Path(out).parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(out)
    plt.close(fig)
    return Path(out)


def plot_grid(panels: Sequence[Sequence[dict]], out: str | Path, dt: float = 0.1) -> Path:
    """Several episodes side by side (the paper's Ours-vs-TEB figure: one row per scenario, one
    column per method). Each panel holds the keyword arguments of :func:`draw_episode` except ``ax``."""
    rows, cols = len(panels), max(len(r) for r in panels)
    fig, axes = plt.subplots(rows, cols, figsize=(4.6 * cols, 4.6 * rows), dpi=110, squeeze=False)
    for r, row in enumerate(panels):
        for c in range(cols):
            if c < len(row):
                draw_episode(axes[r][c], dt=dt, **row[c])
            else:
                axes[r][c].axis("off")
    fig.tight_layout()
    Path(out).parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(out)
    plt.close(fig)
    return Path(out)


def load_scalars(run_dir: str | Path) -> dict[str, tuple[np.ndarray, np.ndarray]]:
    """All scalars of a run's TensorBoard event files: tag → (steps, values), sorted by step."""
    # deferred: tensorboard's event reader costs ~0.3 s at import (python -X importtime), needed
    # only by the training-curve plots
    from tensorboard.backend.event_processing.event_accumulator import EventAccumulator

    series: dict[str, dict[int, float]] = {}
    for events in sorted(Path(run_dir).rglob("events.out.tfevents.*")):
        acc = EventAccumulator(str(events), size_guidance={"scalars": 0})
        acc.Reload()
        for tag in acc.Tags().get("scalars", []):
            series.setdefault(tag, {}).update({e.step: e.value for e in acc.Scalars(tag)})
    return {tag: (np.array(sorted(d)), np.array([d[k] for k in sorted(d)])) for tag, d in series.items()}


def _steps_per_iteration(run_dir: Path) -> int | None:
    config = run_dir / "config.yaml"
    if not config.exists():
        return None
    train = (yaml.safe_load(config.read_text()) or {}).get("train") or {}
    if "num_envs" in train and "steps_per_env" in train:
        return int(train["num_envs"]) * int(train["steps_per_env"])
    return None


def _smooth(values: np.ndarray, window: int) -> np.ndarray:
    if len(values) < window or window <= 1:
        return values
    kernel = np.ones(window) / window
    return np.convolve(np.pad(values, (window - 1, 0), mode="edge"), kernel, mode="valid")


def plot_learning_curve(run_dir: str | Path, out: str | Path, smooth: int = 10) -> Path:
    """Success rate and reward of a training run against environment steps, as PNG.

    Args:
        run_dir: Run folder with TensorBoard events (and ``config.yaml``).
        out: PNG path.
        smooth: Moving-average window, iterations (raw values are drawn faintly).

    Returns:
        The written path.

    Raises:
        FileNotFoundError: No success or reward scalars in the run.
    """
    run_dir = Path(run_dir)
    scalars = load_scalars(run_dir)
    wanted = (("episode/success", "success rate"), ("episode/return", "episode return"),
              ("Train/mean_reward", "mean reward (rsl-rl)"))
    panels = [(tag, label) for tag, label in wanted if tag in scalars][:2]
    if not panels:
        raise FileNotFoundError(f"{run_dir}: no episode/success, episode/return or Train/mean_reward scalars")
    scale = _steps_per_iteration(run_dir)
    fig, axes = plt.subplots(len(panels), 1, figsize=(6, 2.6 * len(panels)), dpi=120, sharex=True,
                             squeeze=False)
    for ax, (tag, label) in zip(axes[:, 0], panels):
        steps, values = scalars[tag]
        x = steps * scale if scale else steps
        ax.plot(x, values, color="tab:blue", alpha=0.25, lw=0.8)
        ax.plot(x, _smooth(values, smooth), color="tab:blue", lw=1.6)
        ax.set_ylabel(label)
        ax.grid(alpha=0.3)
    axes[-1, 0].set_xlabel("environment steps" if scale else "iteration")
    axes[0, 0].set_title(run_dir.name, fontsize=9)
    fig.tight_layout()
    Path(out).parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(out)
    plt.close(fig)
    return Path(out)


def plot_success_by_distance(series: dict[str, list[dict]], out: str | Path, title: str = "") -> Path:
    """Success % with 95 % intervals per start-goal distance bin, one line per method, as PNG.

    Args:
        series: Method name -> the bins of :func:`mjnav.eval.tables.success_by_distance`.
        out: PNG path.
        title: Figure title.

    Returns:
        The written path.
    """
    fig, ax = plt.subplots(figsize=(6, 3.4), dpi=120)
    for k, (name, bins) in enumerate(series.items()):
        full = [b for b in bins if b["episodes"]]
        hi = [b["hi"] if np.isfinite(b["hi"]) else b["lo"] + 2.0 for b in full]
        x = np.array([0.5 * (b["lo"] + h) for b, h in zip(full, hi)]) + 0.06 * (k - 0.5 * (len(series) - 1))
        rate = np.array([100 * b["rate"] for b in full])
        err = np.array([[100 * (b["rate"] - b["ci"][0]), 100 * (b["ci"][1] - b["rate"])] for b in full]).reshape(-1, 2)
        ax.errorbar(x, rate, yerr=np.clip(err, 0.0, None).T, marker="o", ms=4, capsize=3, label=name)
    ax.set_xlabel("start-goal distance (m), bin centre")
    ax.set_ylabel("success (%)")
    ax.set_ylim(0, 102)
    ax.grid(alpha=0.3)
    ax.legend(fontsize=8)
    ax.set_title(title, fontsize=9)
    fig.tight_layout()
    Path(out).parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(out)
    plt.close(fig)
    return Path(out)
