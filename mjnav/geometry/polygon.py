"""Helpers on 2-D polygons: orientation, convexity, half-planes, containment, ray casts.

All coordinates are metres in one planar frame (mjnav uses the robot frame). A polygon is
an ``(K, 2)`` array of vertices without the closing repeat; either orientation is accepted
unless a function says otherwise. A convex polygon's half-plane form is ``n_j · x <= c_j``
with outward unit normals ``n_j`` (one per edge, in vertex order).

The hull kernels, the ray casts and :func:`point_in_halfplanes` are jitted with numba
(``cache=True``, they sit on the per-step path); the rest is plain numpy.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

__all__ = [
    "contains_point",
    "convex_hull_indices",
    "graham_scan",
    "halfplanes",
    "is_clockwise",
    "is_convex",
    "monotone_chain",
    "orient_clockwise",
    "orient_counterclockwise",
    "points_in_convex",
    "point_in_halfplanes",
    "points_in_polygon",
    "ray_circle_distance",
    "ray_convex_distance",
    "ray_polyline_distance",
    "signed_area",
    "star_hull_indices",
]


def signed_area(vertices: np.ndarray) -> float:
    """Shoelace area of a polygon.

    Args:
        vertices: ``(K, 2)`` vertices in metres.

    Returns:
        Area in m², positive for counter-clockwise order, negative for clockwise.
    """
    v = np.asarray(vertices, dtype=float)
    x, y = v[:, 0], v[:, 1]
    return 0.5 * float(np.dot(x, np.roll(y, -1)) - np.dot(y, np.roll(x, -1)))


def is_clockwise(vertices: np.ndarray) -> bool:
    """Whether the vertices run clockwise (negative signed area)."""
    return signed_area(vertices) < 0.0


def orient_clockwise(vertices: np.ndarray) -> np.ndarray:
    """Return the vertices in clockwise order (a reversed copy if they were counter-clockwise)."""
    v = np.asarray(vertices, dtype=float)
    return v[::-1].copy() if signed_area(v) > 0.0 else v.copy()


def orient_counterclockwise(vertices: np.ndarray) -> np.ndarray:
    """Return the vertices in counter-clockwise order (a reversed copy if they were clockwise)."""
    v = np.asarray(vertices, dtype=float)
    return v[::-1].copy() if signed_area(v) < 0.0 else v.copy()


def is_convex(vertices: np.ndarray, tol: float = 1e-9) -> bool:
    """Whether a polygon is convex and simple (one turn around its interior).

    Collinear consecutive vertices (turn within ``tol``) are allowed; repeated vertices are not.

    Args:
        vertices: ``(K, 2)`` vertices in metres, either orientation.
        tol: Tolerance on the edge cross products, m².

    Returns:
        True if every turn has the sign of the area and the turning angle sums to ±2π.
    """
    v = np.asarray(vertices, dtype=float)
    if v.ndim != 2 or v.shape[0] < 3 or v.shape[1] != 2:
        return False
    edges = np.roll(v, -1, axis=0) - v
    if np.any(np.hypot(edges[:, 0], edges[:, 1]) <= 0.0):
        return False
    nxt = np.roll(edges, -1, axis=0)
    cross = edges[:, 0] * nxt[:, 1] - edges[:, 1] * nxt[:, 0]
    sign = 1.0 if signed_area(v) > 0.0 else -1.0
    if np.any(sign * cross < -tol):
        return False
    turn = np.arctan2(cross, np.sum(edges * nxt, axis=1))
    return bool(abs(abs(turn.sum()) - 2.0 * math.pi) < 1e-6)


def halfplanes(vertices: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Half-plane form ``n_j · x <= c_j`` of a convex polygon.

    Args:
        vertices: ``(K, 2)`` convex polygon in metres, either orientation.

    Returns:
        ``(normals, offsets)``: ``(K, 2)`` outward unit normals and ``(K,)`` offsets in metres;
        row ``j`` belongs to the edge from vertex ``j`` to vertex ``j + 1``.

    Raises:
        ValueError: If an edge has zero length.
    """
    normals, offsets, ok = _halfplanes_kernel(np.ascontiguousarray(vertices, dtype=np.float64))
    if not ok:
        raise ValueError("halfplanes: polygon has a zero-length edge")
    return normals, offsets


