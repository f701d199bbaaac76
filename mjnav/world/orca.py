"""ORCA pedestrians: optimal reciprocal collision avoidance (pure numpy/numba, no MuJoCo).

The algorithm is the one of RVO2 (van den Berg, Guy, Lin and Manocha, "Reciprocal n-body
collision avoidance", ISRR 2009), written afresh as numba kernels in float64:

1. Neighbours. Each agent considers up to ``max_neighbors`` other discs whose centres lie within
   ``neighbor_dist``, nearest first, and every obstacle edge it faces (it is on the edge's outer
   side) within ``time_horizon_obst * max_speed + radius``, nearest first.
2. Obstacle half-planes. The velocity obstacle of an edge for ``time_horizon_obst`` seconds is cut
   off and truncated by legs tangent to its end vertices (or the neighbouring edge when a leg would
   point into the obstacle); the agent's current velocity is projected on its boundary, giving a
   half-plane of admissible velocities. Edges already covered by earlier half-planes are skipped.
3. Agent half-planes. For another disc at relative position ``p`` and relative velocity ``v_rel``,
   ``u`` is the smallest change of ``v_rel`` that leaves the truncated cone of colliding relative
   velocities over ``time_horizon`` seconds (over one time step when the discs already overlap).
   The agent takes ``responsibility * u`` (1/2 for another pedestrian: reciprocal avoidance); the
   half-plane passes through ``v + responsibility * u`` with normal ``u``.
4. Linear program 2 finds the velocity closest to the preferred one inside every half-plane and
   the max-speed disc (randomisation-free incremental 2-D LP, each violated constraint solved as
   the 1-D linear program 1 on its line). If the agent half-planes are infeasible together,
   linear program 3 keeps the obstacle half-planes hard and picks the velocity that minimises the
   largest penetration into the agent half-planes.

Walls are the arena boundary as one clockwise ("negative") polygon, static obstacles are their
counter-clockwise convex polygons, and extra line segments may be given. The robot can be an extra
disc that pedestrians avoid but that the model does not move (:attr:`OrcaConfig.reactive`).

Differences from RVO2: neighbours are found by brute force (N and the edge count are small), so
edges are never split the way RVO2's obstacle k-d tree splits them (RVO2 marks a split point as a
convex vertex, which can loosen a wall's constraint); computation is in float64, not float32.
Checked against RVO2 2.0.3 through the ``pyrvo`` binding: single ORCA steps agree to float32
precision for 99.8 % of agents (the rest: LP 3 round-off with overlapping discs, and split walls)
and a 12-disc circle swap agrees to 1e-3 m after 500 steps. Like RVO2, perfectly symmetric
encounters can deadlock (ORCA only slows both agents); random goals make that rare.

:class:`OrcaModel` is the pedestrian model (the interface of
:class:`~mjnav.world.crowd.PedestrianModel`): goals as in the social-force model, ORCA per
physics step, then the last wall/obstacle guard shared with the other models.

Units are SI: metres, seconds, m/s. All randomness (goals) comes from the generator given to
:meth:`OrcaModel.reset`, so the same inputs and seed give bit-identical trajectories.
"""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Sequence
from typing import Literal, NamedTuple

import numba
import numpy as np

from mjnav.schema import ROBOT_RESPONSIBILITY, OrcaConfig
from mjnav.world.crowd import pack_polygons, polygon_contact
from mjnav.world.social_force import GoalSeekingModel

__all__ = [
    "OrcaConfig",
    "OrcaModel",
    "OrcaObstacles",
    "RVO_EPSILON",
    "orca_obstacles",
    "orca_velocities",
]

#: Tolerance of the linear programs for parallel lines and covered obstacles (RVO2's value).
RVO_EPSILON = 1e-5
#: Responsibility a pedestrian takes for avoiding another pedestrian (reciprocal: half each).
RECIPROCAL = 0.5
_MIN_EDGE = 1e-9  # shorter polygon edges (repeated vertices) are dropped, metres


class OrcaObstacles(NamedTuple):
    """Obstacle vertices in RVO2's linked form: vertex ``k`` starts the edge ``k -> next[k]``.

    The blocked side of every edge is on its left; an agent only considers edges it sees from the
    right. Counter-clockwise polygons are solid, a clockwise polygon (the walls) encloses the
    free space, and a two-vertex obstacle is a segment blocked on both sides.

    Attributes:
        point: (K, 2) vertex positions, metres.
        direction: (K, 2) unit vectors from each vertex to the next.
        next: (K,) int64 index of the next vertex.
        prev: (K,) int64 index of the previous vertex.
        convex: (K,) bool, whether the vertex is convex (turns left, or ends a segment).
    """

    point: np.ndarray
    direction: np.ndarray
    next: np.ndarray
    prev: np.ndarray
    convex: np.ndarray


def orca_obstacles(
    polygons: Sequence[np.ndarray] = (),
    bounds: Sequence[float] | None = None,
    segments: np.ndarray | None = None,
) -> OrcaObstacles:
    """Packs walls, convex polygons and segments into :class:`OrcaObstacles`.

    Args:
        polygons: Convex polygons, each an (n_i >= 3, 2) vertex array, metres; clockwise ones are
            reversed to counter-clockwise (solid).
        bounds: Wall interior ``(xmin, ymin, xmax, ymax)``, metres; None: no walls.
        segments: (M, 4) segments ``(x0, y0, x1, y1)``, metres, each blocked on both sides.

    Returns:
        The packed obstacles (empty arrays when nothing is given).

    Raises:
        ValueError: On a malformed, non-convex or degenerate polygon, bad bounds or segments.
    """
    loops: list[np.ndarray] = []
    if bounds is not None:
        box = np.asarray(bounds, dtype=np.float64).reshape(-1)
        if box.shape != (4,) or not np.all(np.isfinite(box)) or box[2] <= box[0] or box[3] <= box[1]:
            raise ValueError(f"bounds must be finite (xmin, ymin, xmax, ymax) with min < max, got {bounds}")
        xmin, ymin, xmax, ymax = box
        loops.append(np.array([[xmin, ymin], [xmin, ymax], [xmax, ymax], [xmax, ymin]]))  # clockwise
    verts, offsets = pack_polygons(polygons)
    loops.extend(_drop_repeats(verts[offsets[k] : offsets[k + 1]]) for k in range(len(offsets) - 1))
    if segments is not None:
        seg = np.asarray(segments, dtype=np.float64)
        if seg.ndim != 2 or seg.shape[1] != 4 or not np.all(np.isfinite(seg)):
            raise ValueError(f"segments must be a finite (M, 4) array, got shape {seg.shape}")
        if np.any(np.hypot(seg[:, 2] - seg[:, 0], seg[:, 3] - seg[:, 1]) <= _MIN_EDGE):
            raise ValueError("segments must have non-zero length")
        loops.extend(row.reshape(2, 2) for row in seg)
    return _link(loops)


