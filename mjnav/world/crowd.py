"""Pedestrian motion models: pure numpy/numba, no MuJoCo.

A :class:`PedestrianModel` owns the planar state of ``P`` disc pedestrians inside a walled
rectangle with static convex polygon obstacles. The simulation calls :meth:`~PedestrianModel.advance`
once per control period (one step per physics substep) and writes each step's positions to the
mocap bodies before the matching physics step.

Two models are provided:

- :class:`RandomWalkModel` (default, the authors' simulator): constant speed, random-walk
  heading, specular reflection at walls, obstacles and other pedestrians; ignores the robot.
- :class:`~mjnav.world.social_force.SocialForceModel`: Helbing-style goal seeking with
  exponential repulsion from pedestrians, walls, obstacles and the robot.

Units are SI: metres, seconds, radians. All randomness comes from the generator given to
:meth:`~PedestrianModel.reset`, so the same inputs and seed give bit-identical trajectories.
"""

from __future__ import annotations

import abc
import math
from collections.abc import Sequence

import numba
import numpy as np

__all__ = [
    "PedestrianModel",
    "RandomWalkModel",
    "pack_polygons",
    "polygon_contact",
]

#: Default interval between yaw-rate draws of the random walk, s (one control period).
YAW_INTERVAL = 0.1
_TIME_EPS = 1e-9
_AREA_EPS = 1e-9


class PedestrianModel(abc.ABC):
    """Planar motion of ``P`` disc pedestrians in a walled arena with convex obstacles.

    :meth:`reset` validates and stores the episode's initial state; :meth:`step` advances it.
    The position/velocity/radius properties return copies, safe to keep across steps.
    """

    #: Whether the motion depends on the robot. A model that ignores it may be advanced ahead of
    #: the simulation in long blocks (:class:`mjnav.sim.NavSim` does): the steps are the same.
    reacts_to_robot: bool = True

    def __init__(self) -> None:
        self._pos = np.zeros((0, 2))
        self._vel = np.zeros((0, 2))
        self._radius = np.zeros(0)
        self._speed = np.zeros(0)
        self._bounds = np.zeros(4)
        self._box = (0.0, 0.0, 0.0, 0.0)
        self._verts = np.zeros((0, 2))
        self._offsets = np.zeros(1, dtype=np.int64)
        self._rng: np.random.Generator | None = None

    def reset(
        self,
        positions: np.ndarray,
        radii: np.ndarray,
        speeds: np.ndarray,
        headings: np.ndarray,
        bounds: Sequence[float],
        obstacles: Sequence[np.ndarray],
        rng: np.random.Generator,
    ) -> None:
        """Starts an episode.

        Args:
            positions: Disc centres, shape (P, 2), metres, inside ``bounds``. A disc that sticks
                out of a wall is moved inward until it touches the wall.
            radii: Disc radii, shape (P,), metres, > 0.
            speeds: Speeds, shape (P,), m/s, >= 0 (the desired speed for social force).
            headings: Initial headings, shape (P,), radians from +x, counter-clockwise.
            bounds: Wall interior ``(xmin, ymin, xmax, ymax)``, metres.
            obstacles: Convex polygons, each an (n_i, 2) vertex array in the world frame,
                counter-clockwise (clockwise input is reversed).
            rng: Source of all randomness of this model until the next reset.

        Raises:
            ValueError: On wrong shapes, non-finite values, non-positive radii, negative speeds,
                centres outside ``bounds``, an arena narrower than a disc, or a non-convex or
                degenerate polygon.
        """
        pos, radii, speeds, headings = _check_state(positions, radii, speeds, headings)
        box = _check_bounds(bounds, radii)
        _check_inside(pos, box)
        self._pos = _clamp_to_bounds(pos, radii, box)
        self._radius, self._speed, self._bounds = radii, speeds, box
        self._box = tuple(float(x) for x in box)  # plain floats: cheaper numba dispatch than np scalars
        self._verts, self._offsets = pack_polygons(obstacles)
        self._rng = rng
        self._vel = speeds[:, None] * np.stack([np.cos(headings), np.sin(headings)], axis=1)
        self._initialize(headings)

    @abc.abstractmethod
    def _initialize(self, headings: np.ndarray) -> None:
        """Sets up model-specific state after :meth:`reset` stored the common arrays."""

    @abc.abstractmethod
    def step(self, dt: float, robot_position: np.ndarray | None = None, robot_radius: float = 0.225) -> None:
        """Advances the crowd by ``dt`` seconds.

        Args:
            dt: Time step, s, > 0 (a physics substep, typically 0.02 s).
            robot_position: Robot disc centre (2,), metres; None when there is no robot.
            robot_radius: Robot disc radius, metres.
        """

    def advance(self, dt: float, steps: int, robot_positions: np.ndarray | None = None,
                robot_radius: float = 0.225) -> np.ndarray:
        """Takes ``steps`` steps of ``dt`` (one control period of substeps) and records them.

        Args:
            dt: Time step, s, > 0.
            steps: Number of steps, >= 1.
            robot_positions: (steps, 2) robot centre at the start of each step, metres; None when
                there is no robot.
            robot_radius: Robot disc radius, metres.

        Returns:
            (steps, P, 2) disc centres after each step, metres.
        """
        _check_steps(steps)
        track = np.empty((steps, *self._pos.shape))
        for k in range(steps):
            self.step(dt, None if robot_positions is None else robot_positions[k], robot_radius)
            track[k] = self._pos
        return track

    @property
    def positions(self) -> np.ndarray:
        """Disc centres, (P, 2), metres (a copy)."""
        return self._pos.copy()

    @property
    def velocities(self) -> np.ndarray:
        """Velocities, (P, 2), m/s (a copy)."""
        return self._vel.copy()

    @property
    def radii(self) -> np.ndarray:
        """Disc radii, (P,), metres (a copy)."""
        return self._radius.copy()

    def _check_step(self, dt: float) -> float:
        """Returns ``dt`` as a float, s; raises if it is not positive or reset was not called."""
        if self._rng is None:
            raise RuntimeError(f"{type(self).__name__}.step called before reset")
        if not (math.isfinite(dt) and dt > 0.0):
            raise ValueError(f"dt must be finite and > 0, got {dt}")
        return float(dt)


