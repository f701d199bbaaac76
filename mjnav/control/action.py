"""Policy action -> short- and long-term reference points (spec §4).

The policy emits four values already squashed by a sigmoid, ``(α_s, β_s, α_l, β_l) ∈ [0, 1]⁴``.
Everything here is in the robot frame (metres, radians, SI).

* Short-term circle radius ``R_s = short_scale × reach(t_c)``; long-term radius
  ``R_l = max(long_min_radius, reach(long_time))`` (``long_circle='code'``) or ``reach(long_time)``
  (``'paper'``). ``reach(t)`` is the farthest ``|v t + a t²/2 + j t³/6|`` over four jerk
  directions (velocity heading, acceleration heading, their bisector and its negative) with
  ``|j| = jerk_max·√2`` (the box corner).
* ``θ_s = 2π α_s + heading(v)`` (``heading='velocity'``, code) or ``2π α_s`` (``'absolute'``,
  paper), or ``2π α_s + direction(goal)`` (``'goal'``, not in the paper: see
  :class:`ActionConfig`); heading of a zero vector is 0. The ray from the robot at ``θ_s``
  meets the boundary of polygon ∩ disc(R_s) at distance ``d_θ^s`` (exact: ``min`` of the exact
  ray/convex-polygon distance and ``R_s``); ``Q_s = β_s d_θ^s (cos θ_s, sin θ_s)``.
* ``θ_l = θ_s + 2π α_l`` (= ``2π α_l`` + direction O→Q_s); from ``Q_s`` the ray meets
  polygon ∩ disc(O, R_l) at ``d_θ^l``; ``Q_l = Q_s + β_l d_θ^l (cos θ_l, sin θ_l)``.
  If ``Q_s`` is not inside disc(R_l) (impossible with the defaults), ``d_θ^l = 0``.
* Goal inside the polygon -> the MPC reference is the goal (:attr:`ActionPoints.q_l_ref`); the
  network's own point stays in :attr:`ActionPoints.q_l` (observation, feasibility reward).

A recovered region (``region.recovered``, see :mod:`mjnav.geometry.region`) is used like a found
one. Failed region without a polygon (``region.has_polygon`` False): the action polygon is the fallback star polygon (every
6th beam's shrunk point, not convex). Rays are then cast against that closed polyline (first
crossing) and the goal test is an even-odd point-in-polygon test on it.

:func:`map_action` runs as one numba kernel (the per-step Python glue had cost more than the
geometry); :func:`boundary_distance`, :func:`goal_inside` and :func:`radii` are the same rules as
plain functions, and the tests hold the kernel to them.
"""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Sequence
from typing import Literal

import numpy as np
from numba import njit

from mjnav.control.dynamics import Limits, coast, jerk_travel
from mjnav.geometry.polygon import (
    _point_in_halfplanes,
    _ray_circle,
    _ray_convex,
    _ray_polyline,
    point_in_halfplanes,
    points_in_polygon,
    ray_convex_distance,
    ray_polyline_distance,
)
from mjnav.geometry.region import Region
from mjnav.schema import check as _check

__all__ = [
    "ActionConfig", "ActionPoints", "boundary_distance", "goal_inside", "heading_angle", "map_action",
    "map_action_values", "radii", "reach_distance",
]

TWO_PI = 2.0 * math.pi



@dataclasses.dataclass(frozen=True)
class ActionConfig:
    """Action mapping parameters (spec §4).

    Attributes:
        heading: ``velocity`` (θ_s offset by the velocity heading, code), ``absolute`` (paper) or
            ``goal`` (θ_s offset by the goal direction; not in the paper: with it α = 0.5 puts Q_s
            straight away from the goal and Q_l, for α_l = 0.5, straight towards it, so the
            network's outputs are measured from the one direction that matters most; pair it with
            ``observation.frame='goal'``); for Designs 1-2 the axes of the velocity command
            (velocity heading, world or goal direction).
        long_circle: ``code`` (R_l = max(long_min_radius, 1-s reach)) or ``paper`` (1-s reach).
        jerk_max: Per-axis jerk bound, m/s³; the reach uses ``|j| = jerk_max·√2``.
        t_c: Control period, s (short-term reach time).
        long_time: Long-term reach time T = N·t_c, s.
        short_scale: Factor on the one-period reach for R_s.
        long_min_radius: Lower bound on R_l with ``long_circle='code'``, metres.
    """

    heading: Literal["velocity", "absolute", "goal"] = "velocity"
    long_circle: Literal["code", "paper"] = "code"
    jerk_max: float = Limits.j_max
    t_c: float = Limits.control_period
    long_time: float = 1.0
    short_scale: float = 3.0
    long_min_radius: float = 10.0

    def __post_init__(self) -> None:
        _check(
            self.heading in ("velocity", "absolute", "goal"), "heading", "must be 'velocity', 'absolute' or 'goal'"
        )
        _check(self.long_circle in ("code", "paper"), "long_circle", "must be 'code' or 'paper'")
        for name in ("jerk_max", "t_c", "long_time", "short_scale"):
            value = getattr(self, name)
            _check(math.isfinite(value) and value > 0.0, name, "must be finite and > 0")
        _check(
            math.isfinite(self.long_min_radius) and self.long_min_radius >= 0.0,
            "long_min_radius",
            "must be >= 0",
        )