def _drop_repeats(loop: np.ndarray) -> np.ndarray:
    """The polygon without vertices that repeat the previous one (zero-length edges)."""
    edge = np.hypot(*(loop - np.roll(loop, 1, axis=0)).T)
    return loop[edge > _MIN_EDGE]


def _link(loops: list[np.ndarray]) -> OrcaObstacles:
    """Links each vertex loop (a segment when it has two vertices) in RVO2's form."""
    points, nexts, prevs, convex = [], [], [], []
    start = 0
    for loop in loops:
        n = len(loop)
        idx = np.arange(n)
        points.append(loop)
        nexts.append(start + (idx + 1) % n)
        prevs.append(start + (idx - 1) % n)
        if n == 2:
            convex.append(np.ones(2, dtype=np.bool_))
        else:
            before, after = np.roll(loop, 1, axis=0), np.roll(loop, -1, axis=0)
            turn = (loop[:, 0] - before[:, 0]) * (after[:, 1] - loop[:, 1]) - (
                loop[:, 1] - before[:, 1]) * (after[:, 0] - loop[:, 0])  # fmt: skip
            convex.append(turn >= 0.0)
        start += n
    if not points:
        empty_i = np.zeros(0, dtype=np.int64)
        return OrcaObstacles(np.zeros((0, 2)), np.zeros((0, 2)), empty_i, empty_i.copy(), np.zeros(0, dtype=np.bool_))
    point = np.ascontiguousarray(np.concatenate(points), dtype=np.float64)
    nxt = np.concatenate(nexts).astype(np.int64)
    edge = point[nxt] - point
    direction = np.ascontiguousarray(edge / np.hypot(edge[:, 0], edge[:, 1])[:, None])
    return OrcaObstacles(point, direction, nxt, np.concatenate(prevs).astype(np.int64), np.concatenate(convex))


# ---------------------------------------------------------------------------- public core


def orca_velocities(
    positions: np.ndarray,
    velocities: np.ndarray,
    radii: np.ndarray,
    preferred: np.ndarray,
    max_speeds: np.ndarray,
    obstacles: OrcaObstacles,
    config: OrcaConfig,
    dt: float,
    robot: tuple[np.ndarray, np.ndarray, float] | None = None,
) -> np.ndarray:
    """ORCA velocities of ``N`` discs for the next step (synchronous: all from the same state).

    Args:
        positions: (N, 2) disc centres, metres.
        velocities: (N, 2) current velocities, m/s.
        radii: (N,) disc radii, metres, > 0 (``config.safety_margin`` is added).
        preferred: (N, 2) preferred velocities, m/s.
        max_speeds: (N,) speed limits, m/s, >= 0.
        obstacles: Walls, polygons and segments (:func:`orca_obstacles`).
        config: ORCA parameters (``reactive`` is ignored here: pass ``robot`` or None).
        dt: Time step, s, > 0 (used when two discs already overlap).
        robot: ``(position (2,), velocity (2,), radius)`` of a disc that is avoided but not moved,
            metres, m/s, metres, with responsibility :attr:`OrcaConfig.robot_responsibility`;
            None: no such disc.

    Returns:
        (N, 2) new velocities, m/s, each within its max speed.

    Raises:
        ValueError: On wrong shapes, non-finite values, non-positive radii or dt, negative speeds.
    """
    pos = _finite("positions", positions, (-1, 2))
    n = pos.shape[0]
    vel, pref = _finite("velocities", velocities, (n, 2)), _finite("preferred", preferred, (n, 2))
    rad, vmax = _finite("radii", radii, (n,)), _finite("max_speeds", max_speeds, (n,))
    if np.any(rad <= 0) or np.any(vmax < 0) or not (math.isfinite(dt) and dt > 0):
        raise ValueError(f"radii and dt must be > 0 and max_speeds >= 0, got {rad}, {dt}, {vmax}")
    robot_pos, robot_vel, robot_radius = (np.zeros(2), np.zeros(2), 0.0) if robot is None else robot
    robot_pos, robot_vel = _finite("robot position", robot_pos, (2,)), _finite("robot velocity", robot_vel, (2,))
    if robot is not None and not (math.isfinite(robot_radius) and robot_radius > 0):
        raise ValueError(f"robot radius must be finite and > 0, got {robot_radius}")
    work = _workspace(obstacles, config.max_neighbors)
    out = np.empty_like(pos)
    _orca_velocities(
        pos, vel, rad + config.safety_margin, pref, vmax, *obstacles, config.neighbor_dist, config.max_neighbors,
        config.time_horizon, config.time_horizon_obst, float(dt), robot is not None, robot_pos, robot_vel,
        float(robot_radius) + config.safety_margin, config.robot_responsibility, *work, out,
    )  # fmt: skip
    return out


def _finite(name: str, raw: np.ndarray, shape: tuple[int, ...]) -> np.ndarray:
    """``raw`` as a contiguous float64 array of ``shape`` (-1: any); raises ValueError otherwise."""
    arr = np.ascontiguousarray(raw, dtype=np.float64)
    if arr.ndim != len(shape) or any(want not in (-1, got) for want, got in zip(shape, arr.shape, strict=True)):
        raise ValueError(f"{name} must have shape {shape} (-1: any), got {arr.shape}")
    if not np.all(np.isfinite(arr)):
        raise ValueError(f"{name} must be finite, got {arr.tolist()}")
    return arr


class _Workspace(NamedTuple):
    """Scratch arrays of the kernel, sized for one agent's half-planes and neighbours."""

    lines: np.ndarray  # (L, 4) half-planes: point x, y, direction x, y
    proj: np.ndarray  # (L, 4) projected half-planes of linear program 3
    agent_idx: np.ndarray  # (max_neighbors + 1,) int64
    agent_d2: np.ndarray  # (max_neighbors + 1,)
    obst_idx: np.ndarray  # (K,) int64
    obst_d2: np.ndarray  # (K,)



