"""Helbing-style social force pedestrians (pure numpy/numba, no MuJoCo).

Each pedestrian walks towards its own goal at its desired speed ``v0``. Its acceleration is

    a_i = (v0_i e_i - v_i) / tau
          + sum_j A  exp(-g_ij / B)  n_ij          (other pedestrians)
          + sum_w Aw exp(-g_iw / Bw) n_iw          (the four walls)
          + sum_k Aw exp(-g_ik / Bw) n_ik          (obstacles, nearest boundary point)
          + Ar exp(-g_ir / B) n_ir                 (the robot, when given)

with ``e_i`` the unit vector to the goal, ``g`` the surface gap (centre distance minus radii,
metres) and ``n`` the unit vector pushing pedestrian ``i`` away. The force is isotropic (no field
of view). Semi-implicit Euler: velocity first, capped at ``max_speed_factor * v0``, then position.
Hard guards afterwards push a disc out of obstacles and clamp it inside the walls, removing the
velocity component into the surface. A goal is re-drawn uniformly in free space once the
pedestrian is within ``goal_tolerance`` of it, or once its time budget for that goal runs out
(:data:`GOAL_TIME_FACTOR`, :data:`GOAL_TIME_SLACK`).
"""

from __future__ import annotations

import math

import numba
import numpy as np

from mjnav.schema import CrowdConfig
from mjnav.world.crowd import PedestrianModel, polygon_contact

__all__ = ["SocialForceModel"]

#: Speed cap as a multiple of the desired speed (Helbing & Molnar 1995 use 1.3).
MAX_SPEED_FACTOR = 1.3
#: Clearance of a goal from walls and obstacles beyond the pedestrian's radius, metres.
GOAL_CLEARANCE = 0.1
#: A goal not reached within ``GOAL_TIME_FACTOR * distance / v0 + GOAL_TIME_SLACK`` seconds is
#: re-drawn, so that a pedestrian stuck in a jam or behind an obstacle gives up and walks on.
GOAL_TIME_FACTOR = 2.0
GOAL_TIME_SLACK = 5.0
_GOAL_ATTEMPTS = 100


class GoalSeekingModel(PedestrianModel):
    """Goal drawing shared by the models whose pedestrians walk to goals (social force, ORCA).

    A subclass provides ``_pos``, ``_radius``, ``_speed``, ``_bounds``, ``_rng``, ``_verts``,
    ``_offsets``, ``_goal``, ``_time_left`` and :attr:`goal_tolerance`.
    """

    @property
    def goal_tolerance(self) -> float:
        """Distance to the goal at which a new goal is drawn, metres."""
        raise NotImplementedError

    def _new_goal(self, i: int) -> None:
        """Draws a goal for pedestrian ``i`` and sets its time budget, s."""
        self._goal[i] = self._sample_goal(i)
        distance = math.hypot(*(self._goal[i] - self._pos[i]))
        speed = self._speed[i]
        self._time_left[i] = GOAL_TIME_FACTOR * distance / speed + GOAL_TIME_SLACK if speed > 0 else np.inf

    def _sample_goal(self, i: int) -> np.ndarray:
        """Draws a goal for pedestrian ``i`` in free space, farther than the goal tolerance.

        Rejection sampling over the bounds shrunk by the radius plus :data:`GOAL_CLEARANCE`; after
        :data:`_GOAL_ATTEMPTS` failures the last draw is kept (the hard guards still hold).
        """
        margin = self._radius[i] + GOAL_CLEARANCE
        low = self._bounds[:2] + margin
        high = np.maximum(self._bounds[2:] - margin, low)
        goal = self._pos[i]
        for _ in range(_GOAL_ATTEMPTS):
            goal = self._rng.uniform(low, high)
            far = math.hypot(*(goal - self._pos[i])) > self.goal_tolerance
            if far and _obstacle_gap(goal[0], goal[1], self._verts, self._offsets) >= margin:
                break
        return goal