@dataclasses.dataclass(eq=False, slots=True)
class ActionPoints:
    """Reference points of one action (robot frame; made every step, so not frozen: treat as read-only).

    Attributes:
        q_s: ``(2,)`` short-term point Q_s, metres.
        q_l: ``(2,)`` the network's long-term point Q_l, metres (observation, r_f, r_c).
        q_l_ref: ``(2,)`` long-term reference for the MPC: the goal if inside, else ``q_l``.
        theta_s: Ray angle θ_s wrapped to [-π, π), rad.
        theta_l: Ray angle θ_l wrapped to [-π, π), rad.
        d_theta_s: Boundary distance along the short ray, metres.
        d_theta_l: Boundary distance along the long ray (from Q_s), metres.
        r_s: Short-term radius R_s, metres.
        r_l: Long-term radius R_l, metres.
        goal_inside: Whether the goal lies in the action polygon.
    """

    q_s: np.ndarray
    q_l: np.ndarray
    q_l_ref: np.ndarray
    theta_s: float
    theta_l: float
    d_theta_s: float
    d_theta_l: float
    r_s: float
    r_l: float
    goal_inside: bool


def reach_distance(velocity: np.ndarray, acceleration: np.ndarray, t: float, jerk_norm: float) -> float:
    """Farthest one-shot travel ``|v t + a t²/2 + j t³/6|`` over the four spec jerk directions.

    Args:
        velocity: ``(2,)`` velocity, m/s.
        acceleration: ``(2,)`` acceleration, m/s².
        t: Duration, s.
        jerk_norm: Jerk magnitude, m/s³.

    Returns:
        Distance in metres.
    """
    vx, vy, ax, ay = float(velocity[0]), float(velocity[1]), float(acceleration[0]), float(acceleration[1])
    return _reach_max(vx, vy, ax, ay, float(t), float(jerk_norm))


def map_action(
    action01: np.ndarray,
    region: Region,
    velocity: np.ndarray,
    acceleration: np.ndarray,
    goal_rel: np.ndarray,
    config: ActionConfig | None = None,
) -> ActionPoints:
    """Map a squashed action to Q_s, Q_l (spec §4).

    Args:
        action01: ``(4,)`` ``(α_s, β_s, α_l, β_l)`` in [0, 1] (the caller applies the sigmoid).
        region: The current :class:`~mjnav.geometry.region.Region`.
        velocity: ``(2,)`` robot velocity, m/s.
        acceleration: ``(2,)`` robot acceleration, m/s².
        goal_rel: ``(2,)`` goal relative to the robot, metres.
        config: Mapping parameters; defaults to :class:`ActionConfig()`.

    Returns:
        The :class:`ActionPoints`.

    Raises:
        ValueError: On badly shaped or non-finite inputs, or an action outside [0, 1].
    """
    return map_action_values(_validate(action01, velocity, acceleration, goal_rel), region, config)