def _workspace(obstacles: OrcaObstacles, max_neighbors: int) -> _Workspace:
    """Scratch arrays for ``K`` obstacle vertices and ``max_neighbors`` neighbours plus the robot."""
    k = obstacles.point.shape[0]
    size = k + max_neighbors + 1
    return _Workspace(
        np.empty((size, 4)), np.empty((size, 4)), np.empty(max_neighbors + 1, dtype=np.int64),
        np.empty(max_neighbors + 1), np.empty(k, dtype=np.int64), np.empty(k),
    )


# ---------------------------------------------------------------------------- kernels


@numba.njit(cache=True)
def _det(ax: float, ay: float, bx: float, by: float) -> float:
    """2-D cross product a x b."""
    return ax * by - ay * bx


@numba.njit(cache=True)
def _orca_velocities(
    pos: np.ndarray, vel: np.ndarray, radius: np.ndarray, pref: np.ndarray, vmax: np.ndarray,
    ob_point: np.ndarray, ob_dir: np.ndarray, ob_next: np.ndarray, ob_prev: np.ndarray, ob_convex: np.ndarray,
    neighbor_dist: float, max_neighbors: int, tau: float, tau_obst: float, dt: float,
    has_robot: bool, robot_pos: np.ndarray, robot_vel: np.ndarray, robot_radius: float, robot_resp: float,
    lines: np.ndarray, proj: np.ndarray, agent_idx: np.ndarray, agent_d2: np.ndarray,
    obst_idx: np.ndarray, obst_d2: np.ndarray, out: np.ndarray,
) -> None:  # fmt: skip
    """ORCA velocities of every agent into ``out`` (N, 2), m/s; radii already include the margin.

    Index ``N`` in the neighbour list stands for the robot disc when ``has_robot``.
    """
    n = pos.shape[0]
    for i in range(n):
        n_obst = _obstacle_neighbors(pos, radius, vmax, i, tau_obst, ob_point, ob_next, obst_idx, obst_d2)
        count = 0
        for m in range(n_obst):
            count = _add_obstacle_line(pos, vel, radius, i, obst_idx[m], tau_obst, ob_point, ob_dir, ob_next,
                                       ob_prev, ob_convex, lines, count)  # fmt: skip
        num_obst_lines = count
        n_agents = _agent_neighbors(pos, i, has_robot, robot_pos, neighbor_dist, max_neighbors, agent_idx, agent_d2)
        for m in range(n_agents):
            j = agent_idx[m]
            px, py, vx, vy, r = pos[i, 0], pos[i, 1], vel[i, 0], vel[i, 1], radius[i]
            if j == n:  # the robot
                _agent_line(px, py, vx, vy, r, robot_pos[0], robot_pos[1], robot_vel[0], robot_vel[1],
                            robot_radius, robot_resp, 1.0, tau, dt, lines, count)  # fmt: skip
            else:
                _agent_line(px, py, vx, vy, r, pos[j, 0], pos[j, 1], vel[j, 0], vel[j, 1],
                            radius[j], RECIPROCAL, 1.0 if i < j else -1.0, tau, dt, lines, count)  # fmt: skip
            count += 1
        fail, rx, ry = _linear_program2(lines, count, vmax[i], pref[i, 0], pref[i, 1], False)
        if fail < count:
            rx, ry = _linear_program3(lines, count, num_obst_lines, fail, vmax[i], rx, ry, proj)
        out[i, 0], out[i, 1] = rx, ry


@numba.njit(cache=True)
def _obstacle_neighbors(
    pos: np.ndarray, radius: np.ndarray, vmax: np.ndarray, i: int, tau_obst: float,
    ob_point: np.ndarray, ob_next: np.ndarray, obst_idx: np.ndarray, obst_d2: np.ndarray,
) -> int:  # fmt: skip
    """Edges agent ``i`` faces within ``tau_obst * vmax + radius``, nearest first; returns their count."""
    px, py = pos[i, 0], pos[i, 1]
    range_sq = (tau_obst * vmax[i] + radius[i]) ** 2
    count = 0
    for k in range(ob_point.shape[0]):
        ax, ay = ob_point[k, 0], ob_point[k, 1]
        bx, by = ob_point[ob_next[k], 0], ob_point[ob_next[k], 1]
        if _det(bx - ax, by - ay, px - ax, py - ay) >= 0.0:  # agent left of (inside) the edge: unseen
            continue
        d2 = _dist_sq_point_segment(ax, ay, bx, by, px, py)
        if d2 < range_sq:
            m = count
            while m > 0 and d2 < obst_d2[m - 1]:
                obst_idx[m], obst_d2[m] = obst_idx[m - 1], obst_d2[m - 1]
                m -= 1
            obst_idx[m], obst_d2[m] = k, d2
            count += 1
    return count


@numba.njit(cache=True)
def _dist_sq_point_segment(ax: float, ay: float, bx: float, by: float, px: float, py: float) -> float:
    """Squared distance from point p to segment ab, m²."""
    ex, ey = bx - ax, by - ay
    t = ((px - ax) * ex + (py - ay) * ey) / (ex * ex + ey * ey)
    if t < 0.0:
        return (px - ax) ** 2 + (py - ay) ** 2
    if t > 1.0:
        return (px - bx) ** 2 + (py - by) ** 2
    return (px - ax - t * ex) ** 2 + (py - ay - t * ey) ** 2


@numba.njit(cache=True)
def _agent_neighbors(
    pos: np.ndarray, i: int, has_robot: bool, robot_pos: np.ndarray, neighbor_dist: float,
    max_neighbors: int, agent_idx: np.ndarray, agent_d2: np.ndarray,
) -> int:  # fmt: skip
    """Up to ``max_neighbors`` other discs within ``neighbor_dist`` of agent ``i``, nearest first.

    Index N (the pedestrian count) is the robot. Returns how many were kept.
    """
    n = pos.shape[0]
    range_sq = neighbor_dist * neighbor_dist
    count = 0
    if max_neighbors == 0:
        return 0
    for j in range(n + 1 if has_robot else n):
        if j == i:
            continue
        qx, qy = (robot_pos[0], robot_pos[1]) if j == n else (pos[j, 0], pos[j, 1])
        d2 = (qx - pos[i, 0]) ** 2 + (qy - pos[i, 1]) ** 2
        if d2 >= range_sq:
            continue
        if count < max_neighbors:
            count += 1
        m = count - 1
        while m > 0 and d2 < agent_d2[m - 1]:
            agent_idx[m], agent_d2[m] = agent_idx[m - 1], agent_d2[m - 1]
            m -= 1
        agent_idx[m], agent_d2[m] = j, d2
        if count == max_neighbors:
            range_sq = agent_d2[count - 1]
    return count


