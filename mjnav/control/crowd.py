"""Choosing a velocity among candidates against the crowd's predicted motion (pure numpy).

The scoring core of ``mpc_crowd`` / ``mpc_tracked`` (:mod:`mjnav.planners.mpc_crowd`, whose
docstring gives the rule and its tuning) and of the action layer's crowd shield
(:class:`ShieldConfig`, :func:`shield_points`): each candidate velocity ``u`` is scored by its
progress towards the goal against how close its predicted path comes to the pedestrians, every one
moving at its constant velocity over the horizon. Positions are relative to the robot, in the
world's axes, metres; velocities m/s.
"""

from __future__ import annotations

import dataclasses
import math
from typing import TYPE_CHECKING

import numpy as np

from mjnav.control.action import boundary_distance
from mjnav.schema import ConfigError

__all__ = ["MpcCrowdConfig", "ShieldConfig", "best_long_point", "crowd_long_point", "crowd_scores",
           "shield_points"]

if TYPE_CHECKING:
    from mjnav.geometry.region import Region


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


@dataclasses.dataclass(frozen=True)
class ShieldConfig(MpcCrowdConfig):
    """The action layer's crowd shield (the task's ``shield`` section; not in the paper).

    With ``enabled``, every learned action's long-term point is checked against the robot's own
    LiDAR tracks (the task then runs the tracker): when the motion towards it would come within
    ``margin`` of a track's constant-velocity prediction, ``Q_l`` is replaced by the best-scoring
    candidate of :func:`crowd_scores` (:func:`shield_points`). While the tracker reports no track
    the layer is the paper's, bit for bit (in static scenes it rarely reports one: on 1,000 stage-2
    scenarios, which have no pedestrians, the shield stepped in at 344 of about 55,000 steps). The
    other fields are :class:`MpcCrowdConfig`'s.

    Attributes:
        enabled: Shield the learned action layer (off by default).
    """

    enabled: bool = False


def shield_points(region: Region, goal: np.ndarray, velocity: np.ndarray, q_l: np.ndarray, pedestrians: np.ndarray,
                  ped_velocities: np.ndarray, inflation: float, reach_time: float,
                  config: MpcCrowdConfig) -> np.ndarray | None:
    """The shield's ``Q_l`` in place of the action's ``q_l``, or None to keep it.

    The action's motion is taken as the velocity ``q_l / reach_time`` (at most ``max(speeds)``),
    predicted as a candidate of :func:`crowd_scores`; it is kept while its clearance is at least
    ``config.margin``. Arguments as for :func:`crowd_long_point`, plus ``q_l``: (2,) the action's
    long-term point relative to the robot, metres.

    Returns:
        (2,) the replacement ``Q_l`` (robot frame, metres; zeros to stand still), or None.
    """
    if len(pedestrians) == 0:
        return None
    own = np.asarray(q_l, dtype=np.float64) / reach_time
    speed, top = float(np.hypot(*own)), max(config.speeds)
    if speed > top:
        own = own * (top / speed)
    clearance = _clearance(own[None], velocity, pedestrians, ped_velocities, inflation, config)[0]
    if clearance >= config.margin:
        return None
    return crowd_long_point(region, goal, velocity, pedestrians, ped_velocities, inflation, reach_time, config)
