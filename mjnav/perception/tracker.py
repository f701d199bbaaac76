"""Non-privileged LiDAR pedestrian tracker: what the robot can know of the crowd from its own scan.

:class:`Tracker` turns one scan per control step plus the robot's own position (odometry, which
the robot knows; the pedestrians are never read from the simulator) into :class:`Track` s:
detection (:mod:`mjnav.perception.segment`), then association and filtering
(:mod:`mjnav.perception.filter`). Tracks whose centre never left a ``static_distance`` disc over
``static_age`` steps are static structure (a wall piece or an obstacle corner) and are kept to
absorb their detections but not reported; scan pieces that mostly hit cells of the robot's own
hit-count grid that were hit scan after scan are structure before they become detections.
Deterministic: the same scans give the same tracks.
"""

from __future__ import annotations

import dataclasses

import numpy as np
from numba import njit

from mjnav.geometry.raycast import beam_angles
from mjnav.perception.filter import CONFIRMED, TrackArrays, update_kernel
from mjnav.perception.segment import detect_kernel

__all__ = ["Track", "Tracker", "TrackerConfig", "TracksConfig", "nearest_tracks"]


@dataclasses.dataclass(frozen=True)
class TrackerConfig:
    """The tracker's settings (metres, seconds, control steps).

    Attributes:
        noise_std: LiDAR range noise σ, m, >= 0 (the task's ``lidar.noise_std``); sets the margin
            below the maximum range at which a beam counts as a miss (3σ).
        detect_range: Pieces of the scan whose nearest beam is farther than this are not reported
            (they are still segmented, so far walls stay walls), m.
        range_jump: Neighbouring beams whose ranges differ by more than this start a new cluster, m.
        range_jump_per_metre: Growth of that threshold with range, m per m of range.
        line_tolerance: Iterative end-point fit splits a piece while a point is farther than this
            from its chord, m.
        line_min_length: A straight piece this long or longer is structure, not a pedestrian, m.
        radius: Pedestrian radius range [min, max], m; fitted radii are clamped to it.
        split_margin: A run wider than ``2 radius[1] + split_margin`` is split at its deepest
            concavity (touching pedestrians), m.
        notch_depth: A run at least two smallest pedestrians wide is also split where its
            concavity is deeper than this, m (above the smoothed range noise).
        bump_depth: A run beside structure must rise this far above the structure's line towards
            the robot (mean over its points) to be a pedestrian, m.
        max_width: A run that cannot be split and is wider than this is structure, m.
        min_points: Fewest beams of one detection.
        map_cell: Cell size of the robot's own static-hit grid, m.
        map_size: Side of that grid, centred on the robot's first position of the episode, m.
        static_hits: Scans hitting a cell before it counts as static structure (at most 255: the
            grid counts in one byte).
        accel_std: Constant-velocity model's white-acceleration σ, m/s² (per √s).
        measurement_std: σ of a detected centre, m.
        initial_speed_std: σ of a new track's velocity, m/s.
        gate: Largest distance between a prediction and its detection, m.
        gate_chi2: Largest squared Mahalanobis distance (2 degrees of freedom).
        confirm_hits: M: detections needed to confirm a tentative track...
        confirm_window: N: ...within its first N steps.
        max_misses: K: a confirmed track dies after K consecutive steps without a detection.
        static_age: Steps after which a track that has not moved is static structure.
        static_distance: Farthest a static track's centre may have been from its birth, m.
        capacity: Track slots (and detections per scan).
    """

    noise_std: float = 0.05
    detect_range: float = 8.0
    range_jump: float = 0.3
    range_jump_per_metre: float = 0.03
    line_tolerance: float = 0.2
    line_min_length: float = 0.75
    radius: tuple[float, float] = (0.1, 0.4)
    split_margin: float = 0.15
    notch_depth: float = 0.1
    bump_depth: float = 0.12
    max_width: float = 1.2
    min_points: int = 2
    map_cell: float = 0.15
    map_size: float = 64.0
    static_hits: int = 30
    accel_std: float = 0.5
    measurement_std: float = 0.08
    initial_speed_std: float = 1.0
    gate: float = 0.8
    gate_chi2: float = 16.0
    confirm_hits: int = 2
    confirm_window: int = 3
    max_misses: int = 5
    static_age: int = 20
    static_distance: float = 0.3
    capacity: int = 128

    def __post_init__(self) -> None:
        if not self.noise_std >= 0.0:
            raise ValueError(f"tracker.noise_std: {self.noise_std} must be >= 0")
        positive = ("detect_range", "range_jump", "line_tolerance", "line_min_length",
                    "max_width", "accel_std", "measurement_std", "initial_speed_std", "gate", "gate_chi2",
                    "static_distance", "map_cell", "map_size")
        for name in positive:
            if not getattr(self, name) > 0.0:
                raise ValueError(f"tracker.{name}: {getattr(self, name)} must be > 0")
        lo, hi = self.radius
        if not 0.0 < lo <= hi:
            raise ValueError(f"tracker.radius: {self.radius} must be 0 < min <= max")
        for name in ("split_margin", "notch_depth", "bump_depth", "range_jump_per_metre"):
            if getattr(self, name) < 0.0:
                raise ValueError(f"tracker.{name}: {getattr(self, name)} must be >= 0")
        for name in ("min_points", "confirm_hits", "confirm_window", "max_misses", "static_age", "capacity",
                     "static_hits"):
            if getattr(self, name) < 1:
                raise ValueError(f"tracker.{name}: {getattr(self, name)} must be >= 1")
        if self.static_hits > 255:
            raise ValueError(f"tracker.static_hits: {self.static_hits} must be <= 255 (the static map counts hits in "
                             "one byte per cell)")
        if self.confirm_hits > self.confirm_window:
            raise ValueError(f"tracker.confirm_hits: {self.confirm_hits} exceeds confirm_window "
                             f"({self.confirm_window}): no track could be confirmed")