@numba.njit(cache=True)
def _agent_line(
    px: float, py: float, vx: float, vy: float, r: float, ox: float, oy: float, ovx: float, ovy: float,
    orr: float, resp: float, tie: float, tau: float, dt: float, lines: np.ndarray, row: int,
) -> None:  # fmt: skip
    """Writes the ORCA half-plane of an agent at p (velocity v, radius r) against another disc.

    ``resp`` is the share of the avoidance the agent takes; ``tie`` (+1 or -1) orients the push
    when both centres coincide.
    """
    rel_x, rel_y = ox - px, oy - py
    rvx, rvy = vx - ovx, vy - ovy
    dist_sq = rel_x * rel_x + rel_y * rel_y
    comb = r + orr
    comb_sq = comb * comb
    if dist_sq > comb_sq:
        inv_tau = 1.0 / tau
        wx, wy = rvx - inv_tau * rel_x, rvy - inv_tau * rel_y  # from the cut-off centre to v_rel
        w_sq = wx * wx + wy * wy
        dot1 = wx * rel_x + wy * rel_y
        if dot1 < 0.0 and dot1 * dot1 > comb_sq * w_sq:  # closest boundary point on the cut-off circle
            w_len = math.sqrt(w_sq)
            ux, uy = wx / w_len, wy / w_len
            dx, dy = uy, -ux
            scale = comb * inv_tau - w_len
            u_x, u_y = scale * ux, scale * uy
        else:  # on a leg
            leg = math.sqrt(dist_sq - comb_sq)
            if _det(rel_x, rel_y, wx, wy) > 0.0:  # left leg
                dx = (rel_x * leg - rel_y * comb) / dist_sq
                dy = (rel_x * comb + rel_y * leg) / dist_sq
            else:  # right leg
                dx = -(rel_x * leg + rel_y * comb) / dist_sq
                dy = -(-rel_x * comb + rel_y * leg) / dist_sq
            dot2 = rvx * dx + rvy * dy
            u_x, u_y = dot2 * dx - rvx, dot2 * dy - rvy
    else:  # already overlapping: leave the cone cut off at one time step
        inv_dt = 1.0 / dt
        wx, wy = rvx - inv_dt * rel_x, rvy - inv_dt * rel_y
        w_len = math.sqrt(wx * wx + wy * wy)
        if w_len > 1e-12:
            ux, uy = wx / w_len, wy / w_len
        else:
            d = math.sqrt(dist_sq)
            ux, uy = (-rel_x / d, -rel_y / d) if d > 1e-12 else (-tie, 0.0)
        dx, dy = uy, -ux
        scale = comb * inv_dt - w_len
        u_x, u_y = scale * ux, scale * uy
    lines[row, 0], lines[row, 1] = vx + resp * u_x, vy + resp * u_y
    lines[row, 2], lines[row, 3] = dx, dy


@numba.njit(cache=True)
def _add_obstacle_line(
    pos: np.ndarray, vel: np.ndarray, radius: np.ndarray, i: int, k: int, tau_obst: float,
    ob_point: np.ndarray, ob_dir: np.ndarray, ob_next: np.ndarray, ob_prev: np.ndarray,
    ob_convex: np.ndarray, lines: np.ndarray, count: int,
) -> int:  # fmt: skip
    """Appends the half-plane of edge ``k`` for agent ``i`` unless covered or ignorable; returns the count."""
    inv = 1.0 / tau_obst
    px, py, vx, vy, r = pos[i, 0], pos[i, 1], vel[i, 0], vel[i, 1], radius[i]
    o1, o2 = k, ob_next[k]
    r1x, r1y = ob_point[o1, 0] - px, ob_point[o1, 1] - py
    r2x, r2y = ob_point[o2, 0] - px, ob_point[o2, 1] - py
    for m in range(count):  # already covered by an earlier obstacle half-plane?
        lx, ly, ldx, ldy = lines[m, 0], lines[m, 1], lines[m, 2], lines[m, 3]
        if (_det(inv * r1x - lx, inv * r1y - ly, ldx, ldy) - inv * r >= -RVO_EPSILON
                and _det(inv * r2x - lx, inv * r2y - ly, ldx, ldy) - inv * r >= -RVO_EPSILON):  # fmt: skip
            return count
    d1_sq, d2_sq, r_sq = r1x * r1x + r1y * r1y, r2x * r2x + r2y * r2y, r * r
    ovx, ovy = ob_point[o2, 0] - ob_point[o1, 0], ob_point[o2, 1] - ob_point[o1, 1]
    s = (-r1x * ovx - r1y * ovy) / (ovx * ovx + ovy * ovy)
    line_sq = (-r1x - s * ovx) ** 2 + (-r1y - s * ovy) ** 2
    if s < 0.0 and d1_sq <= r_sq:  # touching the left vertex
        if ob_convex[o1]:
            return _put_line(lines, count, 0.0, 0.0, -r1y, r1x, True)
        return count
    if s > 1.0 and d2_sq <= r_sq:  # touching the right vertex (left to the next edge unless needed)
        if ob_convex[o2] and _det(r2x, r2y, ob_dir[o2, 0], ob_dir[o2, 1]) >= 0.0:
            return _put_line(lines, count, 0.0, 0.0, -r2y, r2x, True)
        return count
    if 0.0 <= s < 1.0 and line_sq <= r_sq:  # touching the edge
        return _put_line(lines, count, 0.0, 0.0, -ob_dir[o1, 0], -ob_dir[o1, 1], False)
    return _obstacle_legs_line(vx, vy, r, inv, px, py, o1, o2, s, line_sq, r1x, r1y, r2x, r2y,
                               ob_point, ob_dir, ob_prev, ob_convex, lines, count)  # fmt: skip