class RandomWalkModel(PedestrianModel):
    """Constant-speed pedestrians whose heading does a random walk (the authors' simulator).

    Each pedestrian keeps its speed. Its yaw rate is drawn uniformly from ±``yaw_rate`` at reset
    and again whenever ``yaw_interval`` seconds of simulated time have passed (every step when
    ``yaw_interval`` <= dt), so the heading turns by at most ``yaw_rate * dt`` per step except at
    a bounce. Per step, in this order: turn, move, bounce off other pedestrians (each approaching
    disc reflects its heading about the line of centres; the overlap is split evenly), bounce off
    obstacles (heading reflected about the normal at the nearest boundary point, which is the edge
    normal away from corners; the disc is pushed out), bounce off walls (reflected, clamped inside).
    Walls come last, so a disc never crosses a wall. The robot is ignored.
    """

    reacts_to_robot = False

    def __init__(self, yaw_rate: float = math.pi / 6, yaw_interval: float = YAW_INTERVAL) -> None:
        """Creates the model.

        Args:
            yaw_rate: Bound of the uniform yaw-rate draw, rad/s, >= 0.
            yaw_interval: Simulated time between yaw-rate draws, s, >= 0.
        """
        super().__init__()
        if not (yaw_rate >= 0.0 and yaw_interval >= 0.0):
            raise ValueError(f"yaw_rate and yaw_interval must be >= 0, got {yaw_rate}, {yaw_interval}")
        self._yaw_rate = float(yaw_rate)
        self._yaw_interval = float(yaw_interval)
        self._heading = np.zeros(0)
        self._omega = np.zeros(0)
        self._since_draw = 0.0

    def _initialize(self, headings: np.ndarray) -> None:
        self._heading = np.arctan2(np.sin(headings), np.cos(headings))
        self._omega = self._draw_yaw_rates()
        self._since_draw = 0.0

    @property
    def headings(self) -> np.ndarray:
        """Headings, (P,), radians in (-pi, pi] (a copy)."""
        return self._heading.copy()

    def step(self, dt: float, robot_position: np.ndarray | None = None, robot_radius: float = 0.225) -> None:
        """Advances the crowd by ``dt`` seconds; the robot arguments are ignored."""
        self.advance(dt, 1)

    def advance(self, dt: float, steps: int, robot_positions: np.ndarray | None = None,
                robot_radius: float = 0.225) -> np.ndarray:
        """Takes ``steps`` steps in one kernel call (see :meth:`PedestrianModel.advance`)."""
        dt = self._check_step(dt)
        _check_steps(steps)
        omegas = np.empty((steps, self._heading.shape[0]))
        since, due, omega = self._since_draw, self._yaw_interval - _TIME_EPS, self._omega
        for k in range(steps):  # yaw-rate draws in step order, as single steps would make them
            if since >= due:
                omega = self._omega = self._draw_yaw_rates()
                since = 0.0
            since += dt
            omegas[k] = omega
        self._since_draw = since
        track = np.empty((steps, *self._pos.shape))
        xmin, ymin, xmax, ymax = self._box
        _random_walk_steps(
            self._pos, self._vel, self._heading, omegas, self._speed, self._radius,
            dt, xmin, ymin, xmax, ymax, self._verts, self._offsets, track,
        )  # fmt: skip
        return track

    def _draw_yaw_rates(self) -> np.ndarray:
        return self._rng.uniform(-self._yaw_rate, self._yaw_rate, size=self._heading.shape[0])