@njit(cache=True)
def _halfplanes_kernel(v: np.ndarray) -> tuple[np.ndarray, np.ndarray, bool]:  # pragma: no cover - numba
    k = v.shape[0]
    area = 0.0
    for i in range(k):
        j = (i + 1) % k
        area += v[i, 0] * v[j, 1] - v[j, 0] * v[i, 1]
    sign = 1.0 if area > 0.0 else -1.0
    normals, offsets = np.empty((k, 2)), np.empty(k)
    ok = True
    for i in range(k):
        j = (i + 1) % k
        ex, ey = v[j, 0] - v[i, 0], v[j, 1] - v[i, 1]
        length = math.hypot(ex, ey)
        if length <= 0.0:
            ok = False
            length = 1.0
        normals[i, 0], normals[i, 1] = sign * ey / length, -sign * ex / length
        offsets[i] = normals[i, 0] * v[i, 0] + normals[i, 1] * v[i, 1]
    return normals, offsets, ok


def points_in_convex(
    points: np.ndarray, vertices: np.ndarray, tol: float = 0.0, strict: bool = False
) -> np.ndarray:
    """Containment test of points in a convex polygon.

    Args:
        points: ``(M, 2)`` points in metres (or one ``(2,)`` point).
        vertices: ``(K, 2)`` convex polygon, either orientation.
        tol: Distance tolerance in metres. Non-strict: inside if ``n·x <= c + tol`` for every
            edge. Strict: inside if ``n·x < c - tol`` for every edge.
        strict: Choose the strict test (the boundary is outside).

    Returns:
        ``(M,)`` boolean array (a 0-d array for one point).
    """
    normals, offsets = halfplanes(vertices)
    pts = np.asarray(points, dtype=float)
    slack = offsets - pts @ normals.T
    if strict:
        return np.all(slack > tol, axis=-1)
    return np.all(slack >= -tol, axis=-1)


def contains_point(vertices: np.ndarray, point: np.ndarray, tol: float = 0.0, strict: bool = False) -> bool:
    """Whether one point lies in a convex polygon (see :func:`points_in_convex`)."""
    return bool(points_in_convex(np.asarray(point, dtype=float), vertices, tol=tol, strict=strict))


def points_in_polygon(points: np.ndarray, vertices: np.ndarray) -> np.ndarray:
    """Even-odd containment test for any simple polygon (convex or not).

    Points exactly on the boundary may fall either way.

    Args:
        points: ``(M, 2)`` points in metres (or one ``(2,)`` point).
        vertices: ``(K, 2)`` polygon vertices, either orientation.

    Returns:
        ``(M,)`` boolean array (a 0-d array for one point).
    """
    pts = np.atleast_2d(np.asarray(points, dtype=float))
    a = np.asarray(vertices, dtype=float)
    b = np.roll(a, -1, axis=0)
    px, py = pts[:, 0:1], pts[:, 1:2]
    spans = (a[None, :, 1] > py) != (b[None, :, 1] > py)
    dy = np.where(spans, b[None, :, 1] - a[None, :, 1], 1.0)
    x_cross = a[None, :, 0] + (py - a[None, :, 1]) * (b[None, :, 0] - a[None, :, 0]) / dy
    inside = (np.count_nonzero(spans & (px < x_cross), axis=1) % 2) == 1
    return inside if np.ndim(points) > 1 else inside[0]


def point_in_halfplanes(
    point: np.ndarray, normals: np.ndarray, offsets: np.ndarray, tol: float = 0.0
) -> bool:
    """Whether ``normals @ point <= offsets + tol`` holds for every row (non-strict; jitted core).

    Args:
        point: ``(2,)`` point in metres.
        normals: ``(K, 2)`` outward unit normals (:func:`halfplanes`).
        offsets: ``(K,)`` offsets in metres.
        tol: Tolerance in metres.

    Returns:
        True if the point satisfies every half-plane.
    """
    return _point_in_halfplanes(_f64(point), _f64(normals), _f64(offsets), float(tol))


def _f64(array: np.ndarray) -> np.ndarray:
    return np.asarray(array, dtype=np.float64)


@njit(cache=True)
def _point_in_halfplanes(
    point: np.ndarray, normals: np.ndarray, offsets: np.ndarray, tol: float
) -> bool:  # pragma: no cover - numba
    for j in range(normals.shape[0]):
        if normals[j, 0] * point[0] + normals[j, 1] * point[1] > offsets[j] + tol:
            return False
    return True


