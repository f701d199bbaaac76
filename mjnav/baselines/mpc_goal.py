"""Convex region + MPC without learning: the action layer with hand-made reference points.

Every control step, in the robot frame:

* ``Q_l`` = the goal when it lies inside the convex free-space polygon; otherwise the polygon's
  boundary point in the goal direction scaled back by ``safety`` (0.9), so it stays inside.
  A recovered region (see :mod:`mjnav.geometry.region`) is used like a found one; when
  there is no polygon at all (spec §3: success = 0, ``on_failure='paper'``) the fallback polyline (every 6th beam's shrunk
  point) gives the boundary distance instead.
* ``Q_s`` = the point on the short-term circle (radius R_s of spec §4, from
  :func:`mjnav.control.action.radii`) towards ``Q_l``, or ``Q_l`` itself when it is closer.
  The polygon is convex and contains the origin and ``Q_l``, so ``Q_s`` lies inside too.
* The project's :class:`mjnav.control.mpc.Mpc` tracks ``(Q_s, Q_l)`` with the polygon
  constraint (none when the region failed), with the same fallback ladder as the learned policy.

It is the learned method's pipeline with the policy replaced by "head for the goal", so the
difference to the learned policy measures what learning adds.
"""

from __future__ import annotations

from typing import TYPE_CHECKING

import numpy as np

from mjnav.baselines.tracking import Limits, brake, escape
from mjnav.control.action import ActionConfig, boundary_distance, goal_inside, radii
from mjnav.control.guarded import GuardedMpc

__all__ = ["MpcGoalPlanner", "reference_points"]

if TYPE_CHECKING:
    from mjnav.config import TaskConfig
    from mjnav.geometry.region import Region
    from mjnav.tasks.core import PlannerInput


def reference_points(
    region: Region, goal: np.ndarray, r_s: float, safety: float = 0.9
) -> tuple[np.ndarray, np.ndarray, bool]:
    """``(Q_s, Q_l, goal_inside)`` towards the goal inside the region (robot frame, metres).

    Args:
        region: The scan's :class:`mjnav.geometry.region.Region`.
        goal: (2,) goal relative to the robot, metres.
        r_s: Short-term circle radius, metres.
        safety: Fraction of the boundary distance used for ``Q_l`` when the goal is outside.

    Returns:
        Short-term point, long-term point and whether the goal is inside the region.
    """
    dist = float(np.hypot(*goal))
    if dist < 1e-9:
        return np.zeros(2), np.zeros(2), True
    direction = goal / dist
    inside = goal_inside(region, goal)
    q_l = goal.copy() if inside else safety * min(boundary_distance(region, np.zeros(2), direction), dist) * direction
    q_s = direction * min(r_s, float(np.hypot(*q_l)))
    return q_s, q_l, inside


class MpcGoalPlanner:
    """Region + MPC heading for the goal, as a :class:`mjnav.tasks.core.Planner`."""

    def __init__(self, safety: float = 0.9) -> None:
        """``safety``: fraction of the boundary distance for Q_l when the goal is outside."""
        self.safety = safety
        self.stats = {"fallbacks": 0, "failures": 0}
        self.debug: dict[str, np.ndarray] = {}
        self._mpc: GuardedMpc | None = None
        self._config: tuple | None = None
        self._action = ActionConfig()
        self._escape_speed = 0.2
        self.limits = Limits()

    def reset(self, config: TaskConfig, rng: np.random.Generator) -> None:
        """Start an episode (``config``: the task's TaskConfig; ``rng`` unused: deterministic)."""
        del rng
        if self._mpc is None or self._config != (config.mpc, config.region):
            self._mpc, self._config = GuardedMpc(config.mpc, config.region), (config.mpc, config.region)
        self._mpc.reset()
        self._action = config.action
        self._escape_speed = config.region.escape_speed
        self.limits = Limits.from_task(config)
        self.debug = {}

    def act(self, inp: PlannerInput) -> np.ndarray:
        """Jerk for the next control period, m/s³ (brakes and counts on a bad input)."""
        v = np.asarray(inp.velocity, dtype=np.float64)
        a = np.asarray(inp.acceleration, dtype=np.float64)
        if self._mpc.must_escape(inp.region):  # no region even after recovery: back off
            self.stats["fallbacks"] += 1
            return escape(np.asarray(inp.scan), inp.angles, v, a, self.limits, self._escape_speed)
        try:
            r_s, _ = radii(v, a, self._action)
            goal = np.asarray(inp.goal) - inp.position
            q_s, q_l, inside = reference_points(inp.region, goal, r_s, self.safety)
            result = self._mpc.solve(np.stack([np.zeros(2), v, a]), q_s, q_l, inp.region, inside)
        except (ValueError, FloatingPointError):
            self.stats["failures"] += 1
            return brake(np.nan_to_num(v), np.nan_to_num(a), self.limits)
        self.stats["fallbacks"] += int(result.fallback is not None)
        p = np.asarray(inp.position, dtype=np.float64)
        self.debug = {"q_s": p + q_s, "q_l": p + q_l, "predicted": p + result.positions}
        return np.asarray(result.u0, dtype=np.float64)
