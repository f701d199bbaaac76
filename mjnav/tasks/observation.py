"""Observation of spec §6: 133 values per frame, 3 frames stacked → 399 (float32).

Per frame: a polygon block (60 boundary points as interleaved r̂, θ̂ → 120 values)
and a 13-value state block::

    [dθ/π, ρ/40, v_x/2.5, v_y/2.5, region_ok,
     θ(Q_s)/π, θ(Q_l)/π, (|Q_s|+R)/10, (|Q_l|+R)/10,
     θ(Q*_1)/π, θ(Q*_N)/π, (|Q*_1|+R)/10, (|Q*_N|+R)/10]

The stack is ``[polygon_{t-2}, polygon_{t-1}, polygon_t, state_{t-2}, state_{t-1}, state_t]``
(oldest first); at reset every slot holds the first frame.

With ``observation.history='aligned'`` (not in the paper) the older polygon blocks are
:func:`aligned_block` s: each older region read from the robot's current position along the
current block's bearings (:class:`RegionHistory` keeps the regions in world coordinates).

With ``observation.tracks=K`` (not in the paper; "Ours + tracks") the K nearest pedestrian tracks
of the robot's own LiDAR tracker (:mod:`mjnav.perception`, no simulator ground truth) follow the
stack, for the current frame only (:func:`tracks_block`), 5 values each, nearest centre first::

    [dx/10, dy/10, v_x/2.5, v_y/2.5, valid]

with ``(dx, dy)`` the track's centre relative to the robot (metres) and ``(v_x, v_y)`` its
estimated velocity (m/s), both in the observation's axes (turned into the goal frame with
``observation.frame=goal``), each clipped to [-1, 1], and valid = 1 for a track; missing slots
are zeros. The observation is then ``3·133 + 5K`` long; K = 0 is the paper's 399, bit for bit.
"""

from __future__ import annotations

import dataclasses
import functools
import math

import numpy as np
from numba import njit

from mjnav.geometry.polygon import _ray_polyline, points_in_polygon

__all__ = [
    "DISTANCE_SCALE",
    "POLYGON_SIZE",
    "STATE_SIZE",
    "TRACK_FEATURES",
    "FrameStack",
    "Plan",
    "RegionHistory",
    "aligned_block",
    "observation_size",
    "polygon_block",
    "state_block",
    "tracks_block",
]

DISTANCE_SCALE = 40.0  # ρ normaliser, metres
SPEED_SCALE = 2.5  # velocity normaliser, m/s (per-axis limit)
RANGE_SCALE = 10.0  # point-distance normaliser, metres (LiDAR range)
POLYGON_SIZE = 120
STATE_SIZE = 13
TRACK_FEATURES = 5  # [dx, dy, vx, vy, valid] per track (observation.tracks)


@dataclasses.dataclass(eq=False)
class Plan:
    """The last action and MPC plan, as the observation needs them (made every step: read-only by convention).

    Attributes:
        q_s, q_l: Action points relative to the robot at action time (network's own Q_l), metres.
        q1, qn: Planned p₁ and p_N relative to the robot at planning time, metres.
        q1_world, qn_world: The same planned points in the world frame, metres.
    """

    q_s: np.ndarray
    q_l: np.ndarray
    q1: np.ndarray
    qn: np.ndarray
    q1_world: np.ndarray
    qn_world: np.ndarray

    @functools.cached_property
    def points(self) -> np.ndarray:
        """(6, 2) rows q_s, q_l, q1, qn, q1_world, qn_world (what the jitted state block reads)."""
        return np.array([self.q_s, self.q_l, self.q1, self.qn, self.q1_world, self.qn_world], dtype=np.float64)


def observation_size(frames: int = 3, points: int = 60, state_size: int = STATE_SIZE, tracks: int = 0) -> int:
    """Length of the observation: the stack (399 for the defaults; designs keep fewer state values)
    plus :data:`TRACK_FEATURES` values for each of ``tracks`` track slots."""
    return frames * (2 * points + state_size) + TRACK_FEATURES * tracks