def ray_convex_distance(
    origin: np.ndarray, direction: np.ndarray, normals: np.ndarray, offsets: np.ndarray
) -> float:
    """Exact distance from a point inside a convex polygon to its boundary along a ray (jitted core).

    Args:
        origin: ``(2,)`` start point in metres, inside the polygon.
        direction: ``(2,)`` unit direction.
        normals: ``(K, 2)`` outward unit normals (:func:`halfplanes`).
        offsets: ``(K,)`` offsets in metres.

    Returns:
        Distance in metres (``0`` if the origin is on or outside the boundary ahead; ``inf`` if
        no edge faces the ray, which cannot happen for a bounded polygon).
    """
    return _ray_convex(_f64(origin), _f64(direction), _f64(normals), _f64(offsets))


@njit(cache=True)
def _ray_convex(
    origin: np.ndarray, direction: np.ndarray, normals: np.ndarray, offsets: np.ndarray
) -> float:  # pragma: no cover - numba
    best = math.inf
    for j in range(normals.shape[0]):
        facing = normals[j, 0] * direction[0] + normals[j, 1] * direction[1]
        if facing > 1e-15:
            slack = offsets[j] - normals[j, 0] * origin[0] - normals[j, 1] * origin[1]
            best = min(best, slack / facing)
    return max(0.0, best)


def ray_polyline_distance(origin: np.ndarray, direction: np.ndarray, vertices: np.ndarray) -> float:
    """Distance along a ray to the first crossing of a closed polyline (any simple polygon).

    Used for the non-convex fallback polygon (every 6th beam's shrunk point).

    Args:
        origin: ``(2,)`` start point in metres.
        direction: ``(2,)`` unit direction.
        vertices: ``(K, 2)`` closed polyline (the last vertex joins the first).

    Returns:
        Smallest ``t >= 0`` with ``origin + t·direction`` on the polyline, or ``inf`` if the ray
        misses it. Edges parallel to the ray are ignored.
    """
    return _ray_polyline(_f64(origin), _f64(direction), _f64(vertices))


@njit(cache=True)
def _ray_polyline(
    origin: np.ndarray, direction: np.ndarray, vertices: np.ndarray
) -> float:  # pragma: no cover - numba
    k = vertices.shape[0]
    best = math.inf
    for i in range(k):
        j = (i + 1) % k
        ex, ey = vertices[j, 0] - vertices[i, 0], vertices[j, 1] - vertices[i, 1]
        wx, wy = vertices[i, 0] - origin[0], vertices[i, 1] - origin[1]
        den = direction[0] * ey - direction[1] * ex
        if abs(den) <= 1e-15:
            continue
        t = (wx * ey - wy * ex) / den
        s = (wx * direction[1] - wy * direction[0]) / den
        if t >= 0.0 and -1e-12 <= s <= 1.0 + 1e-12:
            best = min(best, t)
    return best


def ray_circle_distance(origin: np.ndarray, direction: np.ndarray, radius: float) -> float:
    """Distance from a point inside a circle centred at the frame origin to the circle.

    Args:
        origin: ``(2,)`` start point in metres.
        direction: ``(2,)`` unit direction.
        radius: Circle radius in metres.

    Returns:
        The positive root of ``|origin + t·direction| = radius``; ``0`` if the start point is on
        or outside the circle.
    """
    ox, oy, dx, dy = float(origin[0]), float(origin[1]), float(direction[0]), float(direction[1])
    return _ray_circle(ox, oy, dx, dy, float(radius))


@njit(cache=True)
def _ray_circle(ox: float, oy: float, dx: float, dy: float, radius: float) -> float:  # pragma: no cover
    """Numba core of :func:`ray_circle_distance` on floats (callable from other ``@njit`` code)."""
    b = ox * dx + oy * dy
    c = ox * ox + oy * oy - radius * radius
    if c >= 0.0:
        return 0.0
    return -b + math.sqrt(b * b - c)


@njit(cache=True)
def _lex_less(xs: np.ndarray, ys: np.ndarray, i: int, j: int) -> bool:  # pragma: no cover - numba
    return xs[i] < xs[j] or (xs[i] == xs[j] and ys[i] < ys[j])