def _check_steps(steps: int) -> None:
    """Raises unless ``steps`` is an integer >= 1."""
    if not (isinstance(steps, (int, np.integer)) and steps >= 1):
        raise ValueError(f"steps must be an integer >= 1, got {steps!r}")


# ---------------------------------------------------------------------------- input checks


def _check_state(
    positions: np.ndarray, radii: np.ndarray, speeds: np.ndarray, headings: np.ndarray
) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    pos = _as_finite("positions", positions, (-1, 2))
    n = pos.shape[0]
    named = (("radii", radii), ("speeds", speeds), ("headings", headings))
    radii, speeds, headings = (_as_finite(name, raw, (n,)) for name, raw in named)
    if np.any(radii <= 0.0):
        raise ValueError(f"radii must be > 0, got {radii.tolist()}")
    if np.any(speeds < 0.0):
        raise ValueError(f"speeds must be >= 0, got {speeds.tolist()}")
    return pos, radii, speeds, headings


def _as_finite(name: str, raw: np.ndarray, shape: tuple[int, ...]) -> np.ndarray:
    arr = np.array(raw, dtype=np.float64)
    if arr.size == 0 and shape[0] <= 0:
        arr = arr.reshape(0, *shape[1:])
    matches = arr.ndim == len(shape) and all(
        want in (-1, got) for want, got in zip(shape, arr.shape, strict=True)
    )
    if not matches:
        raise ValueError(f"{name} must have shape {shape} (-1: any), got {arr.shape}")
    if not np.all(np.isfinite(arr)):
        raise ValueError(f"{name} must be finite, got {arr.tolist()}")
    return np.ascontiguousarray(arr)


def _check_bounds(bounds: Sequence[float], radii: np.ndarray) -> np.ndarray:
    box = np.array(bounds, dtype=np.float64).reshape(-1)
    if box.shape != (4,) or not np.all(np.isfinite(box)):
        raise ValueError(f"bounds must be 4 finite numbers (xmin, ymin, xmax, ymax), got {bounds}")
    diameter = 2.0 * float(radii.max(initial=0.0))
    if box[2] - box[0] <= diameter or box[3] - box[1] <= diameter:
        raise ValueError(f"bounds {box.tolist()} must be exceed than the largest disc ({diameter} m)")
    return box


def _check_inside(pos: np.ndarray, box: np.ndarray) -> None:
    outside = (pos[:, 0] < box[0]) | (pos[:, 0] > box[2]) | (pos[:, 1] < box[1]) | (pos[:, 1] > box[3])
    if np.any(outside):
        raise ValueError(f"positions {pos[outside].tolist()} lie outside bounds {box.tolist()}")


def _clamp_to_bounds(pos: np.ndarray, radii: np.ndarray, box: np.ndarray) -> np.ndarray:
    x = np.clip(pos[:, 0], box[0] + radii, box[2] - radii)
    y = np.clip(pos[:, 1], box[1] + radii, box[3] - radii)
    return np.ascontiguousarray(np.stack([x, y], axis=1))