class SocialForceModel(GoalSeekingModel):
    """Goal-seeking pedestrians repelled by each other, walls, obstacles and the robot."""

    def __init__(
        self,
        relaxation_time: float = 0.5,
        repulsion_strength: float = 2.1,
        repulsion_range: float = 0.3,
        wall_strength: float = 10.0,
        wall_range: float = 0.2,
        robot_strength: float = 2.1,
        goal_tolerance: float = 0.5,
        max_speed_factor: float = MAX_SPEED_FACTOR,
    ) -> None:
        """Creates the model.

        Args:
            relaxation_time: Time to reach the desired velocity, s, > 0.
            repulsion_strength: Pedestrian repulsion at contact, m/s², >= 0.
            repulsion_range: Pedestrian and robot repulsion decay length, metres, > 0.
            wall_strength: Wall and obstacle repulsion at contact, m/s², >= 0.
            wall_range: Wall and obstacle repulsion decay length, metres, > 0.
            robot_strength: Robot repulsion at contact, m/s², >= 0.
            goal_tolerance: Distance to the goal at which a new goal is drawn, metres, > 0.
            max_speed_factor: Speed cap as a multiple of the desired speed, >= 1.
        """
        super().__init__()
        params = np.array([relaxation_time, repulsion_strength, repulsion_range, wall_strength,
                           wall_range, robot_strength, max_speed_factor], dtype=np.float64)  # fmt: skip
        positive = (relaxation_time, repulsion_range, wall_range, goal_tolerance)
        valid = np.all(np.isfinite(params)) and params.min() >= 0 and min(positive) > 0
        if not (valid and max_speed_factor >= 1.0):
            raise ValueError(f"social force parameters out of range: {params.tolist()}, {goal_tolerance=}")
        self._params = params
        self._goal_tolerance = float(goal_tolerance)
        self._goal = np.zeros((0, 2))
        self._redraw = np.zeros(0, dtype=np.bool_)
        self._time_left = np.zeros(0)

    @classmethod
    def from_config(cls, config: CrowdConfig) -> SocialForceModel:
        """Creates the model from the social-force fields of a crowd config."""
        return cls(
            relaxation_time=config.relaxation_time,
            repulsion_strength=config.repulsion_strength,
            repulsion_range=config.repulsion_range,
            wall_strength=config.wall_strength,
            wall_range=config.wall_range,
            robot_strength=config.robot_strength,
            goal_tolerance=config.goal_tolerance,
            max_speed_factor=config.max_speed_factor,
        )

    @property
    def goal_tolerance(self) -> float:
        """Distance to the goal at which a new goal is drawn, metres."""
        return self._goal_tolerance

    @property
    def goals(self) -> np.ndarray:
        """Current goals, (P, 2), metres (a copy)."""
        return self._goal.copy()

    def _initialize(self, headings: np.ndarray) -> None:
        self._goal = np.empty_like(self._pos)
        self._redraw = np.zeros(self._pos.shape[0], dtype=np.bool_)
        self._time_left = np.empty(self._pos.shape[0])
        for i in range(self._pos.shape[0]):
            self._new_goal(i)

    def step(self, dt: float, robot_position: np.ndarray | None = None, robot_radius: float = 0.225) -> None:
        """Advances the crowd by ``dt`` seconds, repelled by the robot disc when one is given.

        Raises:
            ValueError: If ``dt`` is not positive or the robot position is not finite.
        """
        dt = self._check_step(dt)
        has_robot = robot_position is not None
        rx, ry = (float(robot_position[0]), float(robot_position[1])) if has_robot else (0.0, 0.0)
        if not (math.isfinite(rx) and math.isfinite(ry) and math.isfinite(robot_radius)):
            raise ValueError(
                f"robot position and radius must be finite, got {robot_position}, {robot_radius}"
            )
        xmin, ymin, xmax, ymax = self._bounds
        _social_force_step(
            self._pos, self._vel, self._goal, self._speed, self._radius, self._time_left, self._redraw, dt,
            xmin, ymin, xmax, ymax, self._verts, self._offsets,
            has_robot, rx, ry, float(robot_radius), self._params, self._goal_tolerance,
        )  # fmt: skip
        if self._redraw.any():
            for i in np.flatnonzero(self._redraw):
                self._new_goal(i)