@numba.njit(cache=True)
def _put_line(lines: np.ndarray, row: int, x: float, y: float, dx: float, dy: float, normalize: bool) -> int:
    """Writes a half-plane (point, direction; the direction made unit if asked); returns row + 1."""
    if normalize:
        norm = math.hypot(dx, dy)
        if norm <= 1e-12:
            return row
        dx, dy = dx / norm, dy / norm
    lines[row, 0], lines[row, 1], lines[row, 2], lines[row, 3] = x, y, dx, dy
    return row + 1


@numba.njit(cache=True)
def _tangent(rx: float, ry: float, r: float, left: bool) -> tuple[float, float]:
    """Unit direction of the left or right tangent from the agent to a disc of radius r at (rx, ry)."""
    d_sq = rx * rx + ry * ry
    leg = math.sqrt(max(d_sq - r * r, 0.0))
    if left:
        return (rx * leg - ry * r) / d_sq, (rx * r + ry * leg) / d_sq
    return (rx * leg + ry * r) / d_sq, (-rx * r + ry * leg) / d_sq


@numba.njit(cache=True)
def _obstacle_legs_line(
    vx: float, vy: float, r: float, inv: float, px: float, py: float, o1: int, o2: int, s: float,
    line_sq: float, r1x: float, r1y: float, r2x: float, r2y: float, ob_point: np.ndarray, ob_dir: np.ndarray,
    ob_prev: np.ndarray, ob_convex: np.ndarray, lines: np.ndarray, count: int,
) -> int:  # fmt: skip
    """Half-plane of an edge the agent does not touch: project v on the truncated velocity obstacle."""
    r_sq = r * r
    if s < 0.0 and line_sq <= r_sq:  # seen obliquely: the left vertex alone defines it
        if not ob_convex[o1]:
            return count
        o2 = o1
        lx, ly = _tangent(r1x, r1y, r, True)
        rx_, ry_ = _tangent(r1x, r1y, r, False)
    elif s > 1.0 and line_sq <= r_sq:  # seen obliquely: the right vertex alone defines it
        if not ob_convex[o2]:
            return count
        o1 = o2
        lx, ly = _tangent(r2x, r2y, r, True)
        rx_, ry_ = _tangent(r2x, r2y, r, False)
    else:
        lx, ly = _tangent(r1x, r1y, r, True) if ob_convex[o1] else (-ob_dir[o1, 0], -ob_dir[o1, 1])
        rx_, ry_ = _tangent(r2x, r2y, r, False) if ob_convex[o2] else (ob_dir[o1, 0], ob_dir[o1, 1])
    left_nb = ob_prev[o1]
    left_foreign = right_foreign = False
    if ob_convex[o1] and _det(lx, ly, -ob_dir[left_nb, 0], -ob_dir[left_nb, 1]) >= 0.0:
        lx, ly, left_foreign = -ob_dir[left_nb, 0], -ob_dir[left_nb, 1], True  # leg points into the obstacle
    if ob_convex[o2] and _det(rx_, ry_, ob_dir[o2, 0], ob_dir[o2, 1]) <= 0.0:
        rx_, ry_, right_foreign = ob_dir[o2, 0], ob_dir[o2, 1], True
    lcx, lcy = inv * (ob_point[o1, 0] - px), inv * (ob_point[o1, 1] - py)  # cut-off centres
    rcx, rcy = inv * (ob_point[o2, 0] - px), inv * (ob_point[o2, 1] - py)
    cvx, cvy = rcx - lcx, rcy - lcy
    same = o1 == o2
    t = 0.5 if same else ((vx - lcx) * cvx + (vy - lcy) * cvy) / (cvx * cvx + cvy * cvy)
    t_left = (vx - lcx) * lx + (vy - lcy) * ly
    t_right = (vx - rcx) * rx_ + (vy - rcy) * ry_
    if (t < 0.0 and t_left < 0.0) or (same and t_left < 0.0 and t_right < 0.0):  # left cut-off circle
        return _cutoff_circle_line(vx, vy, lcx, lcy, r * inv, lines, count)
    if t > 1.0 and t_right < 0.0:  # right cut-off circle
        return _cutoff_circle_line(vx, vy, rcx, rcy, r * inv, lines, count)
    d_cut = np.inf if (t < 0.0 or t > 1.0 or same) else (vx - lcx - t * cvx) ** 2 + (vy - lcy - t * cvy) ** 2
    d_left = np.inf if t_left < 0.0 else (vx - lcx - t_left * lx) ** 2 + (vy - lcy - t_left * ly) ** 2
    d_right = np.inf if t_right < 0.0 else (vx - rcx - t_right * rx_) ** 2 + (vy - rcy - t_right * ry_) ** 2
    if d_cut <= d_left and d_cut <= d_right:  # cut-off line
        dx, dy = -ob_dir[o1, 0], -ob_dir[o1, 1]
        return _put_line(lines, count, lcx - r * inv * dy, lcy + r * inv * dx, dx, dy, False)
    if d_left <= d_right:  # left leg
        if left_foreign:
            return count
        return _put_line(lines, count, lcx - r * inv * ly, lcy + r * inv * lx, lx, ly, False)
    if right_foreign:  # right leg
        return count
    return _put_line(lines, count, rcx + r * inv * ry_, rcy - r * inv * rx_, -rx_, -ry_, False)


@numba.njit(cache=True)
def _cutoff_circle_line(
    vx: float, vy: float, cx: float, cy: float, cr: float, lines: np.ndarray, count: int
) -> int:
    """Half-plane tangent to the cut-off circle (centre c, radius cr) at the point nearest to v."""
    wx, wy = vx - cx, vy - cy
    w_len = math.hypot(wx, wy)
    if w_len <= 1e-12:
        return count
    ux, uy = wx / w_len, wy / w_len
    return _put_line(lines, count, cx + cr * ux, cy + cr * uy, uy, -ux, False)