@dataclasses.dataclass(frozen=True)
class TracksConfig(TrackerConfig):
    """The task's ``tracks`` section: the tracker inside the task loop (:class:`TrackerConfig`'s
    fields, ``noise_std`` derived from ``lidar.noise_std``) and whether it runs.

    Attributes:
        enabled: Run the tracker in every episode; it also runs, whatever this says, when the
            planner declares ``uses_tracks`` (:func:`mjnav.planners.base.declared_tracks`).
            Off by default: an episode without tracks is the same as before they existed.
    """

    enabled: bool = False


@dataclasses.dataclass(frozen=True)
class Track:
    """One confirmed moving pedestrian as the robot estimates it (world frame).

    Attributes:
        id: Identity, unique within an episode.
        position: (2,) centre, m.
        velocity: (2,) m/s.
        radius: m.
        age: Steps since birth.
        covariance: (4, 4) covariance of ``[x, y, vx, vy]`` (m², m²/s, m²/s²).
    """

    id: int
    position: np.ndarray
    velocity: np.ndarray
    radius: float
    age: int
    covariance: np.ndarray


@njit(cache=True, error_model="numpy")
def _step_kernel(scan: np.ndarray, trig: np.ndarray, x: float, y: float, dt: float, params: np.ndarray,
                 grid: np.ndarray, detections: np.ndarray, floats: np.ndarray, ints: np.ndarray,
                 next_id: int) -> tuple[int, int]:
    """Detection then filtering in one call (one dispatch per control step): (detections, next id).

    ``trig`` is (2, B) beam cosines and sines; ``params`` the detection parameters (17) then the
    filter parameters (8).
    """
    n = detect_kernel(scan, trig[0], trig[1], x, y, params[:17], grid, detections)
    return n, update_kernel(floats, ints, detections, n, dt, params[17:], next_id)


