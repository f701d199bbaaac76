"""Episode layout sampling: obstacles, start, goal and pedestrians (spec §9).

One attempt draws a whole scene in this order, each item from the generator passed in:

1. ``count`` obstacles: a uniform bank index, a centre uniform over the positions that keep
   the circumcircle inside the walls, a uniform yaw in [-π, π). Obstacles may overlap each other
   (the spec does not forbid it).
2. Start, then goal: uniform over the interior shrunk by the clearance ``c = max(free_clearance,
   robot_radius)``, redrawn (up to ``_ITEM_TRIES`` times) until the point is at least ``c`` from
   every obstacle polygon (distance from the point itself; the robot radius is not added on top)
   and at least ``obstacle_clearance`` from every obstacle centre; the goal must also lie in
   ``[start_goal_min_distance, start_goal_max_distance]`` (no upper bound when the max is 0)
   of the start.
3. Pedestrians (``crowd.count``): radius uniform in ``crowd.radius``, centre uniform over the
   interior shrunk by the radius, redrawn (up to ``_ITEM_TRIES`` times) until clear of the
   obstacles (signed distance >= radius), ``pedestrian_gap`` clear of earlier pedestrians, with
   the centre at least ``pedestrian_clearance`` from the start and the goal (spec §9: obstacle
   centres >= 1.95 m from both; pedestrians are the dynamic obstacles).
4. Start scan: the noise-free analytic scan at the start, shrunk by ``inflation``, must read
   more than ``min_start_scan`` on every beam; a pedestrian overlapping the robot's disc at the
   start also fails. The walls-and-obstacles part of this test runs right after the start is
   drawn (the accepted distribution is the same; rejected scenes stop early). The test is exact:
   it casts ``cast_rays_kernel`` beams against every item within the threshold of the start.

Any failure (an item out of tries, or the scan) discards the whole scene and starts a new
attempt, so accepted scenes follow the proposal conditioned on every constraint. Speeds and
headings (uniform) are drawn once, after acceptance. After ``max_attempts`` attempts a
:class:`LayoutError` names the constraint that failed most often.
"""

from __future__ import annotations

import dataclasses

import numpy as np
from numba import njit

from mjnav.geometry.raycast import beam_angles, cast_rays_kernel, polygon_segments, wall_segments
from mjnav.schema import ArenaConfig, CrowdConfig, LayoutConfig, LidarConfig, ObstacleConfig
from mjnav.world.shapes import ShapeBank

__all__ = ["Layout", "LayoutError", "sample_layout", "scene_circles", "scene_segments"]

# Draws per item (start, goal, one pedestrian) inside one attempt before the attempt fails.
_ITEM_TRIES = 100
_FAILURES = ("start in free space", "goal in free space at the start-goal distance",
             "pedestrian placement", "start scan above min_start_scan")


class LayoutError(RuntimeError):
    """No layout met the constraints within ``max_attempts``; the message names the culprit."""


@dataclasses.dataclass(frozen=True, eq=False)
class Layout:
    """One episode's world (read-only arrays; metres, radians, m/s).

    Attributes:
        start: (2,) robot start position.
        goal: (2,) goal position.
        obstacle_shapes: (K,) int64 shape-bank indices.
        obstacle_poses: (K, 3) obstacle poses (x, y, yaw) of the local (circle-centre) frame.
        obstacle_polygons: K world-frame counter-clockwise vertex arrays, each (3 or 4, 2).
        ped_positions: (P, 2) pedestrian centres.
        ped_radii: (P,) pedestrian radii.
        ped_speeds: (P,) pedestrian speeds.
        ped_headings: (P,) pedestrian headings in [-π, π).
    """

    start: np.ndarray
    goal: np.ndarray
    obstacle_shapes: np.ndarray
    obstacle_poses: np.ndarray
    obstacle_polygons: tuple[np.ndarray, ...]
    ped_positions: np.ndarray
    ped_radii: np.ndarray
    ped_speeds: np.ndarray
    ped_headings: np.ndarray

    def __post_init__(self) -> None:
        for array in self._arrays():
            array.flags.writeable = False

    def _arrays(self) -> list[np.ndarray]:
        named = [getattr(self, f.name) for f in dataclasses.fields(self) if f.name != "obstacle_polygons"]
        return named + list(self.obstacle_polygons)

    def __eq__(self, other: object) -> bool:
        if not isinstance(other, Layout):
            return NotImplemented
        mine, theirs = self._arrays(), other._arrays()
        return len(mine) == len(theirs) and all(map(np.array_equal, mine, theirs))

    __hash__ = None  # type: ignore[assignment]