@numba.njit(cache=True)
def _linear_program1(
    lines: np.ndarray, line_no: int, radius: float, opt_x: float, opt_y: float, direction_opt: bool
) -> tuple[bool, float, float]:
    """Optimum on the line ``line_no`` within the disc and the half-planes before it.

    Returns ``(feasible, x, y)``: minimum distance to ``opt`` (or furthest along the direction
    ``opt`` when ``direction_opt``); ``feasible`` False when that part of the line is empty.
    """
    px, py, dx, dy = lines[line_no, 0], lines[line_no, 1], lines[line_no, 2], lines[line_no, 3]
    dot = px * dx + py * dy
    disc = dot * dot + radius * radius - (px * px + py * py)
    if disc < 0.0:  # the max-speed disc misses the line
        return False, 0.0, 0.0
    root = math.sqrt(disc)
    t_left, t_right = -dot - root, -dot + root
    for m in range(line_no):
        denom = _det(dx, dy, lines[m, 2], lines[m, 3])
        numer = _det(lines[m, 2], lines[m, 3], px - lines[m, 0], py - lines[m, 1])
        if abs(denom) <= RVO_EPSILON:  # (almost) parallel
            if numer < 0.0:
                return False, 0.0, 0.0
            continue
        t = numer / denom
        if denom >= 0.0:
            t_right = min(t_right, t)  # line m bounds this line on the right
        else:
            t_left = max(t_left, t)
        if t_left > t_right:
            return False, 0.0, 0.0
    if direction_opt:
        t = t_right if opt_x * dx + opt_y * dy > 0.0 else t_left
    else:
        t = min(max(dx * (opt_x - px) + dy * (opt_y - py), t_left), t_right)
    return True, px + t * dx, py + t * dy


@numba.njit(cache=True)
def _linear_program2(
    lines: np.ndarray, count: int, radius: float, opt_x: float, opt_y: float, direction_opt: bool
) -> tuple[int, float, float]:
    """Point of the disc of ``radius`` inside the first ``count`` half-planes closest to ``opt``.

    With ``direction_opt``, ``opt`` is a unit direction and the point furthest along it is sought.
    Returns ``(fail, x, y)``: ``fail`` is ``count`` on success, else the first half-plane that
    could not be met, with the last feasible result.
    """
    if direction_opt:
        rx, ry = opt_x * radius, opt_y * radius
    elif opt_x * opt_x + opt_y * opt_y > radius * radius:
        norm = math.hypot(opt_x, opt_y)
        rx, ry = opt_x / norm * radius, opt_y / norm * radius
    else:
        rx, ry = opt_x, opt_y
    for m in range(count):
        if _det(lines[m, 2], lines[m, 3], lines[m, 0] - rx, lines[m, 1] - ry) > 0.0:  # violated
            ok, nx, ny = _linear_program1(lines, m, radius, opt_x, opt_y, direction_opt)
            if not ok:
                return m, rx, ry
            rx, ry = nx, ny
    return count, rx, ry


@numba.njit(cache=True)
def _linear_program3(
    lines: np.ndarray, count: int, num_obst: int, begin: int, radius: float, rx: float, ry: float,
    proj: np.ndarray,
) -> tuple[float, float]:  # fmt: skip
    """Velocity minimising the largest penetration into the agent half-planes, obstacle ones kept hard.

    Starts from the result of linear program 2 that failed at half-plane ``begin``.
    """
    distance = 0.0
    for i in range(begin, count):
        ldx, ldy = lines[i, 2], lines[i, 3]
        if _det(ldx, ldy, lines[i, 0] - rx, lines[i, 1] - ry) <= distance:
            continue
        n_proj = num_obst
        proj[:num_obst] = lines[:num_obst]
        for j in range(num_obst, i):
            det = _det(ldx, ldy, lines[j, 2], lines[j, 3])
            if abs(det) <= RVO_EPSILON:  # parallel
                if ldx * lines[j, 2] + ldy * lines[j, 3] > 0.0:
                    continue  # same direction
                qx, qy = 0.5 * (lines[i, 0] + lines[j, 0]), 0.5 * (lines[i, 1] + lines[j, 1])
            else:
                t = _det(lines[j, 2], lines[j, 3], lines[i, 0] - lines[j, 0], lines[i, 1] - lines[j, 1]) / det
                qx, qy = lines[i, 0] + t * ldx, lines[i, 1] + t * ldy
            ddx, ddy = lines[j, 2] - ldx, lines[j, 3] - ldy
            norm = math.hypot(ddx, ddy)
            proj[n_proj, 0], proj[n_proj, 1] = qx, qy
            proj[n_proj, 2], proj[n_proj, 3] = ddx / norm, ddy / norm
            n_proj += 1
        fail, nx, ny = _linear_program2(proj, n_proj, radius, -ldy, ldx, True)
        if fail >= n_proj:  # on failure (round-off only) the previous result is kept
            rx, ry = nx, ny
        distance = _det(ldx, ldy, lines[i, 0] - rx, lines[i, 1] - ry)
    return rx, ry


# ---------------------------------------------------------------------------- model step


#: Layout of the float parameter vector of :func:`_orca_advance`.
_P_NEIGHBOR_DIST, _P_TAU, _P_TAU_OBST, _P_GOAL_TOL, _P_MARGIN, _P_ROBOT_RADIUS, _P_ROBOT_RESP = range(7)
_P_BOX = 7  # xmin, ymin, xmax, ymax follow