@numba.njit(cache=True)
def _obstacle_gap(px: float, py: float, verts: np.ndarray, offsets: np.ndarray) -> float:
    """Smallest signed distance from a point to any obstacle, metres (inf without obstacles)."""
    gap = np.inf
    for k in range(offsets.shape[0] - 1):
        gap = min(gap, polygon_contact(px, py, verts, offsets[k], offsets[k + 1])[0])
    return gap


@numba.njit(cache=True)
def _social_force_step(
    pos: np.ndarray, vel: np.ndarray, goal: np.ndarray, v0: np.ndarray, radius: np.ndarray,
    time_left: np.ndarray, redraw: np.ndarray, dt: float, xmin: float, ymin: float, xmax: float, ymax: float,
    verts: np.ndarray, offsets: np.ndarray, has_robot: bool, rx: float, ry: float, rr: float,
    params: np.ndarray, goal_tolerance: float,
) -> None:  # fmt: skip
    """One social-force step in place; flags in ``redraw`` who reached its goal or ran out of time."""
    tau, strength, length, cap = params[0], params[1], params[2], params[6]
    wall_a, wall_b, robot_a = params[3], params[4], params[5]
    acc = np.zeros_like(pos)
    n = pos.shape[0]
    for i in range(n):
        gx, gy = goal[i, 0] - pos[i, 0], goal[i, 1] - pos[i, 1]
        d = math.hypot(gx, gy)
        ex, ey = (gx / d, gy / d) if d > 1e-12 else (0.0, 0.0)
        acc[i, 0] = (v0[i] * ex - vel[i, 0]) / tau
        acc[i, 1] = (v0[i] * ey - vel[i, 1]) / tau
        for j in range(i + 1, n):
            _add_pair_repulsion(pos, radius, acc, i, j, strength, length)
        if has_robot:
            dx, dy = pos[i, 0] - rx, pos[i, 1] - ry
            d = math.hypot(dx, dy)
            ux, uy = (dx / d, dy / d) if d > 1e-12 else (1.0, 0.0)
            f = robot_a * math.exp(-(d - radius[i] - rr) / length)
            acc[i, 0] += f * ux
            acc[i, 1] += f * uy
        _add_wall_repulsion(pos, radius, acc, i, xmin, ymin, xmax, ymax, wall_a, wall_b)
        for k in range(offsets.shape[0] - 1):
            dist, nx, ny = polygon_contact(pos[i, 0], pos[i, 1], verts, offsets[k], offsets[k + 1])
            f = wall_a * math.exp(-(dist - radius[i]) / wall_b)
            acc[i, 0] += f * nx
            acc[i, 1] += f * ny
    for i in range(n):
        _integrate(pos, vel, acc, i, dt, cap * v0[i])
    for i in range(n):
        for j in range(i + 1, n):
            _separate_pair(pos, vel, radius, i, j)
    for i in range(n):
        _guard(pos, vel, radius, i, xmin, ymin, xmax, ymax, verts, offsets)
        time_left[i] -= dt
        distance = math.hypot(goal[i, 0] - pos[i, 0], goal[i, 1] - pos[i, 1])
        redraw[i] = distance < goal_tolerance or time_left[i] <= 0.0


@numba.njit(cache=True)
def _add_pair_repulsion(
    pos: np.ndarray, radius: np.ndarray, acc: np.ndarray, i: int, j: int, strength: float, length: float
) -> None:
    """Adds the equal and opposite exponential repulsion between pedestrians i and j."""
    dx, dy = pos[i, 0] - pos[j, 0], pos[i, 1] - pos[j, 1]
    d = math.sqrt(dx * dx + dy * dy)
    ux, uy = (dx / d, dy / d) if d > 1e-12 else (1.0, 0.0)
    f = strength * math.exp(-(d - radius[i] - radius[j]) / length)
    acc[i, 0] += f * ux
    acc[i, 1] += f * uy
    acc[j, 0] -= f * ux
    acc[j, 1] -= f * uy