def scene_segments(layout: Layout, arena: ArenaConfig) -> np.ndarray:
    """(4 + edges, 4) segments ``[x0, y0, x1, y1]`` of the wall faces and obstacle edges, metres."""
    return np.vstack([wall_segments(arena.size), polygon_segments(layout.obstacle_polygons)])


def scene_circles(positions: np.ndarray, radii: np.ndarray) -> np.ndarray:
    """(P, 3) circles ``[x, y, r]`` from (P, 2) centres and (P,) radii, metres."""
    return np.ascontiguousarray(np.column_stack([positions, radii]), dtype=np.float64)


# ---------------------------------------------------------------------------- numba kernels


@njit(cache=True)
def _segment_distance(px: float, py: float, ax: float, ay: float, bx: float, by: float) -> float:
    """Distance from point p to segment ab (a point when a == b), metres."""
    ex, ey, wx, wy = bx - ax, by - ay, px - ax, py - ay
    ee = ex * ex + ey * ey
    u = 0.0 if ee == 0.0 else min(max((wx * ex + wy * ey) / ee, 0.0), 1.0)
    return np.hypot(wx - u * ex, wy - u * ey)


@njit(cache=True)
def _signed_distance(px: float, py: float, poly: np.ndarray) -> float:
    """Signed distance from p to a padded convex CCW polygon (4, 2): negative inside."""
    inside, best = True, np.inf
    for i in range(4):
        ax, ay, bx, by = poly[i, 0], poly[i, 1], poly[(i + 1) % 4, 0], poly[(i + 1) % 4, 1]
        if (bx - ax) * (py - ay) - (by - ay) * (px - ax) < 0.0:
            inside = False
        best = min(best, _segment_distance(px, py, ax, ay, bx, by))
    return -best if inside else best


@njit(cache=True)
def _place_obstacles(
    rng: np.random.Generator, bank: np.ndarray, margin_x: float, margin_y: float,
    shapes: np.ndarray, poses: np.ndarray, polys: np.ndarray,
) -> None:
    """Draw bank indices and poses; write world-frame padded polygons into ``polys``."""
    for k in range(shapes.shape[0]):
        shapes[k] = rng.integers(0, bank.shape[0])
        x, y = rng.uniform(-margin_x, margin_x), rng.uniform(-margin_y, margin_y)
        yaw = rng.uniform(-np.pi, np.pi)
        poses[k, 0], poses[k, 1], poses[k, 2] = x, y, yaw
        c, s = np.cos(yaw), np.sin(yaw)
        for v in range(4):
            lx, ly = bank[shapes[k], v, 0], bank[shapes[k], v, 1]
            polys[k, v, 0], polys[k, v, 1] = x + c * lx - s * ly, y + s * lx + c * ly


@njit(cache=True)
def _clear_of_obstacles(
    x: float, y: float, poses: np.ndarray, polys: np.ndarray, clearance: float, centre_clearance: float
) -> bool:
    """Whether p is >= clearance from every polygon and >= centre_clearance from every centre."""
    for k in range(polys.shape[0]):
        if np.hypot(x - poses[k, 0], y - poses[k, 1]) < centre_clearance:
            return False
        if _signed_distance(x, y, polys[k]) < clearance:
            return False
    return True