def tracks_block(tracks: np.ndarray | None, position: np.ndarray, count: int, rotation: float = 0.0) -> np.ndarray:
    """The ``count`` nearest tracks as the observation holds them (module docstring).

    Args:
        tracks: (T, >=4) rows ``[x, y, vx, vy, ...]`` of confirmed tracks, world frame (metres,
            m/s), in any order; None or empty: no track.
        position: (2,) robot position, world frame, metres.
        count: Slots K (>= 0); the K tracks with the nearest centres, the rest zeros.
        rotation: Angle (rad) of the observation's x axis in the world (``observation.frame``).

    Returns:
        (5K,) float64: ``[dx/10, dy/10, vx/2.5, vy/2.5, 1]`` per track, clipped to [-1, 1].

    Raises:
        ValueError: A negative ``count`` or rows with fewer than 4 values.
    """
    if count < 0:
        raise ValueError(f"tracks_block: count must be >= 0, got {count}")
    out = np.zeros((count, TRACK_FEATURES))
    rows = np.zeros((0, 4)) if tracks is None or np.size(tracks) == 0 else np.asarray(tracks, dtype=np.float64)
    if rows.ndim != 2 or rows.shape[1] < 4:
        raise ValueError(f"tracks_block: tracks must be (T, >=4) [x, y, vx, vy, ...], got shape {rows.shape}")
    if count == 0 or len(rows) == 0:
        return out.ravel()
    relative = rows[:, :2] - np.asarray(position, dtype=np.float64)[:2]
    order = np.argsort(np.hypot(relative[:, 0], relative[:, 1]), kind="stable")[:count]
    c, s = math.cos(rotation), math.sin(rotation)
    turn = np.array([[c, s], [-s, c]])  # world -> observation axes
    k = len(order)
    out[:k, 0:2] = relative[order] @ turn.T / RANGE_SCALE
    out[:k, 2:4] = rows[order, 2:4] @ turn.T / SPEED_SCALE
    np.clip(out[:k, :4], -1.0, 1.0, out=out[:k, :4])
    out[:k, 4] = 1.0
    return out.ravel()


def polygon_block(boundary: np.ndarray, inflation: float, rotation: float = 0.0) -> np.ndarray:
    """Interleaved (r̂, θ̂) of the resampled boundary points.

    Args:
        boundary: (M, 2) points as (r, θ) with r the shrunk distance in metres and θ in [0, 2π),
            in ascending θ (CCW from the smallest angle).
        inflation: R_inf in metres, added back to r.
        rotation: Angle (rad) of the observation's x axis (``observation.frame``): each θ becomes
            ``(θ − rotation) mod 2π`` and the points start again from the smallest.

    Returns:
        (2M,) float64 with r̂ = clip((r + R_inf)/10, 0, 1) and θ̂ = θ/2π.
    """
    b = np.asarray(boundary, dtype=np.float64)
    out = np.empty(2 * len(b))
    _polygon_kernel(b, float(inflation), float(rotation), out)
    return out


@njit(cache=True)
def _polygon_kernel(
    boundary: np.ndarray, inflation: float, rotation: float, out: np.ndarray
) -> None:  # pragma: no cover - numba
    m = boundary.shape[0]
    start, best = 0, 10.0
    if rotation != 0.0:
        for i in range(m):
            t = (boundary[i, 1] - rotation) % (2.0 * math.pi)
            if t < best:
                best, start = t, i
    for k in range(m):
        i = start + k if start + k < m else start + k - m
        out[2 * k] = min(max((boundary[i, 0] + inflation) / RANGE_SCALE, 0.0), 1.0)
        out[2 * k + 1] = ((boundary[i, 1] - rotation) % (2.0 * math.pi)) / (2.0 * math.pi)


def state_block(
    position: np.ndarray,
    velocity: np.ndarray,
    goal: np.ndarray,
    region_ok: bool,
    plan: Plan | None,
    inflation: float,
    angle_mode: str = "mpc",
    rotation: float = 0.0,
) -> np.ndarray:
    """The 13 state values of one frame.

    Args:
        position: Robot position, world frame, metres.
        velocity: Robot velocity, m/s.
        goal: Goal position, world frame, metres.
        region_ok: The free-space polygon succeeded for this frame's scan.
        plan: The last successful plan, or None at reset or after a failed plan.
        inflation: R_inf, metres.
        angle_mode: ``mpc`` (code) or ``velocity`` (paper) for the heading-error term.
        rotation: Angle (rad) of the observation's x axis (``observation.frame``): velocities are
            turned by ``-rotation`` and polar angles measured from it (dθ and distances do not change).

    Returns:
        (13,) float64.
    """
    robot = np.array([position, velocity, goal], dtype=np.float64).reshape(3, 2)
    points = _NO_PLAN if plan is None else plan.points
    out = np.empty(STATE_SIZE)
    _state_kernel(
        robot, bool(region_ok), plan is not None, points, float(inflation), angle_mode == "mpc", float(rotation), out
    )
    return out


