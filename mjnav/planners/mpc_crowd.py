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

Tuning (the same choice acted through Ours' action layer, goal frame, ``region.margin=0.1``, paper's
rule, 200 stage-6 tuning scenarios, ``seed_offset=1000000000``): ``mpc_gap`` 64.5 %; a first-contact
time instead of the clearance 73.5–77.0 %; margin 0.3 / 0.4 / 0.5 / 0.6 m: 83.5 / 90.5 / 88.5 /
89.0 %; weight 4, kappa 0 or 0.05: 89.5–90.5 %; margin 0.4 with the pedestrians taken as standing
still: 73.5 %. Default margin 0.4, weight 2, kappa 0.1.
"""

from __future__ import annotations

import dataclasses
import math
from typing import TYPE_CHECKING

import numpy as np

from mjnav.control.action import boundary_distance, goal_inside
from mjnav.planners.mpc_goal import MpcGoalPlanner
from mjnav.schema import ConfigError
from mjnav.tasks.privileged import CrowdTracker

__all__ = ["CrowdTracker", "MpcCrowdConfig", "MpcCrowdPlanner", "best_long_point", "crowd_long_point", "crowd_scores"]

if TYPE_CHECKING:
    from mjnav.config import TaskConfig
    from mjnav.geometry.region import Region
    from mjnav.planners.base import PlannerInput


@dataclasses.dataclass(frozen=True)
class MpcCrowdConfig:
    """Parameters of ``mpc_crowd`` (see the module docstring).

    Attributes:
        margin: Clearance beyond R_inf below which a candidate is penalised, metres.
        weight: Weight of the clearance penalty against progress (a unit at full speed).
        horizon: Prediction horizon, seconds.
        samples: Prediction times over the horizon (including 0).
        kappa: Clearance credited per second ahead, m/s.
        lag: Time constant of the robot's velocity response, seconds.
        speeds: Candidate speeds, m/s (plus standing still).
        directions: Candidate headings, evenly spaced over the circle.
        safety: Fraction of the boundary distance ``Q_l`` may use.
    """

    margin: float = 0.4
    weight: float = 2.0
    horizon: float = 2.0
    samples: int = 21
    kappa: float = 0.1
    lag: float = 0.3
    speeds: tuple[float, ...] = (0.6, 1.2, 1.8, 2.4)
    directions: int = 36
    safety: float = 0.9

    def __post_init__(self) -> None:
        """Reject values that would make the choice meaningless."""
        positive = {"margin": self.margin, "horizon": self.horizon, "lag": self.lag}
        for name, value in positive.items():
            if not (math.isfinite(value) and value > 0.0):
                raise ConfigError(f"{name}: must be finite and > 0, got {value}")
        for name, value in {"weight": self.weight, "kappa": self.kappa}.items():
            if not (math.isfinite(value) and value >= 0.0):
                raise ConfigError(f"{name}: must be finite and >= 0, got {value}")
        if self.samples < 2:
            raise ConfigError(f"samples: must be >= 2, got {self.samples}")
        if self.directions < 4:
            raise ConfigError(f"directions: must be >= 4, got {self.directions}")
        if not self.speeds or not all(math.isfinite(s) and s > 0.0 for s in self.speeds):
            raise ConfigError(f"speeds: must be finite and > 0, got {self.speeds}")
        if not 0.0 < self.safety <= 1.0:
            raise ConfigError(f"safety: must be in (0, 1], got {self.safety}")


def _candidates(config: MpcCrowdConfig) -> np.ndarray:
    """(1 + directions·len(speeds), 2) candidate velocities, m/s; row 0 stands still."""
    angles = np.linspace(0.0, 2.0 * np.pi, config.directions, endpoint=False)
    unit = np.column_stack([np.cos(angles), np.sin(angles)])
    return np.concatenate([np.zeros((1, 2))] + [s * unit for s in config.speeds])


def _free_distances(region: Region, candidates: np.ndarray, speeds: np.ndarray) -> np.ndarray:
    """Boundary distance along each candidate's direction, metres (0 for standing still)."""
    moving = speeds > 0.0
    free = np.zeros(len(candidates))
    if region.has_polygon:  # exact ray / convex polygon distances, all at once
        along = candidates[moving] @ np.asarray(region.normals).T
        with np.errstate(divide="ignore"):
            hit = np.where(along > 1e-12, np.asarray(region.offsets)[None] / along, np.inf).min(1)
        free[moving] = np.where(np.isfinite(hit), hit, 0.0) * speeds[moving]
    else:
        free[moving] = [boundary_distance(region, np.zeros(2), u / s) for u, s in zip(candidates[moving],
                                                                                     speeds[moving])]
    return free