@njit(cache=True)
def _free_point(
    rng: np.random.Generator, half: np.ndarray, clear: float, centre_clear: float, poses: np.ndarray,
    polys: np.ndarray, ref: np.ndarray, dist_lo: float, dist_hi: float, out: np.ndarray,
) -> bool:
    """Draw a free point ``dist_lo <= |p - ref| <= dist_hi`` (no upper bound if dist_hi <= 0)."""
    for _ in range(_ITEM_TRIES):
        x = rng.uniform(-half[0] + clear, half[0] - clear)
        y = rng.uniform(-half[1] + clear, half[1] - clear)
        d = np.hypot(x - ref[0], y - ref[1])
        if d < dist_lo or (dist_hi > 0.0 and d > dist_hi):
            continue
        if _clear_of_obstacles(x, y, poses, polys, clear, centre_clear):
            out[0], out[1] = x, y
            return True
    return False


@njit(cache=True)
def _ped_fits(
    x: float, y: float, r: float, i: int, gap: float, positions: np.ndarray, radii: np.ndarray,
    polys: np.ndarray, start: np.ndarray, goal: np.ndarray, clearance: float,
) -> bool:
    """Whether pedestrian i at (x, y) clears the obstacles and pedestrians 0..i-1, and its centre
    lies at least ``clearance`` from the start and the goal."""
    if np.hypot(x - start[0], y - start[1]) < clearance or np.hypot(x - goal[0], y - goal[1]) < clearance:
        return False
    for k in range(polys.shape[0]):
        if _signed_distance(x, y, polys[k]) < r:
            return False
    for j in range(i):
        if np.hypot(x - positions[j, 0], y - positions[j, 1]) < r + radii[j] + gap:
            return False
    return True


@njit(cache=True)
def _place_peds(
    rng: np.random.Generator, half: np.ndarray, crowd: tuple[float, float, float, float], polys: np.ndarray,
    start: np.ndarray, goal: np.ndarray, positions: np.ndarray, radii: np.ndarray,
) -> bool:
    """Place pedestrians one by one; False when one runs out of tries."""
    r_lo, r_hi, gap, clearance = crowd
    for i in range(radii.shape[0]):
        r = rng.uniform(r_lo, r_hi)
        radii[i] = r
        placed = False
        for _ in range(_ITEM_TRIES):
            x, y = rng.uniform(-half[0] + r, half[0] - r), rng.uniform(-half[1] + r, half[1] - r)
            if _ped_fits(x, y, r, i, gap, positions, radii, polys, start, goal, clearance):
                positions[i, 0], positions[i, 1] = x, y
                placed = True
                break
        if not placed:
            return False
    return True


@njit(cache=True)
def _scan_clear(
    p: np.ndarray, segments: np.ndarray, circles: np.ndarray, body_radius: float, cos_a: np.ndarray,
    sin_a: np.ndarray, max_range: float, threshold: float,
) -> bool:
    """Whether every beam from p reads > threshold; exact, casting only against nearby items.

    Items farther than ``threshold`` cannot lower any reading to it, so they are skipped. A
    circle overlapping the disc of radius ``body_radius`` around p fails outright.
    """
    if max_range <= threshold:
        return False
    near_seg = np.zeros(segments.shape[0], dtype=np.bool_)
    for s in range(segments.shape[0]):
        a = segments[s]
        near_seg[s] = _segment_distance(p[0], p[1], a[0], a[1], a[2], a[3]) <= threshold
    near_circ = np.zeros(circles.shape[0], dtype=np.bool_)
    for c in range(circles.shape[0]):
        gap = np.hypot(p[0] - circles[c, 0], p[1] - circles[c, 1]) - circles[c, 2]
        if gap < body_radius:
            return False
        near_circ[c] = gap <= threshold
    if not (near_seg.any() or near_circ.any()):
        return True
    ranges = cast_rays_kernel(p[0], p[1], cos_a, sin_a, segments[near_seg], circles[near_circ], max_range)
    return ranges.min() > threshold