@njit(cache=True)
def _cross3(xs: np.ndarray, ys: np.ndarray, o: int, a: int, b: int) -> float:  # pragma: no cover
    return (xs[a] - xs[o]) * (ys[b] - ys[o]) - (ys[a] - ys[o]) * (xs[b] - xs[o])


@njit(cache=True)
def convex_hull_indices(xs: np.ndarray, ys: np.ndarray) -> np.ndarray:  # pragma: no cover - numba
    """Convex hull by Andrew's monotone chain (numba; entry point for Python callers).

    Collinear and repeated points are dropped (strict hull).

    Args:
        xs: ``(n,)`` x coordinates.
        ys: ``(n,)`` y coordinates.

    Returns:
        Indices of the hull vertices, counter-clockwise, starting at the lexicographically
        smallest point; fewer than 3 indices for degenerate input.
    """
    return monotone_chain(xs, ys)


@njit(cache=True)
def monotone_chain(xs: np.ndarray, ys: np.ndarray) -> np.ndarray:  # pragma: no cover - numba
    """Kernel of :func:`convex_hull_indices`, to be called from other jitted code only.

    Jitted functions called both from Python and from other cached jitted functions can lose
    their boxing environment when loaded from numba's cache (``'descr' is NULL``), so every
    kernel has a separate Python entry point.
    """
    n = xs.shape[0]
    order = np.argsort(xs)
    for i in range(1, n):  # insertion pass: ties in x ordered by y (nearly sorted, O(n))
        cur = order[i]
        j = i - 1
        while j >= 0 and _lex_less(xs, ys, cur, order[j]):
            order[j + 1] = order[j]
            j -= 1
        order[j + 1] = cur
    hull = np.empty(2 * n + 1, dtype=np.int64)
    k = 0
    for i in range(n):
        p = order[i]
        while k >= 2 and _cross3(xs, ys, hull[k - 2], hull[k - 1], p) <= 0.0:
            k -= 1
        hull[k] = p
        k += 1
    lower = k + 1
    for i in range(n - 2, -1, -1):
        p = order[i]
        while k >= lower and _cross3(xs, ys, hull[k - 2], hull[k - 1], p) <= 0.0:
            k -= 1
        hull[k] = p
        k += 1
    if k <= 1:
        return hull[:k]
    return hull[: k - 1]


@njit(cache=True)
def star_hull_indices(xs: np.ndarray, ys: np.ndarray) -> np.ndarray:  # pragma: no cover - numba
    """Convex hull in O(n) of points sorted by strictly increasing polar angle (numba entry point).

    Graham's scan about the frame origin, started at the point farthest from it (always a hull
    vertex). The scan is only valid if the origin is strictly inside the hull; the result is
    therefore checked (strictly convex, origin strictly inside every edge) and an empty array is
    returned when the check fails, so that the caller can fall back to
    :func:`convex_hull_indices` or report the origin outside.

    Args:
        xs: ``(n,)`` x coordinates, polar angles strictly increasing over less than one turn.
        ys: ``(n,)`` y coordinates.

    Returns:
        Hull vertex indices, counter-clockwise, or an empty array.
    """
    return graham_scan(xs, ys)


@njit(cache=True)
def graham_scan(xs: np.ndarray, ys: np.ndarray) -> np.ndarray:  # pragma: no cover - numba
    """Kernel of :func:`star_hull_indices`, to be called from other jitted code only."""
    n = xs.shape[0]
    start, best = 0, -1.0
    for i in range(n):
        d = xs[i] * xs[i] + ys[i] * ys[i]
        if d > best:
            best, start = d, i
    hull = np.empty(n + 2, dtype=np.int64)
    k = 0
    p = start
    for _ in range(n + 1):  # indices wrap by a compare, not `%` (an integer division per point)
        while k >= 2 and _cross3(xs, ys, hull[k - 2], hull[k - 1], p) <= 0.0:
            k -= 1
        hull[k] = p
        k += 1
        p = p + 1 if p + 1 < n else 0
    k -= 1  # the start point was appended again to close the chain
    if k < 3:
        return hull[:0]
    hull[k + 1] = hull[1]  # hull[k] is hull[0] again: consecutive triples need no wrapping
    for i in range(k):
        a, b, c = hull[i], hull[i + 1], hull[i + 2]
        if _cross3(xs, ys, a, b, c) <= 0.0 or xs[a] * ys[b] - ys[a] * xs[b] <= 0.0:
            return hull[:0]
    return hull[:k]
