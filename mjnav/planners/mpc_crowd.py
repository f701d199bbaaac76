"""``mpc_crowd``: the action layer steered by the pedestrians' true motion (privileged; not in the paper).

The same pipeline as :mod:`mjnav.planners.mpc_goal` (convex region, MPC, fallbacks), with ``Q_l``
chosen from the simulator's ground truth: the pedestrians' positions and radii
(:attr:`mjnav.planners.base.PlannerInput.pedestrians`,
declared in ``MpcCrowdPlanner.privileged``), their velocities estimated by differencing
the positions over one control period. A robot never has this; the planner is an *oracle*: it
shows what the action layer reaches when the crowd's motion is known, an upper reference for a
learned policy that must infer it from the scan.

Every control step, with the goal outside the polygon (inside: ``Q_l`` = the goal, as for
``mpc_goal``), among the candidate velocities ``u`` (zero and ``directions`` headings × ``speeds``):

* the robot's path is ``u·t + (v − u)·lag·(1 − exp(−t/lag))`` (its velocity reaches ``u`` with a
  first-order lag), every pedestrian moves at its constant velocity, over ``t`` in ``[0, horizon]``;
* ``clearance(u)`` = the smallest ``distance − radius − R_inf + kappa·t`` over pedestrians and
  times (a near miss counts less the later it comes);
* score = ``u·ĝ / max(speeds) − weight·max(0, margin − clearance)/margin`` (− 0.5 when the polygon
  cuts ``Q_l`` below half of ``|u|`` × the MPC horizon);
* ``Q_l = u/|u| · min(|u|·T, safety·d, ρ)`` with ``T`` the MPC horizon (s), ``d`` the polygon's
  boundary distance along ``u`` and ``ρ`` the goal distance; ``Q_s`` the short-term point towards it.

The scoring is :mod:`mjnav.control.crowd` (shared with the action layer's crowd shield).

Tuning (the same choice acted through Ours' action layer, goal frame, ``region.margin=0.1``, paper's
rule, 200 stage-6 tuning scenarios, ``seed_offset=1000000000``): ``mpc_gap`` 64.5 %; a first-contact
time instead of the clearance 73.5–77.0 %; margin 0.3 / 0.4 / 0.5 / 0.6 m: 83.5 / 90.5 / 88.5 /
89.0 %; weight 4, kappa 0 or 0.05: 89.5–90.5 %; margin 0.4 with the pedestrians taken as standing
still: 73.5 %. Default margin 0.4, weight 2, kappa 0.1.
"""

from __future__ import annotations

from typing import TYPE_CHECKING

import numpy as np

from mjnav.control.action import goal_inside
from mjnav.control.crowd import MpcCrowdConfig, best_long_point, crowd_long_point, crowd_scores
from mjnav.planners.mpc_goal import MpcGoalPlanner
from mjnav.tasks.privileged import CrowdTracker

__all__ = ["CrowdTracker", "MpcCrowdConfig", "MpcCrowdPlanner", "best_long_point", "crowd_long_point", "crowd_scores"]

if TYPE_CHECKING:
    from mjnav.config import TaskConfig
    from mjnav.planners.base import PlannerInput


class MpcCrowdPlanner(MpcGoalPlanner):
    """Region + MPC with ``Q_l`` from the crowd's true motion (``mpc_crowd``, privileged).

    Reads the pedestrians' true positions and radii (declared in :attr:`privileged`); it estimates
    their velocities itself by differencing the positions (:class:`CrowdTracker`).
    """

    #: The ground truth it reads (:data:`mjnav.planners.base.PRIVILEGED_FIELDS`).
    privileged = frozenset({"positions", "radii"})
    config_class = MpcCrowdConfig

    def __init__(self, config: MpcCrowdConfig | None = None) -> None:
        """``config``: :class:`MpcCrowdConfig` (defaults when None)."""
        self.config = config or MpcCrowdConfig()
        super().__init__(safety=self.config.safety)
        self._inflation = 0.325
        self._reach_time = 1.0
        self.tracker = CrowdTracker()

    def reset(self, config: TaskConfig, rng: np.random.Generator) -> None:
        """Start an episode: forget the crowd seen so far (``rng`` unused: deterministic)."""
        super().reset(config, rng)
        self._inflation = config.region.inflation
        self._reach_time = config.mpc.horizon * config.timing.control_period
        self.tracker.reset()

    def crowd(self, inp: PlannerInput) -> tuple[np.ndarray, np.ndarray]:
        """The pedestrians this step: ((P, 3) ``[x, y, r]`` relative to the robot, metres; (P, 2)
        velocities, m/s), from the true positions and radii, velocities by differencing (every step,
        also when the goal is inside, so the differences stay one period apart)."""
        peds = np.asarray(inp.pedestrians, dtype=np.float64).reshape(-1, 3)
        ped_velocities = self.tracker.update(inp.time, peds[:, :2])
        return np.column_stack([peds[:, :2] - inp.position, peds[:, 2]]), ped_velocities

    def reference(self, inp: PlannerInput, goal: np.ndarray, r_s: float) -> tuple[np.ndarray, np.ndarray, bool]:
        """``(Q_s, Q_l, goal_inside)`` from the crowd's motion (robot frame, metres)."""
        relative, ped_velocities = self.crowd(inp)
        inside = goal_inside(inp.region, goal)
        if inside:
            q_l = goal.copy()
        else:
            q_l = crowd_long_point(inp.region, goal, np.asarray(inp.velocity, dtype=np.float64), relative,
                                   ped_velocities, self._inflation, self._reach_time, self.config)
        length = float(np.hypot(*q_l))
        q_s = q_l / length * min(r_s, length) if length > 1e-9 else np.zeros(2)
        return q_s, q_l, inside