@njit(cache=True)
def _static_segments(half: np.ndarray, polys: np.ndarray) -> np.ndarray:
    """(4 + 4K, 4) wall faces plus padded polygon edges (zero-length ones are never hit)."""
    out = np.empty((4 + 4 * polys.shape[0], 4))
    corners = np.array([[-half[0], -half[1]], [half[0], -half[1]], [half[0], half[1]], [-half[0], half[1]]])
    for i in range(4):
        out[i, :2], out[i, 2:] = corners[i], corners[(i + 1) % 4]
    for k in range(polys.shape[0]):
        for v in range(4):
            out[4 + 4 * k + v, :2], out[4 + 4 * k + v, 2:] = polys[k, v], polys[k, (v + 1) % 4]
    return out


@njit(cache=True)
def _sample_scene(
    rng: np.random.Generator, bank: np.ndarray, half: np.ndarray, obstacle_margin: float,
    geometry: tuple[float, float, float, float], crowd: tuple[float, float, float, float],
    scan: tuple[float, float, float], cos_a: np.ndarray, sin_a: np.ndarray, scene: tuple[np.ndarray, ...],
) -> int:
    """One attempt: fill ``scene`` in place; return 0 on success, else the failing step (1-4).

    geometry = (clearance, centre clearance, min distance, max distance); crowd = (r_lo, r_hi,
    gap, start/goal clearance); scan = (robot radius, max range, threshold); scene = (shapes,
    poses, polys, start, goal, positions, radii).
    """
    shapes, poses, polys, start, goal, positions, radii = scene
    _place_obstacles(rng, bank, half[0] - obstacle_margin, half[1] - obstacle_margin, shapes, poses, polys)
    clear, centre_clear, dist_lo, dist_hi = geometry
    if not _free_point(rng, half, clear, centre_clear, poses, polys, start, 0.0, 0.0, start):
        return 1
    no_circles = np.zeros((0, 3))
    if not _scan_clear(start, _static_segments(half, polys), no_circles, 0.0, cos_a, sin_a, scan[1], scan[2]):
        return 4
    if not _free_point(rng, half, clear, centre_clear, poses, polys, start, dist_lo, dist_hi, goal):
        return 2
    if not _place_peds(rng, half, crowd, polys, start, goal, positions, radii):
        return 3
    circles = np.empty((radii.shape[0], 3))
    circles[:, :2], circles[:, 2] = positions, radii
    if not _scan_clear(start, np.zeros((0, 4)), circles, scan[0], cos_a, sin_a, scan[1], scan[2]):
        return 4
    return 0


@njit(cache=True)
def _sample_attempts(
    rng: np.random.Generator, bank: np.ndarray, half: np.ndarray, obstacle_margin: float,
    geometry: tuple[float, float, float, float], crowd: tuple[float, float, float, float],
    scan: tuple[float, float, float], cos_a: np.ndarray, sin_a: np.ndarray, scene: tuple[np.ndarray, ...],
    max_attempts: int, fails: np.ndarray,
) -> bool:
    """Up to ``max_attempts`` :func:`_sample_scene` attempts in one call (a numba dispatch with a
    generator costs ~25 µs, and stage 7 takes ~36 attempts); ``fails[code - 1]`` counts each
    failed attempt. True once ``scene`` holds an accepted layout."""
    for _ in range(max_attempts):
        code = _sample_scene(rng, bank, half, obstacle_margin, geometry, crowd, scan, cos_a, sin_a, scene)
        if code == 0:
            return True
        fails[code - 1] += 1
    return False


# ---------------------------------------------------------------------------- public sampler


def _check_feasible(arena: ArenaConfig, obstacles: ObstacleConfig, crowd: CrowdConfig,
                    bank: ShapeBank, clearance: float) -> None:
    """Raise LayoutError for configs no attempt can satisfy (items cannot fit the interior)."""
    smallest = min(arena.size)
    needs = {
        "free_clearance (start/goal margin to the walls)": 2.0 * clearance,
        "pedestrian radius": 2.0 * crowd.radius[1] if crowd.count else 0.0,
        "obstacle circumcircle": 2.0 * bank.circumradius if obstacles.count else 0.0,
    }
    for what, width in needs.items():
        if width >= smallest:
            raise LayoutError(f"sample_layout: {what} needs {width} m, interior is only {smallest} m wide")