def map_action_values(values: Sequence[float], region: Region, config: ActionConfig | None = None) -> ActionPoints:
    """:func:`map_action` on ten plain floats, without its input checks.

    For callers that have already checked the inputs (the task checks them once per step).

    Args:
        values: ``α_s, β_s, α_l, β_l`` (each in [0, 1]), ``vx, vy`` (m/s), ``ax, ay`` (m/s²) and
            ``gx, gy`` (goal relative to the robot, metres), all finite Python floats.
        region: The current :class:`~mjnav.geometry.region.Region`.
        config: Mapping parameters; defaults to :class:`ActionConfig()`.

    Returns:
        The :class:`ActionPoints`.
    """
    cfg = config if config is not None else _DEFAULT
    out = _map_kernel(
        *values, region.has_polygon, region.normals, region.offsets, region.boundary_xy,
        heading_angle(cfg.heading, values[4:6], values[8:10]), cfg.long_circle == "code",
        cfg.jerk_max * math.sqrt(2.0), cfg.t_c, cfg.long_time, cfg.short_scale, cfg.long_min_radius,
    )  # fmt: skip
    q_s, q_l = np.array(out[0:2]), np.array(out[2:4])
    inside = bool(out[10])
    goal = np.array(values[8:10])
    return ActionPoints(q_s, q_l, goal if inside else q_l, out[4], out[5], out[6], out[7], out[8], out[9], inside)


@njit(cache=True)
def _map_kernel(
    a_s: float, b_s: float, a_l: float, b_l: float, vx: float, vy: float, ax: float, ay: float,
    gx: float, gy: float, convex: bool, normals: np.ndarray, offsets: np.ndarray, star: np.ndarray,
    heading: float, code_circle: bool, jerk: float, t_c: float, long_time: float,
    short_scale: float, long_min_radius: float,
) -> tuple:  # pragma: no cover - numba; fmt: skip
    """:func:`map_action` on floats: (qsx, qsy, qlx, qly, θ_s, θ_l, d_s, d_l, R_s, R_l, inside)."""
    r_s, r_l = _radii_kernel(vx, vy, ax, ay, jerk, t_c, long_time, short_scale, code_circle, long_min_radius)
    theta_s = TWO_PI * a_s + heading
    cs, ss = math.cos(theta_s), math.sin(theta_s)
    d_s = min(_boundary(convex, normals, offsets, star, 0.0, 0.0, cs, ss), r_s)
    qsx, qsy = (b_s * d_s) * cs, (b_s * d_s) * ss
    theta_l = theta_s + TWO_PI * a_l
    cl, sl = math.cos(theta_l), math.sin(theta_l)
    d_l = min(_boundary(convex, normals, offsets, star, qsx, qsy, cl, sl), _ray_circle(qsx, qsy, cl, sl, r_l))
    qlx, qly = qsx + (b_l * d_l) * cl, qsy + (b_l * d_l) * sl
    if convex:
        inside = _point_in_halfplanes(np.array((gx, gy)), normals, offsets, 0.0)
    else:
        inside = _in_star(gx, gy, star)
    return qsx, qsy, qlx, qly, _wrap(theta_s), _wrap(theta_l), d_s, d_l, r_s, r_l, inside


def heading_angle(mode: str, velocity: Sequence[float], goal_rel: Sequence[float]) -> float:
    """Angle (rad) the action's directions are measured from (:attr:`ActionConfig.heading`).

    Args:
        mode: ``velocity``, ``absolute`` or ``goal``.
        velocity: Robot velocity, m/s.
        goal_rel: Goal relative to the robot, metres.

    Returns:
        The velocity heading, 0, or the goal direction; the heading of a zero vector is 0.
    """
    x, y = (velocity[0], velocity[1]) if mode == "velocity" else (goal_rel[0], goal_rel[1])
    if mode == "absolute" or (x == 0.0 and y == 0.0):  # also -0.0, whose atan2 is ±π
        return 0.0
    return math.atan2(y, x)


def radii(velocity: np.ndarray, acceleration: np.ndarray, config: ActionConfig) -> tuple[float, float]:
    """Short- and long-term circle radii ``(R_s, R_l)`` in metres (spec §4)."""
    return _radii_kernel(
        float(velocity[0]), float(velocity[1]), float(acceleration[0]), float(acceleration[1]),
        config.jerk_max * math.sqrt(2.0), config.t_c, config.long_time, config.short_scale,
        config.long_circle == "code", config.long_min_radius,
    )  # fmt: skip


_DEFAULT = ActionConfig()


@njit(cache=True)
def _wrap(angle: float) -> float:
    """Wrap an angle to [-π, π)."""
    return (angle + math.pi) % TWO_PI - math.pi