def pack_polygons(obstacles: Sequence[np.ndarray]) -> tuple[np.ndarray, np.ndarray]:
    """Checks convex polygons and packs them for the kernels.

    Args:
        obstacles: Convex polygons, each an (n_i >= 3, 2) vertex array, metres; clockwise ones
            are reversed to counter-clockwise.

    Returns:
        ``(verts, offsets)``: all vertices (sum n_i, 2), CCW per polygon, and int64 offsets
        (M + 1,) such that polygon k is ``verts[offsets[k]:offsets[k + 1]]``.

    Raises:
        ValueError: If a polygon is malformed, non-finite, degenerate or not convex.
    """
    polys = [_check_polygon(k, poly) for k, poly in enumerate(obstacles)]
    offsets = np.cumsum([0] + [len(p) for p in polys]).astype(np.int64)
    verts = np.concatenate(polys) if polys else np.zeros((0, 2))
    return np.ascontiguousarray(verts, dtype=np.float64), offsets


def _check_polygon(index: int, poly: np.ndarray) -> np.ndarray:
    v = np.asarray(poly, dtype=np.float64)
    if v.ndim != 2 or v.shape[1] != 2 or v.shape[0] < 3 or not np.all(np.isfinite(v)):
        raise ValueError(f"obstacles[{index}] must be a finite (n >= 3, 2) array, got shape {v.shape}")
    edges = np.roll(v, -1, axis=0) - v
    cross = edges[:, 0] * np.roll(edges[:, 1], -1) - edges[:, 1] * np.roll(edges[:, 0], -1)
    area = 0.5 * float(np.sum(v[:, 0] * np.roll(v[:, 1], -1) - np.roll(v[:, 0], -1) * v[:, 1]))
    if abs(area) < _AREA_EPS or not (np.all(cross * np.sign(area) >= -_AREA_EPS)):
        raise ValueError(f"obstacles[{index}] must be a convex polygon with non-zero area, got {v.tolist()}")
    return v if area > 0 else v[::-1].copy()


# ---------------------------------------------------------------------------- kernels


@numba.njit(cache=True)
def polygon_contact(
    px: float, py: float, verts: np.ndarray, start: int, stop: int
) -> tuple[float, float, float]:
    """Signed distance from a point to a CCW convex polygon and the outward contact normal.

    Args:
        px: Point x, metres.
        py: Point y, metres.
        verts: Packed vertices (see :func:`pack_polygons`).
        start: First vertex index of the polygon.
        stop: One past its last vertex index.

    Returns:
        ``(distance, nx, ny)``: distance to the boundary, metres, negative inside; the unit normal
        at the nearest boundary point pointing from the polygon towards the point (pushing along it
        increases the distance).
    """
    inside = True
    best, qx, qy, ex_best, ey_best = np.inf, px, py, 1.0, 0.0
    for e in range(start, stop):
        ax, ay = verts[e, 0], verts[e, 1]
        nxt = e + 1 if e + 1 < stop else start
        ex, ey = verts[nxt, 0] - ax, verts[nxt, 1] - ay
        if ex * (py - ay) - ey * (px - ax) < 0.0:
            inside = False
        t = min(max(((px - ax) * ex + (py - ay) * ey) / (ex * ex + ey * ey), 0.0), 1.0)
        cx, cy = ax + t * ex, ay + t * ey
        d2 = (px - cx) ** 2 + (py - cy) ** 2
        if d2 < best:
            best, qx, qy, ex_best, ey_best = d2, cx, cy, ex, ey
    dist = math.sqrt(best)
    if dist < 1e-12:  # on the boundary: outward edge normal
        norm = math.hypot(ex_best, ey_best)
        return 0.0, ey_best / norm, -ex_best / norm
    sign = -1.0 if inside else 1.0
    return sign * dist, sign * (px - qx) / dist, sign * (py - qy) / dist


@numba.njit(cache=True)
def _reflect(heading: float, nx: float, ny: float) -> float:
    """Reflects a heading about the unit normal (nx, ny) if it points against it."""
    c, s = math.cos(heading), math.sin(heading)
    dot = c * nx + s * ny
    if dot >= 0.0:
        return heading
    return math.atan2(s - 2.0 * dot * ny, c - 2.0 * dot * nx)