@numba.njit(cache=True)
def _add_wall_repulsion(
    pos: np.ndarray, radius: np.ndarray, acc: np.ndarray, i: int,
    xmin: float, ymin: float, xmax: float, ymax: float, strength: float, length: float,
) -> None:  # fmt: skip
    """Adds the exponential repulsion of the four walls on pedestrian i."""
    r = radius[i]
    x, y = pos[i, 0], pos[i, 1]
    acc[i, 0] += strength * (math.exp((xmin + r - x) / length) - math.exp((x + r - xmax) / length))
    acc[i, 1] += strength * (math.exp((ymin + r - y) / length) - math.exp((y + r - ymax) / length))


@numba.njit(cache=True)
def _integrate(pos: np.ndarray, vel: np.ndarray, acc: np.ndarray, i: int, dt: float, vmax: float) -> None:
    """Semi-implicit Euler step of pedestrian i with its speed capped at ``vmax``, m/s."""
    vx, vy = vel[i, 0] + acc[i, 0] * dt, vel[i, 1] + acc[i, 1] * dt
    speed = math.hypot(vx, vy)
    if speed > vmax:
        scale = vmax / speed
        vx, vy = vx * scale, vy * scale
    vel[i, 0], vel[i, 1] = vx, vy
    pos[i, 0] += vx * dt
    pos[i, 1] += vy * dt


@numba.njit(cache=True)
def _separate_pair(pos: np.ndarray, vel: np.ndarray, radius: np.ndarray, i: int, j: int) -> None:
    """Splits the overlap of discs i and j evenly; each stops moving towards the other."""
    dx, dy = pos[j, 0] - pos[i, 0], pos[j, 1] - pos[i, 1]
    d2, contact = dx * dx + dy * dy, radius[i] + radius[j]
    if d2 >= contact * contact:
        return
    d = math.sqrt(d2)
    overlap = contact - d
    ux, uy = (dx / d, dy / d) if d > 1e-12 else (1.0, 0.0)
    pos[i, 0] -= 0.5 * overlap * ux
    pos[i, 1] -= 0.5 * overlap * uy
    pos[j, 0] += 0.5 * overlap * ux
    pos[j, 1] += 0.5 * overlap * uy
    _drop_normal(vel, i, -ux, -uy)
    _drop_normal(vel, j, ux, uy)


@numba.njit(cache=True)
def _drop_normal(vel: np.ndarray, i: int, nx: float, ny: float) -> None:
    """Removes the velocity component of pedestrian i into a surface with outward normal (nx, ny)."""
    vn = vel[i, 0] * nx + vel[i, 1] * ny
    if vn < 0.0:
        vel[i, 0] -= vn * nx
        vel[i, 1] -= vn * ny


@numba.njit(cache=True)
def _guard(
    pos: np.ndarray, vel: np.ndarray, radius: np.ndarray, i: int, xmin: float, ymin: float,
    xmax: float, ymax: float, verts: np.ndarray, offsets: np.ndarray,
) -> None:  # fmt: skip
    """Pushes disc i out of obstacles, then inside the walls, dropping velocity into surfaces."""
    r = radius[i]
    for k in range(offsets.shape[0] - 1):
        dist, nx, ny = polygon_contact(pos[i, 0], pos[i, 1], verts, offsets[k], offsets[k + 1])
        if dist < r:
            pos[i, 0] += (r - dist) * nx
            pos[i, 1] += (r - dist) * ny
            _drop_normal(vel, i, nx, ny)
    for axis, low, high in ((0, xmin, xmax), (1, ymin, ymax)):
        if pos[i, axis] < low + r:
            pos[i, axis] = low + r
            vel[i, axis] = max(vel[i, axis], 0.0)
        elif pos[i, axis] > high - r:
            pos[i, axis] = high - r
            vel[i, axis] = min(vel[i, axis], 0.0)