@njit(cache=True)
def _reach_max(vx: float, vy: float, ax: float, ay: float, t: float, jerk: float) -> float:  # pragma: no cover
    """Farthest travel over t for the four jerk directions (velocity, acceleration, ± bisector)."""
    th_v, th_a = math.atan2(vy, vx), math.atan2(ay, ax)
    th_b = th_v + _wrap(th_a - th_v) / 2.0
    bx, by, jt = coast(vx, ax, t), coast(vy, ay, t), jerk_travel(jerk, t)
    best = -1.0
    for th, sign in ((th_v, 1.0), (th_a, 1.0), (th_b, 1.0), (th_b, -1.0)):
        c, s = sign * math.cos(th), sign * math.sin(th)
        best = max(best, math.hypot(bx + jt * c, by + jt * s))
    return best


@njit(cache=True)
def _radii_kernel(
    vx: float, vy: float, ax: float, ay: float, jerk: float, t_c: float, long_time: float, short_scale: float,
    code_circle: bool, long_min_radius: float,
) -> tuple[float, float]:  # pragma: no cover - numba; fmt: skip
    """(R_s, R_l) of :func:`radii` on floats (``jerk`` is the jerk norm, m/s³)."""
    r_l = _reach_max(vx, vy, ax, ay, long_time, jerk)
    return short_scale * _reach_max(vx, vy, ax, ay, t_c, jerk), (max(long_min_radius, r_l) if code_circle else r_l)


@njit(cache=True)
def _boundary(
    convex: bool, normals: np.ndarray, offsets: np.ndarray, star: np.ndarray, ox: float, oy: float,
    dx: float, dy: float,
) -> float:  # pragma: no cover - numba; fmt: skip
    """:func:`boundary_distance` on floats (the geometry module's jitted ray casts)."""
    origin, direction = np.array((ox, oy)), np.array((dx, dy))
    if convex:
        return _ray_convex(origin, direction, normals, offsets)
    hit = _ray_polyline(origin, direction, star)
    return 0.0 if math.isinf(hit) else hit


@njit(cache=True)
def _in_star(x: float, y: float, vertices: np.ndarray) -> bool:  # pragma: no cover
    """:func:`~mjnav.geometry.polygon.points_in_polygon` (even-odd) for one point."""
    k, crossings = vertices.shape[0], 0
    for i in range(k):
        j = i + 1 if i + 1 < k else 0  # wrap by compare: `%` divides
        ay, by = vertices[i, 1], vertices[j, 1]
        if (ay > y) != (by > y):
            x_cross = vertices[i, 0] + (y - ay) * (vertices[j, 0] - vertices[i, 0]) / (by - ay)
            crossings += x < x_cross
    return crossings % 2 == 1


def _validate(
    action01: np.ndarray, velocity: np.ndarray, acceleration: np.ndarray, goal_rel: np.ndarray
) -> list[float]:
    """The ten inputs as Python floats; ValueError naming the first bad argument."""
    args = (
        ("action01", action01, 4),
        ("velocity", velocity, 2),
        ("acceleration", acceleration, 2),
        ("goal_rel", goal_rel, 2),
    )
    values: list[float] = []
    for name, value, size in args:
        flat = np.ravel(value).tolist()
        if len(flat) != size or not all(map(math.isfinite, flat)):
            raise ValueError(f"{name}: expected {size} finite values, got {flat}")
        values += flat
    if min(values[:4]) < 0.0 or max(values[:4]) > 1.0:
        raise ValueError(f"action01: values must lie in [0, 1] (sigmoid-squashed), got {values[:4]}")
    return [float(v) for v in values]


def boundary_distance(region: Region, origin: np.ndarray, direction: np.ndarray) -> float:
    """Distance along the ray to the action polygon's boundary (convex, or the fallback polyline)."""
    if region.has_polygon:
        return ray_convex_distance(origin, direction, region.normals, region.offsets)
    hit = ray_polyline_distance(origin, direction, region.boundary_xy)
    return 0.0 if math.isinf(hit) else hit


def goal_inside(region: Region, goal: np.ndarray) -> bool:
    """Whether ``goal`` (robot frame, metres) lies in the region (or its fallback star polygon)."""
    if region.has_polygon:
        return bool(point_in_halfplanes(goal, region.normals, region.offsets))
    return bool(points_in_polygon(goal, region.boundary_xy))
