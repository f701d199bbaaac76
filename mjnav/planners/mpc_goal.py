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

With ``tracks`` (:class:`MpcGoalConfig`, ``planner.tracks=true``) the LiDAR tracks
(:attr:`mjnav.planners.base.PlannerInput.tracks`, not privileged) are obstacles too: every
tracked pedestrian's disc, predicted at constant velocity to ``track_samples`` times evenly
spread over the MPC horizon (``mpc.horizon`` × ``timing.control_period``), also stops the beams
(:func:`mjnav.planners.tracks.scan_with_discs`), and the region, ``Q_l``, ``Q_s`` and the MPC's
polygon constraint come from that scan: the robot keeps out of where the pedestrians will be
over the horizon, not only of where they are. Predicted discs that come within the region's
inflation (+ 5 cm) of the robot are left out (a convex region around the robot cannot exclude them).
It does not help "head for the goal" (2026-12-06, paper's rule, stage 7, 200 tuning scenarios from
``seed_offset=1000000000``): 65.0 % with tracks against 67.0 % without; ``track_samples`` 1 / 2 / 4
on the second hundred 66 / 66 / 67 % (without: 65 %). The region only gets smaller; where to go
instead is what ``mpc_tracked`` adds.

``mpc_gap`` (:class:`MpcGapPlanner`, not in the paper) is the same pipeline with one hand-made
choice more: when the goal is outside the polygon, ``Q_l`` goes along the direction (of
``directions`` evenly spaced ones) that maximises ``cos(angle to the goal) + clearance_weight ·
min(d, clearance_cap)/clearance_cap``, ``d`` the boundary distance along it, so the robot heads
for open space near the goal direction instead of into the nearest pedestrian. It shows what the
action layer can do with better reference points than "straight at the goal".