def _failure(fails: np.ndarray, attempts: int) -> LayoutError:
    worst = int(np.argmax(fails))
    counts = ", ".join(f"{name}: {int(n)}" for name, n in zip(_FAILURES, fails))
    return LayoutError(
        f"sample_layout: no valid layout in {attempts} attempts; the constraint that kept failing "
        f"is '{_FAILURES[worst]}' (failures per constraint: {counts})"
    )


def _empty_scene(num_obstacles: int, num_peds: int) -> tuple[np.ndarray, ...]:
    return (np.zeros(num_obstacles, np.int64), np.zeros((num_obstacles, 3)), np.zeros((num_obstacles, 4, 2)),
            np.zeros(2), np.zeros(2), np.zeros((num_peds, 2)), np.zeros(num_peds))


def sample_layout(
    arena: ArenaConfig,
    obstacles: ObstacleConfig,
    crowd: CrowdConfig,
    layout: LayoutConfig,
    lidar: LidarConfig,
    bank: ShapeBank,
    rng: np.random.Generator,
    inflation: float = 0.325,
    robot_radius: float = 0.225,
) -> Layout:
    """Sample one episode's world by whole-scene rejection (spec §9; procedure in the module doc).

    Args:
        arena: Interior size (metres, centred on the origin).
        obstacles: Obstacle count (K); the shapes come from ``bank``.
        crowd: Pedestrian count (P), radius range (m) and speed range (m/s).
        layout: Clearances (m), start-goal distance bounds (m), ``min_start_scan`` (m),
            ``pedestrian_gap`` and ``pedestrian_clearance`` (m) and ``max_attempts``.
        lidar: Beam count and ``max_range`` (m) of the noise-free start scan.
        bank: The task's obstacle shape bank.
        rng: The only source of randomness.
        inflation: R_inf, metres; scan readings are shrunk by it before the start test.
        robot_radius: Robot disc radius, metres; a lower bound on the start/goal clearance, and
            pedestrians may not overlap the robot's disc at the start.

    Returns:
        The layout.

    Raises:
        LayoutError: Items cannot fit the interior, or ``max_attempts`` attempts all failed; the
            message names the constraint that failed most often.
    """
    clearance = max(layout.free_clearance, robot_radius)
    _check_feasible(arena, obstacles, crowd, bank, clearance)
    angles = beam_angles(lidar.beams)
    cos_a, sin_a = np.cos(angles), np.sin(angles)
    geometry = (clearance, layout.obstacle_clearance, layout.start_goal_min_distance,
                layout.start_goal_max_distance)
    crowd_params = (float(crowd.radius[0]), float(crowd.radius[1]), layout.pedestrian_gap,
                    layout.pedestrian_clearance)
    scan = (robot_radius, lidar.max_range, layout.min_start_scan + inflation)
    half = 0.5 * np.asarray(arena.size, dtype=np.float64)
    scene = _empty_scene(obstacles.count, crowd.count)
    fails = np.zeros(len(_FAILURES), np.int64)
    if _sample_attempts(rng, bank.vertices, half, bank.circumradius, geometry, crowd_params, scan, cos_a, sin_a,
                        scene, layout.max_attempts, fails):
        return _make_layout(scene, bank, crowd, rng)
    raise _failure(fails, layout.max_attempts)


def _make_layout(scene: tuple[np.ndarray, ...], bank: ShapeBank, crowd: CrowdConfig,
                 rng: np.random.Generator) -> Layout:
    """Freeze an accepted scene; draw pedestrian speeds and headings (uniform)."""
    shapes, poses, polys, start, goal, positions, radii = scene
    count = radii.shape[0]
    return Layout(
        start=start.copy(),
        goal=goal.copy(),
        obstacle_shapes=shapes.copy(),
        obstacle_poses=poses.copy(),
        obstacle_polygons=tuple(polys[k, : bank.counts[shapes[k]]].copy() for k in range(len(shapes))),
        ped_positions=positions.copy(),
        ped_radii=radii.copy(),
        ped_speeds=rng.uniform(crowd.speed[0], crowd.speed[1], size=count),
        ped_headings=rng.uniform(-np.pi, np.pi, size=count),
    )
