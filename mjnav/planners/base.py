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

__all__ = ["PRIVILEGED_FIELDS", "Planner", "PlannerInput", "declared_privileged", "declared_tracks"]

#: The ground truth a planner may declare in its ``privileged`` attribute (pedestrian positions,
#: velocities, radii and goals, as the simulation's crowd model has them).
PRIVILEGED_FIELDS = frozenset({"positions", "velocities", "radii", "goals"})


@dataclasses.dataclass(frozen=True)
class PlannerInput:
    """What a non-learned planner sees at the start of a control step.

    Everything a robot could measure is always there. The simulator's ground truth about the
    pedestrians (``pedestrian_*``) is there only for what the planner declared in its
    ``privileged`` attribute (:data:`PRIVILEGED_FIELDS`); the rest is None.

    Attributes:
        scan: (B,) LiDAR ranges as the robot sees them (noisy), metres, clipped to [0, max range].
        angles: (B,) beam angles, radians (beam 0 along the world +x axis, counter-clockwise).
        position: (2,) robot position, world frame, metres.
        velocity: (2,) robot velocity, world frame, m/s.
        acceleration: (2,) robot (reference) acceleration, world frame, m/s².
        goal: (2,) goal, world frame, metres.
        region: The free-space polygon of this scan (robot-centred, world-aligned axes, metres).
        time: Time since the episode start, seconds.
        pedestrian_positions: (P, 2) pedestrian centres, world frame, metres (``"positions"``).
        pedestrian_velocities: (P, 2) pedestrian velocities over the last physics substep, world
            frame, m/s (``"velocities"``; the crowd model's own at the first step).
        pedestrian_radii: (P,) pedestrian disc radii, metres (``"radii"``).
        pedestrian_goals: (P, 2) where each pedestrian is heading, world frame, metres (``"goals"``;
            NaN rows for crowd models without goals, such as the random walk).
        tracks: (T, 5) ``[x, y, vx, vy, r]`` the robot's own LiDAR tracker estimates of the moving
            pedestrians (world frame, metres, m/s), nearest to the robot first; not privileged
            (made from this step's ``scan`` and ``position`` only). None unless the planner declared
            ``uses_tracks`` or the task has ``tracks.enabled`` (:func:`declared_tracks`).
    """

    scan: np.ndarray
    angles: np.ndarray
    position: np.ndarray
    velocity: np.ndarray
    acceleration: np.ndarray
    goal: np.ndarray
    region: Region
    time: float
    pedestrian_positions: np.ndarray | None = None
    pedestrian_velocities: np.ndarray | None = None
    pedestrian_radii: np.ndarray | None = None
    pedestrian_goals: np.ndarray | None = None
    tracks: np.ndarray | None = None

    @property
    def pedestrians(self) -> np.ndarray:
        """(P, 3) ``[x, y, r]`` (world frame, metres) from the declared positions and radii (NaN radii
        when only positions were declared); (0, 3) without declared positions."""
        if self.pedestrian_positions is None:
            return np.zeros((0, 3))
        positions = np.asarray(self.pedestrian_positions, dtype=np.float64).reshape(-1, 2)
        radii = np.full(len(positions), np.nan) if self.pedestrian_radii is None else self.pedestrian_radii
        return np.column_stack([positions, radii])


def declared_privileged(planner: object) -> frozenset[str]:
    """The ground truth ``planner`` (an instance or its class) declared in its ``privileged`` attribute.

    Raises:
        ValueError: ``privileged`` is not a set of names from :data:`PRIVILEGED_FIELDS`.
    """
    declared = getattr(planner, "privileged", frozenset())
    if isinstance(declared, str) or not isinstance(declared, (set, frozenset, tuple, list)):
        raise ValueError(f"planner {_name(planner)}: privileged must be a frozenset of names from "
                         f"{sorted(PRIVILEGED_FIELDS)}, got {declared!r}")
    unknown = set(declared) - PRIVILEGED_FIELDS
    if unknown:
        raise ValueError(f"planner {_name(planner)}: unknown privileged {sorted(unknown)} "
                         f"(known: {sorted(PRIVILEGED_FIELDS)})")
    return frozenset(declared)


def declared_tracks(planner: object) -> bool:
    """Whether ``planner`` (an instance or its class; None: no planner) reads the LiDAR tracks: its
    ``uses_tracks`` attribute (False when absent). An instance may decide it from its parameters.

    Raises:
        ValueError: ``uses_tracks`` is not a bool.
    """
    declared = getattr(planner, "uses_tracks", False)
    if not isinstance(declared, (bool, np.bool_)):
        raise ValueError(f"planner {_name(planner)}: uses_tracks must be True or False, got {declared!r}")
    return bool(declared)


def _name(planner: object) -> str:
    return planner.__name__ if isinstance(planner, type) else type(planner).__name__


class Planner(typing.Protocol):
    """A baseline controller: replaces the learned action layer, same episode and scoring.

    Optional attributes: ``privileged`` (the ground truth it reads, a subset of
    :data:`PRIVILEGED_FIELDS`; none when absent), ``uses_tracks`` (True: it reads
    :attr:`PlannerInput.tracks`, and the task runs the LiDAR tracker for it), ``config_class`` (the dataclass its constructor
    takes, for ``planner.<field>=value``) and ``stats`` (a dict of integer counters recorded per
    episode). The planners guide of the documentation describes each.
    """

    def reset(self, config: TaskConfig, rng: np.random.Generator) -> None:
        """Start an episode of the task ``config`` with its own generator."""

    def act(self, inp: PlannerInput) -> np.ndarray:
        """Jerk (2,) in m/s³ to apply over the next control period."""
