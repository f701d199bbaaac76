"""``mpc_tracked``: the action layer steered by the robot's own LiDAR tracks (not privileged).

The non-privileged twin of :mod:`mjnav.planners.mpc_crowd`: the same convex region, MPC and
fallbacks, and the same choice of ``Q_l`` among candidate velocities scored against every
pedestrian's constant-velocity motion over ``horizon`` (:func:`mjnav.planners.mpc_crowd.crowd_scores`),
with the pedestrians taken from :attr:`mjnav.planners.base.PlannerInput.tracks` (the tracker's
estimated centres, velocities and radii, made from the robot's scan and position) instead of the
simulator. Only what the tracker reports is avoided: pedestrians hidden behind others or not yet
confirmed are in the scan (so in the region) but not in the prediction.

With ``track_region`` the MPC also plans in the region of the scan stopped by the tracks'
discs predicted over its horizon (``mpc_goal``'s ``planner.tracks=true``, see
:mod:`mjnav.planners.mpc_goal`): its polygon constraint then keeps the whole predicted path out
of where the pedestrians will be.

Parameters: :class:`MpcTrackedConfig`, those of ``mpc_crowd`` (same defaults) plus
``track_region`` and ``track_samples``.

Development check (2026-12-06; paper's collision rule, default task config, stage tuning scenarios
``seed_offset=1000000000`` (:data:`mjnav.eval.runner.TUNING_SEED_OFFSET`), 200 per stage, never
the held-out sets): stage 6 / 7 success ``mpc_tracked`` 92.5 / 80.5 %, ``mpc_crowd`` (privileged)
94.5 / 83.0 %, ``mpc_goal`` 73.0 / 67.0 %. On stage 7's second hundred (``seed_offset=1000000100``)
mpc_crowd's defaults were kept: margin 0.4 / 0.5 / 0.6 m 81 / 78 / 79 %, weight 4 80 %, margin 0.5
with weight 4 78 %, horizon 3 s 77 %, all within the noise of 100 episodes (± 8 points).
``track_region=true`` on the first hundred: 90 / 80 % (stage 6 / 7) against 94 / 80 %; off by
default. Command: ``mjnav evaluate task=stage7 policy=mpc_tracked episodes=100
seed_offset=1000000000 task.collision=scan``.
"""

from __future__ import annotations

import dataclasses
from typing import TYPE_CHECKING

import numpy as np

from mjnav.planners.mpc_crowd import MpcCrowdConfig, MpcCrowdPlanner
from mjnav.planners.tracks import relative_tracks
from mjnav.schema import ConfigError

__all__ = ["MpcTrackedConfig", "MpcTrackedPlanner"]

if TYPE_CHECKING:
    from mjnav.planners.base import PlannerInput


@dataclasses.dataclass(frozen=True)
class MpcTrackedConfig(MpcCrowdConfig):
    """Parameters of ``mpc_tracked``: :class:`MpcCrowdConfig`'s, plus

    Attributes:
        track_region: Also plan in the region that excludes the tracks' predicted discs.
        track_samples: Prediction times over the MPC horizon for ``track_region``.
    """

    track_region: bool = False
    track_samples: int = 4

    def __post_init__(self) -> None:
        """:class:`MpcCrowdConfig`'s checks, and at least one prediction time."""
        super().__post_init__()
        if self.track_samples < 1:
            raise ConfigError(f"track_samples: must be >= 1, got {self.track_samples}")


class MpcTrackedPlanner(MpcCrowdPlanner):
    """Region + MPC with ``Q_l`` from the LiDAR tracks' motion (``mpc_tracked``, not privileged)."""

    #: No ground truth: the pedestrians come from the robot's own tracker.
    privileged = frozenset()
    #: Reads :attr:`PlannerInput.tracks` (the task runs the tracker for it).
    uses_tracks = True
    config_class = MpcTrackedConfig

    def __init__(self, config: MpcTrackedConfig | None = None) -> None:
        """``config``: :class:`MpcTrackedConfig` (defaults when None)."""
        config = config or MpcTrackedConfig()
        super().__init__(config)
        if config.track_region:
            self._keep_out_of_tracks(config.track_samples)

    def crowd(self, inp: PlannerInput) -> tuple[np.ndarray, np.ndarray]:
        """The tracked pedestrians: ((T, 3) ``[x, y, r]`` relative to the robot, metres; (T, 2)
        velocities, m/s); none when the tracks are missing."""
        tracks = relative_tracks(inp.tracks, inp.position)
        return tracks[:, [0, 1, 4]], tracks[:, 2:4]