@numba.njit(cache=True)
def _orca_advance(
    pos: np.ndarray, vel: np.ndarray, goal: np.ndarray, v0: np.ndarray, radius: np.ndarray, vmax: np.ndarray,
    time_left: np.ndarray, redraw: np.ndarray, verts: np.ndarray, offsets: np.ndarray,
    ob_point: np.ndarray, ob_dir: np.ndarray, ob_next: np.ndarray, ob_prev: np.ndarray, ob_convex: np.ndarray,
    params: np.ndarray, max_neighbors: int, dt: float, robot_path: np.ndarray, robot_memory: np.ndarray,
    track: np.ndarray, start: int, counters: np.ndarray,
) -> int:  # fmt: skip
    """ORCA steps ``start, start + 1, ...`` in place, positions into ``track``; stops after a step
    that flags a goal redraw in ``redraw`` (the caller draws, then resumes) or at ``len(track)``.

    Per step: preferred velocities, ORCA velocities of all pedestrians from the same state, move,
    guard, goal bookkeeping. ``robot_path`` (len(track), 2) holds the robot centre at the start of
    each step, or has no rows (no robot). ``robot_memory`` = (known, x, y): the robot centre of the
    previous step, from which its velocity is taken (zero when unknown). ``counters`` gets +=
    (guard corrections, overlapping pedestrian pairs after a step). Returns the next step index.
    """
    n = pos.shape[0]
    orca_radius = radius + params[_P_MARGIN]
    lines = np.empty((ob_point.shape[0] + max_neighbors + 1, 4))
    proj = np.empty_like(lines)
    agent_idx, agent_d2 = np.empty(max_neighbors + 1, dtype=np.int64), np.empty(max_neighbors + 1)
    obst_idx, obst_d2 = np.empty(ob_point.shape[0], dtype=np.int64), np.empty(ob_point.shape[0])
    pref, new_vel, robot_vel = np.empty((n, 2)), np.empty((n, 2)), np.zeros(2)
    has_robot = robot_path.shape[0] > 0
    xmin, ymin, xmax, ymax = params[_P_BOX], params[_P_BOX + 1], params[_P_BOX + 2], params[_P_BOX + 3]
    for k in range(start, track.shape[0]):
        if has_robot:
            robot_vel[0] = (robot_path[k, 0] - robot_memory[1]) / dt if robot_memory[0] else 0.0
            robot_vel[1] = (robot_path[k, 1] - robot_memory[2]) / dt if robot_memory[0] else 0.0
            robot_memory[0], robot_memory[1], robot_memory[2] = 1.0, robot_path[k, 0], robot_path[k, 1]
        for i in range(n):
            gx, gy = goal[i, 0] - pos[i, 0], goal[i, 1] - pos[i, 1]
            d = math.hypot(gx, gy)
            scale = v0[i] / d if d > 1e-12 else 0.0
            pref[i, 0], pref[i, 1] = scale * gx, scale * gy
        _orca_velocities(
            pos, vel, orca_radius, pref, vmax, ob_point, ob_dir, ob_next, ob_prev, ob_convex,
            params[_P_NEIGHBOR_DIST], max_neighbors, params[_P_TAU], params[_P_TAU_OBST], dt, has_robot,
            robot_path[k] if has_robot else robot_vel, robot_vel, params[_P_ROBOT_RADIUS], params[_P_ROBOT_RESP],
            lines, proj, agent_idx, agent_d2, obst_idx, obst_d2, new_vel,
        )  # fmt: skip
        flagged = _move_and_check(pos, vel, new_vel, goal, radius, time_left, redraw, dt, xmin, ymin, xmax, ymax,
                                  verts, offsets, params[_P_GOAL_TOL], counters)  # fmt: skip
        track[k] = pos
        if flagged:
            return k + 1
    return track.shape[0]


@numba.njit(cache=True)
def _move_and_check(
    pos: np.ndarray, vel: np.ndarray, new_vel: np.ndarray, goal: np.ndarray, radius: np.ndarray,
    time_left: np.ndarray, redraw: np.ndarray, dt: float, xmin: float, ymin: float, xmax: float, ymax: float,
    verts: np.ndarray, offsets: np.ndarray, goal_tolerance: float, counters: np.ndarray,
) -> bool:  # fmt: skip
    """Takes the new velocities, moves, guards, counts contacts; returns whether a goal is due."""
    n = pos.shape[0]
    flagged = False
    for i in range(n):
        vel[i, 0], vel[i, 1] = new_vel[i, 0], new_vel[i, 1]
        pos[i, 0] += vel[i, 0] * dt
        pos[i, 1] += vel[i, 1] * dt
    for i in range(n):
        counters[0] += _guard(pos, vel, radius, i, xmin, ymin, xmax, ymax, verts, offsets)
        time_left[i] -= dt
        distance = math.hypot(goal[i, 0] - pos[i, 0], goal[i, 1] - pos[i, 1])
        redraw[i] = distance < goal_tolerance or time_left[i] <= 0.0
        flagged = flagged or redraw[i]
    for i in range(n):
        for j in range(i + 1, n):
            contact = radius[i] + radius[j]
            if (pos[i, 0] - pos[j, 0]) ** 2 + (pos[i, 1] - pos[j, 1]) ** 2 < contact * contact:
                counters[1] += 1
    return flagged


@numba.njit(cache=True)
def _guard(
    pos: np.ndarray, vel: np.ndarray, radius: np.ndarray, i: int, xmin: float, ymin: float,
    xmax: float, ymax: float, verts: np.ndarray, offsets: np.ndarray,
) -> int:  # fmt: skip
    """Pushes disc i out of obstacles, then inside the walls, dropping velocity into the surfaces.

    Returns how many corrections it made (0 when ORCA kept the disc clear, as it should).
    """
    r = radius[i]
    moved = 0
    for k in range(offsets.shape[0] - 1):
        dist, nx, ny = polygon_contact(pos[i, 0], pos[i, 1], verts, offsets[k], offsets[k + 1])
        if dist < r:
            pos[i, 0] += (r - dist) * nx
            pos[i, 1] += (r - dist) * ny
            vn = vel[i, 0] * nx + vel[i, 1] * ny
            if vn < 0.0:
                vel[i, 0] -= vn * nx
                vel[i, 1] -= vn * ny
            moved += 1
    for axis, low, high in ((0, xmin, xmax), (1, ymin, ymax)):
        if pos[i, axis] < low + r:
            pos[i, axis] = low + r
            vel[i, axis] = max(vel[i, axis], 0.0)
            moved += 1
        elif pos[i, axis] > high - r:
            pos[i, axis] = high - r
            vel[i, axis] = min(vel[i, axis], 0.0)
            moved += 1
    return moved


# ---------------------------------------------------------------------------- model