_NO_PLAN = np.zeros((6, 2))


@njit(cache=True)
def _polar(x: float, y: float, inflation: float, rotation: float) -> tuple[float, float]:  # pragma: no cover
    angle = math.atan2(y, x)
    if rotation != 0.0:
        angle = (angle - rotation + math.pi) % (2.0 * math.pi) - math.pi
    return angle / math.pi, (math.hypot(x, y) + inflation) / RANGE_SCALE


@njit(cache=True)
def _state_kernel(
    robot: np.ndarray, region_ok: bool, has_plan: bool, points: np.ndarray, inflation: float, mpc_angle: bool,
    rotation: float, out: np.ndarray,
) -> None:  # pragma: no cover - numba; fmt: skip
    """:func:`state_block` into ``out``; rows of ``robot``: position, velocity, goal."""
    gx, gy = robot[2, 0] - robot[0, 0], robot[2, 1] - robot[0, 1]  # velocity against goal - position
    ax, ay = robot[1, 0], robot[1, 1]
    if mpc_angle and has_plan:  # Q*_1 -> Q*_N against Q*_1 -> goal
        ax, ay = points[5, 0] - points[4, 0], points[5, 1] - points[4, 1]
        gx, gy = robot[2, 0] - points[4, 0], robot[2, 1] - points[4, 1]
    out[0] = math.atan2(ax * gy - ay * gx, ax * gx + ay * gy) / math.pi
    out[1] = math.hypot(robot[2, 0] - robot[0, 0], robot[2, 1] - robot[0, 1]) / DISTANCE_SCALE
    c, s = math.cos(rotation), math.sin(rotation)
    out[2] = (c * robot[1, 0] + s * robot[1, 1]) / SPEED_SCALE
    out[3] = (c * robot[1, 1] - s * robot[1, 0]) / SPEED_SCALE
    out[4] = 1.0 if region_ok else 0.0
    if not has_plan:
        out[5] = out[6] = out[9] = out[10] = 0.0
        out[7] = out[8] = out[11] = out[12] = inflation / RANGE_SCALE
        return
    out[5], out[7] = _polar(points[0, 0], points[0, 1], inflation, rotation)
    out[6], out[8] = _polar(points[1, 0], points[1, 1], inflation, rotation)
    out[9], out[11] = _polar(points[2, 0], points[2, 1], inflation, rotation)
    out[10], out[12] = _polar(points[3, 0], points[3, 1], inflation, rotation)


class FrameStack:
    """Keeps the last ``frames`` polygon and state blocks and lays them out as spec §6.

    The blocks live in the float32 observation itself (polygon slots, then state slots), so a
    push shifts two slices and writes the new frame: no per-step concatenation or cast. With
    ``stride`` > 1 the stacked frames are ``stride`` pushes apart (the newest always last), taken
    from a history of the last ``(frames - 1) * stride + 1`` frames.
    """

    def __init__(self, frames: int = 3, points: int = 60, state_size: int = STATE_SIZE, stride: int = 1) -> None:
        """Create an empty stack for ``frames`` frames of ``points`` boundary points and
        ``state_size`` state values, ``stride`` pushes apart."""
        self._frames, self._poly, self._state, self._stride = frames, 2 * points, state_size, stride
        self._obs = np.zeros(frames * (2 * points + state_size), dtype=np.float32)
        self._polygons = self._obs[: frames * self._poly].reshape(frames, self._poly)  # views
        self._states = self._obs[frames * self._poly :].reshape(frames, state_size)
        history = (frames - 1) * stride + 1
        self._history = np.zeros((history, 2 * points + state_size), dtype=np.float32) if stride > 1 else None

    def reset(self, polygon: np.ndarray, state: np.ndarray) -> np.ndarray:
        """Fill every slot with the first frame and return the observation."""
        self._polygons[:] = polygon
        self._states[:] = state
        if self._history is not None:
            self._history[:, : self._poly] = polygon
            self._history[:, self._poly :] = state
        return self.observation()

    def push(self, polygon: np.ndarray, state: np.ndarray) -> np.ndarray:
        """Drop the oldest frame, append this one and return the observation."""
        if self._history is not None:
            history = self._history
            history[:-1] = history[1:]
            history[-1, : self._poly], history[-1, self._poly :] = polygon, state
            picked = history[:: self._stride]
            self._polygons[:], self._states[:] = picked[:, : self._poly], picked[:, self._poly :]
            return self.observation()
        obs, old, split = self._obs, self._poly * (self._frames - 1), self._poly * self._frames
        obs[:old] = obs[self._poly : split]  # overlapping slices: numpy copies as if buffered
        obs[old:split] = polygon
        obs[split : -self._state] = obs[split + self._state :]
        obs[-self._state :] = state
        return obs.copy()

    def observation(self) -> np.ndarray:
        """Stacked observation, float32: polygon blocks oldest first, then state blocks (a copy)."""
        return self._obs.copy()