class Tracker:
    """Tracks pedestrians across control steps from scans and the robot's own position.

    Args:
        config: Settings.
        beams: Beams per scan (beam ``b`` along ``2πb/beams`` in the world frame).
        max_range: The LiDAR's maximum range, m (a beam reading it hit nothing).
    """

    def __init__(self, config: TrackerConfig = TrackerConfig(), beams: int = 360, max_range: float = 10.0) -> None:
        if beams < 8 or not max_range > 0.0:
            raise ValueError(f"tracker: needs >= 8 beams and max_range > 0 (got {beams}, {max_range})")
        self.config, self.beams = config, beams
        angles = beam_angles(beams)
        self._trig = np.stack([np.cos(angles), np.sin(angles)])
        c = config
        limit = max_range - 3.0 * c.noise_std
        self._detect_params = np.array([limit, c.range_jump, c.line_tolerance, c.line_min_length, *c.radius,
                                        c.split_margin, c.max_width, c.min_points,
                                        c.notch_depth, c.bump_depth, c.detect_range, 1.0 / c.map_cell,
                                        0.0, 0.0, c.static_hits, c.range_jump_per_metre], dtype=np.float64)
        self._filter_params = np.array([c.accel_std, c.measurement_std, c.initial_speed_std, c.gate, c.gate_chi2,
                                        c.confirm_hits, c.confirm_window, c.max_misses], dtype=np.float64)
        self._params = np.concatenate([self._detect_params, self._filter_params])
        self._detect_params = self._params[:17]  # views: the grid origin is written through them
        self._detections = np.zeros((c.capacity, 3))
        self.reset()

    def reset(self) -> None:
        """Forget every track (a new episode); identities restart at 0."""
        self.arrays = TrackArrays(self.config.capacity)
        cells = int(np.ceil(self.config.map_size / self.config.map_cell))
        self._grid = np.zeros((cells, cells), dtype=np.uint8)  # counts saturate at 255 >= static_hits
        self._grid_placed = False
        self._next_id = 0
        self.num_detections = 0

    def step(self, ranges: np.ndarray, position: np.ndarray, dt: float) -> None:
        """Advance by one control step.

        Args:
            ranges: (beams,) LiDAR ranges, m.
            position: (2,) robot position in the world (its odometry), m.
            dt: Time since the previous scan, s.
        """
        if ranges.shape != (self.beams,):
            raise ValueError(f"tracker.step: scan of shape {ranges.shape}, expected ({self.beams},)")
        scan = np.ascontiguousarray(ranges, dtype=np.float64)
        x, y = float(position[0]), float(position[1])
        if not self._grid_placed:  # the static map is centred on the episode's first position
            self._detect_params[13:15] = x - 0.5 * self.config.map_size, y - 0.5 * self.config.map_size
            self._grid_placed = True
        self.num_detections, self._next_id = _step_kernel(
            scan, self._trig, x, y, float(dt), self._params, self._grid, self._detections, self.arrays.floats,
            self.arrays.ints, self._next_id)

    @property
    def detections(self) -> np.ndarray:
        """(n, 3) ``[x, y, r]`` detected this step (before association), world metres."""
        return self._detections[: self.num_detections].copy()

    def _reported(self) -> np.ndarray:
        """Slots of confirmed tracks that are not static, by identity."""
        a, c = self.arrays, self.config
        moving = ~((a.counts[:, 0] >= c.static_age) & (a.shape[:, 3] < c.static_distance))
        slots = np.flatnonzero((a.status == CONFIRMED) & moving)
        return slots[np.argsort(a.ids[slots], kind="stable")]

    def track_array(self) -> np.ndarray:
        """(n, 6) ``[x, y, vx, vy, radius, id]`` of the reported tracks (m, m/s), by identity."""
        a, slots = self.arrays, self._reported()
        return np.column_stack([a.state[slots], a.shape[slots, 0], a.ids[slots].astype(np.float64)])

    def tracks(self) -> list[Track]:
        """The reported tracks as :class:`Track` s, by identity."""
        a, out = self.arrays, []
        for t in self._reported():
            cov = np.zeros((4, 4))
            for ax in range(2):
                pp, pv, vv = a.cov[t, 3 * ax:3 * ax + 3]
                cov[ax, ax], cov[ax, 2 + ax], cov[2 + ax, ax], cov[2 + ax, 2 + ax] = pp, pv, pv, vv
            out.append(Track(int(a.ids[t]), a.state[t, :2].copy(), a.state[t, 2:].copy(), float(a.shape[t, 0]),
                             int(a.counts[t, 0]), cov))
        return out


def nearest_tracks(tracks: np.ndarray, position: np.ndarray, k: int) -> np.ndarray:
    """The ``k`` tracks nearest to ``position`` as a fixed-size planner input.

    Args:
        tracks: (n, >=5) rows ``[x, y, vx, vy, radius, ...]`` (:meth:`Tracker.track_array`).
        position: (2,) reference point (the robot), m.
        k: Rows returned.

    Returns:
        (k, 6) ``[x, y, vx, vy, radius, valid]`` nearest first; missing rows are zeros with valid 0.
    """
    out = np.zeros((k, 6))
    if len(tracks) and k:
        order = np.argsort(np.hypot(tracks[:, 0] - position[0], tracks[:, 1] - position[1]), kind="stable")[:k]
        out[: len(order), :5] = tracks[order, :5]
        out[: len(order), 5] = 1.0
    return out
