"""The planner protocol: what a non-learned controller sees and returns each control step.

A planner (:mod:`mjnav.planners`) replaces the learned action layer of the task; the episode and
its scoring stay the same. The task builds a :class:`PlannerInput` from the scan and the robot
state and applies the jerk :meth:`Planner.act` returns over one control period.
"""

from __future__ import annotations

import dataclasses
import typing

import numpy as np

from mjnav.geometry.region import Region

if typing.TYPE_CHECKING:
    from mjnav.config import TaskConfig

__all__ = ["Planner", "PlannerInput"]


@dataclasses.dataclass(frozen=True)
class PlannerInput:
    """What a non-learned planner (baseline) sees at the start of a control step.

    Attributes:
        scan: LiDAR ranges as the robot sees them (noisy), metres.
        angles: Beam angles, radians (beam 0 along +x, CCW).
        position: Robot position, world frame, metres.
        velocity: Robot velocity, m/s.
        acceleration: Robot (reference) acceleration, m/s².
        goal: Goal, world frame, metres.
        region: The free-space polygon of this scan (robot frame).
        time: Time since the episode start, seconds.
        pedestrians: (P, 3) ``[x, y, r]`` of the pedestrians, world frame, metres: the simulator's
            ground truth, which a robot does not have; only privileged planners (``mpc_crowd``)
            read it.
    """

    scan: np.ndarray
    angles: np.ndarray
    position: np.ndarray
    velocity: np.ndarray
    acceleration: np.ndarray
    goal: np.ndarray
    region: Region
    time: float
    pedestrians: np.ndarray = dataclasses.field(default_factory=lambda: np.zeros((0, 3)))


class Planner(typing.Protocol):
    """A baseline controller: replaces the learned action layer, same episode and scoring."""

    def reset(self, config: TaskConfig, rng: np.random.Generator) -> None:
        """Start an episode of the task ``config`` with its own generator."""

    def act(self, inp: PlannerInput) -> np.ndarray:
        """Jerk (2,) in m/s³ to apply over the next control period."""