Tuning (:class:`MpcGapConfig`): stage 5, 200 tuning scenarios (``seed_offset=1000000000``,
:data:`mjnav.eval.runner.TUNING_SEED_OFFSET`), paper's rule, ``region.margin=0.1``; success with
(clearance_weight, clearance_cap) = (0, –) i.e. ``mpc_goal`` 75.5 %; (0.5, 2) 82.0 %; (1, 2) 84.0 %;
(2, 2) 85.5 %; (1, 4) 83.0 %; (2, 4) 89.0 %; (4, 4) 87.5 % (1 % timeouts, 8.8 m paths). Default
(2, 4); with it on the same stage-6 tuning scenarios 65.5 % (``mpc_goal`` 51.0 %, TEB 67.5 %).
"""

from __future__ import annotations

import dataclasses
import functools
import math
from typing import TYPE_CHECKING

import numpy as np

from mjnav.control.action import ActionConfig, boundary_distance, goal_inside, radii
from mjnav.control.dynamics import Limits, brake, escape
from mjnav.control.guarded import GuardedMpc
from mjnav.geometry.raycast import beam_angles
from mjnav.geometry.region import RegionFinder
from mjnav.planners.tracks import predicted_discs, relative_tracks, scan_with_discs
from mjnav.schema import ConfigError

__all__ = ["MpcGapConfig", "MpcGapPlanner", "MpcGoalConfig", "MpcGoalPlanner", "reference_points"]

#: Predicted discs closer than the region's inflation plus this to the robot are left out, metres.
_KEEP_OUT_MARGIN = 0.05


@dataclasses.dataclass(frozen=True)
class MpcGoalConfig:
    """Parameters of ``mpc_goal`` (see the module docstring).

    Attributes:
        tracks: Also keep out of the LiDAR tracks' predicted discs (declares ``uses_tracks``).
        track_samples: Prediction times over the MPC horizon (its end included, now excluded:
            the scan shows the pedestrians where they are).
    """

    tracks: bool = False
    track_samples: int = 4

    def __post_init__(self) -> None:
        """Reject a prediction without times."""
        if self.track_samples < 1:
            raise ConfigError(f"track_samples: must be >= 1, got {self.track_samples}")

if TYPE_CHECKING:
    from mjnav.config import TaskConfig
    from mjnav.geometry.region import Region
    from mjnav.planners.base import PlannerInput


@dataclasses.dataclass(frozen=True)
class MpcGapConfig:
    """Parameters of ``mpc_gap`` (see the module docstring).

    Attributes:
        clearance_weight: Weight of the capped boundary distance against the goal direction's cosine.
        clearance_cap: Boundary distance counted at most, metres.
        directions: Candidate directions, evenly spaced over the full circle.
        safety: Fraction of the boundary distance used for ``Q_l``.
    """

    clearance_weight: float = 2.0
    clearance_cap: float = 4.0
    directions: int = 72
    safety: float = 0.9

    def __post_init__(self) -> None:
        """Reject values that would make the choice meaningless."""
        if not (math.isfinite(self.clearance_weight) and self.clearance_weight >= 0.0):
            raise ConfigError(f"clearance_weight: must be finite and >= 0, got {self.clearance_weight}")
        if not (math.isfinite(self.clearance_cap) and self.clearance_cap > 0.0):
            raise ConfigError(f"clearance_cap: must be finite and > 0, got {self.clearance_cap}")
        if self.directions < 4:
            raise ConfigError(f"directions: must be >= 4, got {self.directions}")
        if not 0.0 < self.safety <= 1.0:
            raise ConfigError(f"safety: must be in (0, 1], got {self.safety}")


@functools.lru_cache(maxsize=8)
def _unit_directions(count: int) -> np.ndarray:
    """(count, 2) unit vectors evenly spaced over the circle (read-only, shared)."""
    angles = np.linspace(0.0, 2.0 * np.pi, count, endpoint=False)
    dirs = np.column_stack([np.cos(angles), np.sin(angles)])
    dirs.flags.writeable = False
    return dirs


def _gap_direction(region: Region, unit_goal: np.ndarray, gap: MpcGapConfig) -> tuple[np.ndarray, float]:
    """The candidate direction with the best goal/clearance score and its boundary distance (m)."""
    dirs = _unit_directions(gap.directions)
    free = np.array([boundary_distance(region, np.zeros(2), u) for u in dirs])
    score = dirs @ unit_goal + gap.clearance_weight * np.minimum(free, gap.clearance_cap) / gap.clearance_cap
    best = int(np.argmax(score))
    return dirs[best].copy(), float(free[best])


def reference_points(
    region: Region, goal: np.ndarray, r_s: float, safety: float = 0.9, gap: MpcGapConfig | None = None
) -> tuple[np.ndarray, np.ndarray, bool]:
    """``(Q_s, Q_l, goal_inside)`` towards the goal inside the region (robot frame, metres).

    Args:
        region: The scan's :class:`mjnav.geometry.region.Region`.
        goal: (2,) goal relative to the robot, metres.
        r_s: Short-term circle radius, metres.
        safety: Fraction of the boundary distance used for ``Q_l`` when the goal is outside.
        gap: ``mpc_gap``'s direction choice when the goal is outside (None: straight at the goal).

    Returns:
        Short-term point, long-term point and whether the goal is inside the region.
    """
    dist = float(np.hypot(*goal))
    if dist < 1e-9:
        return np.zeros(2), np.zeros(2), True
    direction = goal / dist
    inside = goal_inside(region, goal)
    if inside:
        q_l = goal.copy()
    elif gap is None:
        q_l = safety * min(boundary_distance(region, np.zeros(2), direction), dist) * direction
    else:
        direction, free = _gap_direction(region, direction, gap)
        q_l = safety * min(free, dist) * direction
    q_s = direction * min(r_s, float(np.hypot(*q_l)))
    return q_s, q_l, inside


class MpcGoalPlanner:
    """Region + MPC heading for the goal, as a :class:`mjnav.planners.base.Planner`."""

    #: Reads :attr:`PlannerInput.tracks` (per instance: ``MpcGoalConfig.tracks``).
    uses_tracks = False

    def __init__(self, config: MpcGoalConfig | None = None, *, safety: float = 0.9,
                 gap: MpcGapConfig | None = None) -> None:
        """``config``: :class:`MpcGoalConfig` (defaults when None); ``safety``: fraction of the
        boundary distance for Q_l when the goal is outside; ``gap``: ``mpc_gap``'s direction
        choice (None: straight at the goal)."""
        tracking = config or MpcGoalConfig()
        self.safety = safety
        self.gap = gap
        self._region_tracks = False
        self._track_samples = tracking.track_samples
        self._finder: RegionFinder | None = None
        self._track_times = np.zeros(0)
        if tracking.tracks:
            self._keep_out_of_tracks(tracking.track_samples)
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
        if self._region_tracks:
            self._finder = RegionFinder(beam_angles(config.lidar.beams), config.region)
            horizon = config.mpc.horizon * config.timing.control_period
            self._track_times = np.linspace(0.0, horizon, self._track_samples + 1)[1:]

    def _keep_out_of_tracks(self, samples: int) -> None:
        """Plan in the region of the scan stopped by the tracks' discs at ``samples`` times over the
        MPC horizon (module docstring); declares ``uses_tracks``."""
        self._region_tracks, self._track_samples, self.uses_tracks = True, samples, True

    def _with_tracks(self, inp: PlannerInput) -> PlannerInput:
        """``inp`` with its scan also stopped by the tracks' predicted discs and that scan's region."""
        discs = predicted_discs(relative_tracks(inp.tracks, inp.position), self._track_times)
        keep_out = self._finder.config.inflation + _KEEP_OUT_MARGIN
        scan = scan_with_discs(inp.scan, inp.angles, discs, self.limits.max_range, keep_out)
        return dataclasses.replace(inp, scan=scan, region=self._finder(scan))

    def reference(self, inp: PlannerInput, goal: np.ndarray, r_s: float) -> tuple[np.ndarray, np.ndarray, bool]:
        """``(Q_s, Q_l, goal_inside)`` for this step (robot frame, metres): :func:`reference_points`."""
        return reference_points(inp.region, goal, r_s, self.safety, self.gap)

    def act(self, inp: PlannerInput) -> np.ndarray:
        """Jerk for the next control period, m/s³ (brakes and counts on a bad input)."""
        v = np.asarray(inp.velocity, dtype=np.float64)
        a = np.asarray(inp.acceleration, dtype=np.float64)
        if self._region_tracks and inp.tracks is not None and len(inp.tracks):
            inp = self._with_tracks(inp)
        if self._mpc.must_escape(inp.region):  # no region even after recovery: back off
            self.stats["fallbacks"] += 1
            return escape(np.asarray(inp.scan), inp.angles, v, a, self.limits, self._escape_speed)
        try:
            r_s, _ = radii(v, a, self._action)
            goal = np.asarray(inp.goal) - inp.position
            q_s, q_l, inside = self.reference(inp, goal, r_s)
            result = self._mpc.solve(np.stack([np.zeros(2), v, a]), q_s, q_l, inp.region, inside)
        except (ValueError, FloatingPointError):
            self.stats["failures"] += 1
            return brake(np.nan_to_num(v), np.nan_to_num(a), self.limits)
        self.stats["fallbacks"] += int(result.fallback is not None)
        p = np.asarray(inp.position, dtype=np.float64)
        self.debug = {"q_s": p + q_s, "q_l": p + q_l, "predicted": p + result.positions}
        return np.asarray(result.u0, dtype=np.float64)


class MpcGapPlanner(MpcGoalPlanner):
    """Region + MPC heading for open space near the goal direction (``mpc_gap``)."""

    def __init__(self, config: MpcGapConfig | None = None) -> None:
        """``config``: :class:`MpcGapConfig` (defaults when None)."""
        config = config or MpcGapConfig()
        super().__init__(safety=config.safety, gap=config)
        self.config = config