@numba.njit(cache=True)
def _random_walk_steps(
    pos: np.ndarray, vel: np.ndarray, heading: np.ndarray, omegas: np.ndarray, speed: np.ndarray,
    radius: np.ndarray, dt: float, xmin: float, ymin: float, xmax: float, ymax: float,
    verts: np.ndarray, offsets: np.ndarray, track: np.ndarray,
) -> None:  # fmt: skip
    """``len(omegas)`` random-walk steps in place (yaw rates per step); positions into ``track``.

    Velocities follow the final headings (intermediate ones are never read).
    """
    for k in range(omegas.shape[0]):
        _random_walk_step(pos, heading, omegas[k], speed, radius, dt, xmin, ymin, xmax, ymax, verts, offsets)
        track[k] = pos
    for i in range(pos.shape[0]):
        vel[i, 0] = speed[i] * math.cos(heading[i])
        vel[i, 1] = speed[i] * math.sin(heading[i])


@numba.njit(cache=True)
def _random_walk_step(
    pos: np.ndarray, heading: np.ndarray, omega: np.ndarray, speed: np.ndarray,
    radius: np.ndarray, dt: float, xmin: float, ymin: float, xmax: float, ymax: float,
    verts: np.ndarray, offsets: np.ndarray,
) -> None:  # fmt: skip
    """One random-walk step of positions and headings in place: turn, move, bounce off pedestrians,
    obstacles, walls."""
    n = pos.shape[0]
    for i in range(n):
        h = heading[i] + omega[i] * dt
        heading[i] = math.atan2(math.sin(h), math.cos(h))
        pos[i, 0] += speed[i] * math.cos(heading[i]) * dt
        pos[i, 1] += speed[i] * math.sin(heading[i]) * dt
    for i in range(n):
        for j in range(i + 1, n):
            dx, dy = pos[j, 0] - pos[i, 0], pos[j, 1] - pos[i, 1]
            d2, contact = dx * dx + dy * dy, radius[i] + radius[j]
            if d2 < contact * contact:
                d = math.sqrt(d2)
                overlap = contact - d
                ux, uy = (dx / d, dy / d) if d > 1e-12 else (1.0, 0.0)
                heading[i] = _reflect(heading[i], -ux, -uy)
                heading[j] = _reflect(heading[j], ux, uy)
                pos[i, 0] -= 0.5 * overlap * ux
                pos[i, 1] -= 0.5 * overlap * uy
                pos[j, 0] += 0.5 * overlap * ux
                pos[j, 1] += 0.5 * overlap * uy
    for i in range(n):
        for k in range(offsets.shape[0] - 1):
            dist, nx, ny = polygon_contact(pos[i, 0], pos[i, 1], verts, offsets[k], offsets[k + 1])
            if dist < radius[i]:
                pos[i, 0] += (radius[i] - dist) * nx
                pos[i, 1] += (radius[i] - dist) * ny
                heading[i] = _reflect(heading[i], nx, ny)
        _bounce_walls(pos, heading, radius, i, xmin, ymin, xmax, ymax)


@numba.njit(cache=True)
def _bounce_walls(
    pos: np.ndarray, heading: np.ndarray, radius: np.ndarray, i: int,
    xmin: float, ymin: float, xmax: float, ymax: float,
) -> None:  # fmt: skip
    """Clamps disc ``i`` inside the walls and reflects its heading off any wall it touched."""
    r = radius[i]
    if pos[i, 0] < xmin + r:
        pos[i, 0] = xmin + r
        heading[i] = _reflect(heading[i], 1.0, 0.0)
    elif pos[i, 0] > xmax - r:
        pos[i, 0] = xmax - r
        heading[i] = _reflect(heading[i], -1.0, 0.0)
    if pos[i, 1] < ymin + r:
        pos[i, 1] = ymin + r
        heading[i] = _reflect(heading[i], 0.0, 1.0)
    elif pos[i, 1] > ymax - r:
        pos[i, 1] = ymax - r
        heading[i] = _reflect(heading[i], 0.0, -1.0)