def _clearance(candidates: np.ndarray, velocity: np.ndarray, pedestrians: np.ndarray,
               ped_velocities: np.ndarray, inflation: float, config: MpcCrowdConfig) -> np.ndarray:
    """Smallest predicted clearance (with the kappa credit) of each candidate, metres (inf: no crowd)."""
    if len(pedestrians) == 0:
        return np.full(len(candidates), np.inf)
    t = np.linspace(0.0, config.horizon, config.samples)
    lag = config.lag * (1.0 - np.exp(-t / config.lag))
    robot = candidates[:, None, :] * t[None, :, None] + (velocity[None, None, :] - candidates[:, None, :]) * lag[
        None, :, None]  # (K, T, 2), robot frame
    peds = pedestrians[None, :, :2] + ped_velocities[None] * t[:, None, None]  # (T, P, 2)
    gap = np.linalg.norm(robot[:, :, None, :] - peds[None], axis=-1)  # (K, T, P)
    return (gap - pedestrians[None, None, :, 2] - inflation + config.kappa * t[None, :, None]).min(axis=(1, 2))


def crowd_scores(region: Region, goal: np.ndarray, velocity: np.ndarray, pedestrians: np.ndarray,
                 ped_velocities: np.ndarray, inflation: float, reach_time: float,
                 config: MpcCrowdConfig) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Every candidate velocity with its reach and score (module docstring); arguments as for
    :func:`crowd_long_point`.

    Returns:
        ``(candidates, reach, score)``: (K, 2) velocities, m/s (row 0 stands still); (K,) how far
        ``Q_l`` may lie along each, metres; (K,) scores, higher is better.
    """
    dist = float(np.hypot(*goal))
    candidates = _candidates(config)
    speeds = np.hypot(candidates[:, 0], candidates[:, 1])
    reach = np.minimum(speeds * reach_time, config.safety * _free_distances(region, candidates, speeds))
    clearance = _clearance(candidates, velocity, pedestrians, ped_velocities, inflation, config)
    danger = np.maximum(0.0, config.margin - clearance) / config.margin
    progress = candidates @ (goal / max(dist, 1e-9)) / max(config.speeds)
    score = progress - config.weight * danger - 0.5 * (reach < 0.5 * speeds * reach_time)
    return candidates, reach, score


def best_long_point(candidates: np.ndarray, reach: np.ndarray, score: np.ndarray, goal: np.ndarray) -> np.ndarray:
    """``Q_l`` (robot frame, metres) of the best-scoring candidate of :func:`crowd_scores`: along its
    velocity, as far as its reach and the goal allow; zeros to stand still."""
    best = int(np.argmax(score))
    dist = float(np.hypot(*goal))
    if best == 0 or dist < 1e-9:
        return np.zeros(2)
    speed = float(np.hypot(*candidates[best]))
    return candidates[best] / speed * min(float(reach[best]), dist)


def crowd_long_point(region: Region, goal: np.ndarray, velocity: np.ndarray, pedestrians: np.ndarray,
                     ped_velocities: np.ndarray, inflation: float, reach_time: float,
                     config: MpcCrowdConfig) -> np.ndarray:
    """``Q_l`` (robot frame, metres) for the best candidate velocity; zeros to stand still.

    Args:
        region: The scan's region (its polygon bounds ``Q_l``).
        goal: (2,) goal relative to the robot, metres.
        velocity: (2,) robot velocity, m/s.
        pedestrians: (P, 3) ``[x, y, r]`` relative to the robot, metres.
        ped_velocities: (P, 2) pedestrian velocities, m/s.
        inflation: R_inf, metres.
        reach_time: Time ``Q_l`` lies ahead at the candidate's speed (the MPC horizon), seconds.
        config: :class:`MpcCrowdConfig`.
    """
    scored = crowd_scores(region, goal, velocity, pedestrians, ped_velocities, inflation, reach_time, config)
    return best_long_point(*scored, goal)


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