def aligned_block(
    boundary: np.ndarray, older_xy: np.ndarray, position: np.ndarray, inflation: float, rotation: float = 0.0
) -> np.ndarray:
    """An older region's polygon block, read along the current region's bearings.

    The paper's older blocks list each past region's own boundary points, seen from where the
    robot was then; their bearings differ from frame to frame, so an approaching pedestrian does
    not show as a change at a fixed input. Here the older region (a closed polyline in world
    coordinates) is cut by rays from the robot's current position along the bearings of
    ``boundary``: the same θ̂ as the current block, and r̂ the older region's extent along them.

    Args:
        boundary: ``(M, 2)`` current boundary points as (r [m], θ [rad]) (``Region.boundary``).
        older_xy: ``(K, 2)`` the older region's boundary points in world coordinates, metres.
        position: ``(2,)`` robot position now, metres (world).
        inflation: R_inf in metres, added back to r as in :func:`polygon_block`.
        rotation: The current frame's rotation (``observation.frame``), radians.

    Returns:
        ``(2M,)`` float64 block laid out as :func:`polygon_block` lays out ``boundary``. Every r is 0
        when the robot now stands outside the older region (it left it, or its fallback polygon).
    """
    current = np.asarray(boundary, dtype=np.float64)
    older = np.asarray(older_xy, dtype=np.float64)
    origin = np.asarray(position, dtype=np.float64)
    reread = current.copy()
    if len(older) >= 3 and bool(points_in_polygon(origin, older)):
        _reread_kernel(origin, older, current, reread)
    else:
        reread[:, 0] = 0.0
    return polygon_block(reread, inflation, rotation)


@njit(cache=True)
def _reread_kernel(
    origin: np.ndarray, older: np.ndarray, current: np.ndarray, out: np.ndarray
) -> None:  # pragma: no cover - numba
    direction = np.empty(2)
    for i in range(current.shape[0]):
        direction[0], direction[1] = math.cos(current[i, 1]), math.sin(current[i, 1])
        t = _ray_polyline(origin, direction, older)
        out[i, 0] = t if t < math.inf else 0.0


class RegionHistory:
    """The last regions' boundaries in world coordinates, for ``observation.history='aligned'``.

    Keeps ``(frames - 1) * stride + 1`` boundaries (the newest last), the same frames as
    :class:`FrameStack` picks, and rewrites the older polygon blocks of an observation.
    """

    def __init__(self, frames: int = 3, stride: int = 1, points: int = 60) -> None:
        """History of ``frames`` frames ``stride`` control steps apart, ``points`` boundary points each."""
        self._stride, self._poly = stride, 2 * points
        self._history: list[np.ndarray] = []
        self._length = (frames - 1) * stride + 1

    def reset(self, boundary_xy: np.ndarray, position: np.ndarray) -> None:
        """Fill the history with the first region (robot-frame ``boundary_xy`` at ``position``)."""
        self._history = [np.asarray(boundary_xy, dtype=np.float64) + position] * self._length

    def push(self, boundary_xy: np.ndarray, position: np.ndarray) -> None:
        """Append this step's region (robot-frame ``boundary_xy`` at ``position``)."""
        self._history = [*self._history[1:], np.asarray(boundary_xy, dtype=np.float64) + position]

    def rewrite(
        self, obs: np.ndarray, boundary: np.ndarray, position: np.ndarray, inflation: float, rotation: float
    ) -> np.ndarray:
        """Replace the older polygon blocks of ``obs`` (laid out as :class:`FrameStack`) in place and
        return it; the newest block and the state blocks stay."""
        older = self._history[:: self._stride][:-1]  # oldest first, without the newest
        for k, xy in enumerate(older):
            obs[k * self._poly : (k + 1) * self._poly] = aligned_block(boundary, xy, position, inflation, rotation)
        return obs