class OrcaModel(GoalSeekingModel):
    """Goal-seeking pedestrians that choose ORCA velocities against each other, walls and obstacles.

    Each pedestrian walks towards its own goal at its speed from :meth:`reset` (its preferred
    speed), drawn and re-drawn as in the social-force model (uniform in free space; a new goal
    once within ``goal_tolerance`` or once the time budget runs out). Per step: preferred
    velocities, ORCA velocities of all pedestrians from the same state (the robot disc as an extra
    agent when ``reactive``), move, then a last geometric guard that pushes a disc out of obstacles
    and inside the walls (counted in :attr:`guard_corrections`; ORCA's hard obstacle half-planes
    keep it near zero). Pedestrian pairs are not separated by hand: :attr:`overlaps` counts
    pairs that overlap after a step.
    """

    config_class = OrcaConfig

    def __init__(self, config: OrcaConfig | None = None) -> None:
        """Creates the model.

        Args:
            config: ORCA parameters; None: the defaults (non-reactive).
        """
        super().__init__()
        self.config = OrcaConfig() if config is None else config
        if not isinstance(self.config, OrcaConfig):
            raise TypeError(f"OrcaModel needs an OrcaConfig, got {type(self.config).__name__}")
        #: Whether the motion depends on the robot (see :class:`PedestrianModel`).
        self.reacts_to_robot = self.config.reactive
        self._goal = np.zeros((0, 2))
        self._redraw = np.zeros(0, dtype=np.bool_)
        self._time_left = np.zeros(0)
        self._counters = np.zeros(2, dtype=np.int64)
        self._robot_memory = np.zeros(3)  # (known, x, y) of the robot at the previous step
        self._params = np.zeros(_P_BOX + 4)
        self._vmax = np.zeros(0)
        self._obstacles = orca_obstacles()

    @classmethod
    def from_config(cls, crowd: object, orca: OrcaConfig | None = None) -> OrcaModel:
        """Creates the model for a task's crowd config.

        Args:
            crowd: The task's :class:`~mjnav.schema.CrowdConfig`. Read when present: ``orca``
                (an :class:`OrcaConfig`, used when ``orca`` is None) and ``reactive`` (when not
                None it overrides :attr:`OrcaConfig.reactive`).
            orca: ORCA parameters; None: ``crowd.orca`` or the defaults.
        """
        if orca is None:
            orca = getattr(crowd, "orca", None) or OrcaConfig()
        reactive = getattr(crowd, "reactive", None)
        return cls(orca if reactive is None else dataclasses.replace(orca, reactive=bool(reactive)))

    @property
    def goal_tolerance(self) -> float:
        """Distance to the goal at which a new goal is drawn, metres (:attr:`OrcaConfig.goal_tolerance`)."""
        return self.config.goal_tolerance

    @property
    def goals(self) -> np.ndarray:
        """Current goals, (P, 2), metres (a copy)."""
        return self._goal.copy()

    @property
    def guard_corrections(self) -> int:
        """Wall and obstacle corrections the last guard made since :meth:`reset`."""
        return int(self._counters[0])

    @property
    def overlaps(self) -> int:
        """Pedestrian pairs that overlapped after a step, summed over steps since :meth:`reset`."""
        return int(self._counters[1])

    def _initialize(self, headings: np.ndarray) -> None:
        n = self._pos.shape[0]
        self._obstacles = orca_obstacles(
            [self._verts[self._offsets[k] : self._offsets[k + 1]] for k in range(len(self._offsets) - 1)],
            bounds=self._bounds,
        )
        c = self.config
        params = [c.neighbor_dist, c.time_horizon, c.time_horizon_obst, c.goal_tolerance, c.safety_margin, 0.0,
                  c.robot_responsibility, *self._bounds]  # fmt: skip
        self._params = np.array(params, dtype=np.float64)
        self._vmax = self._speed * c.max_speed_factor
        self._goal = np.empty_like(self._pos)
        self._redraw = np.zeros(n, dtype=np.bool_)
        self._time_left = np.empty(n)
        self._counters[:] = 0
        self._robot_memory[:] = 0.0
        for i in range(n):
            self._new_goal(i)

    def step(self, dt: float, robot_position: np.ndarray | None = None, robot_radius: float = 0.225) -> None:
        """Advances the crowd by ``dt`` seconds (see :meth:`advance`).

        Raises:
            ValueError: If ``dt`` is not positive, or a reactive model gets a non-finite robot.
        """
        robot = None if robot_position is None else np.asarray(robot_position, dtype=np.float64).reshape(1, -1)
        self.advance(dt, 1, robot, robot_radius)

    def advance(self, dt: float, steps: int, robot_positions: np.ndarray | None = None,
                robot_radius: float = 0.225) -> np.ndarray:
        """Takes ``steps`` steps of ``dt``, in as few kernel calls as goal redraws allow.

        With ``config.reactive`` and robot positions, the robot is a disc of ``robot_radius``
        moving at the velocity of its last step (its position change over ``dt``; zero on the
        first step after :meth:`reset` or after a step without robot); otherwise it is ignored.

        Args:
            dt: Time step, s, > 0.
            steps: Number of steps, >= 1.
            robot_positions: (steps, 2) robot centre at the start of each step, metres (further
                columns are ignored); None: none.
            robot_radius: Robot disc radius, metres, > 0.

        Returns:
            (steps, P, 2) disc centres after each step, metres.

        Raises:
            ValueError: On a bad ``dt`` or ``steps``, or non-finite robot inputs for a reactive model.
        """
        dt = self._check_step(dt)
        if not (isinstance(steps, (int, np.integer)) and steps >= 1):
            raise ValueError(f"steps must be an integer >= 1, got {steps!r}")
        path = self._robot_path(steps, robot_positions, robot_radius)
        track = np.empty((steps, *self._pos.shape))
        done = 0
        while done < steps:
            done = _orca_advance(
                self._pos, self._vel, self._goal, self._speed, self._radius, self._vmax, self._time_left,
                self._redraw, self._verts, self._offsets, *self._obstacles, self._params, self.config.max_neighbors,
                dt, path, self._robot_memory, track, done, self._counters,
            )  # fmt: skip
            for i in np.flatnonzero(self._redraw):
                self._new_goal(i)
        return track

    def _robot_path(self, steps: int, robot_positions: np.ndarray | None, robot_radius: float) -> np.ndarray:
        """(steps, 2) robot centres for a reactive model given a robot, else (0, 2); sets its radius."""
        if not self.reacts_to_robot or robot_positions is None:
            self._robot_memory[0] = 0.0
            return np.zeros((0, 2))
        path = np.asarray(robot_positions, dtype=np.float64)
        radius_ok = math.isfinite(robot_radius) and robot_radius > 0
        if path.ndim != 2 or path.shape[0] != steps or path.shape[1] < 2 or not radius_ok:
            raise ValueError(f"robot positions must be ({steps}, >= 2) (x, y first) and its radius finite and > 0, "
                             f"got shape {path.shape}, radius {robot_radius}")  # fmt: skip
        path = np.ascontiguousarray(path[:, :2])
        if not np.all(np.isfinite(path)):
            raise ValueError(f"robot positions must be finite, got {path.tolist()}")
        self._params[_P_ROBOT_RADIUS] = robot_radius + self.config.safety_margin
        return path
