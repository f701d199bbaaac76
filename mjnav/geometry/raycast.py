"""Exact 2-D ray casting for the analytic LiDAR (spec §2).

Rays are cast in the plane against line segments (walls, polygon edges) and circles
(pedestrian cylinders). Distances are in metres, angles in radians.

Convention for a ray that starts inside a geometry, matched to MuJoCo 3's ``mj_ray``
(which the ``mujoco`` LiDAR backend uses): the reading is the distance to the first
surface crossing at ``t >= 0``. Inside a circle that is the exit point; inside a polygon
it is the exit edge; a ray starting exactly on a surface reads 0. Segments parallel to a
ray (including degenerate zero-length ones) are never hit.
"""

from __future__ import annotations

import math
from collections.abc import Sequence

import numpy as np
from numba import njit

__all__ = [
    "add_noise",
    "beam_angles",
    "beam_trig",
    "cast_rays",
    "cast_rays_kernel",
    "cast_uniform_rays_kernel",
    "polygon_segments",
    "wall_segments",
]


def beam_angles(beams: int) -> np.ndarray:
    """Beam directions: beam 0 along +x, counter-clockwise, evenly over 360°.

    Args:
        beams: Number of beams (360 gives 1° spacing).

    Returns:
        (beams,) float64 angles in radians, in [0, 2π).
    """
    return np.arange(beams, dtype=np.float64) * (2.0 * np.pi / beams)


_TRIG_CACHE: dict[bytes, tuple[np.ndarray, np.ndarray, bool]] = {}


def beam_trig(angles: np.ndarray) -> tuple[np.ndarray, np.ndarray, bool]:
    """Cosines, sines and "strictly increasing over < 1 turn" flag of the beam angles (radians).

    Cached by value (the beam layout rarely changes), so every region finder and analytic LiDAR of
    a process (one of each per environment) reads one set of tables; callers never write them.
    Ordered angles allow the region's O(n) hull.
    """
    key = angles.tobytes()
    hit = _TRIG_CACHE.get(key)
    if hit is None:
        if len(_TRIG_CACHE) >= 8:
            _TRIG_CACHE.clear()
        ordered = bool(np.all(np.diff(angles) > 0.0) and angles[-1] - angles[0] < 2.0 * math.pi)
        hit = (np.cos(angles), np.sin(angles), ordered)
        _TRIG_CACHE[key] = hit
    return hit


def wall_segments(size: tuple[float, float] | Sequence[float]) -> np.ndarray:
    """Inner faces of the arena walls around an interior centred on the origin.

    Args:
        size: Interior extent (x, y), metres.

    Returns:
        (4, 4) float64 segments ``[x0, y0, x1, y1]``, counter-clockwise: bottom, right,
        top, left.
    """
    hx, hy = 0.5 * float(size[0]), 0.5 * float(size[1])
    corners = np.array([[-hx, -hy], [hx, -hy], [hx, hy], [-hx, hy]], dtype=np.float64)
    return np.hstack([corners, np.roll(corners, -1, axis=0)])


def polygon_segments(polygons: Sequence[np.ndarray]) -> np.ndarray:
    """Closed-polygon edges as segments.

    Args:
        polygons: Polygons, each (n, 2) vertices in metres (n >= 2; the last vertex
            connects back to the first).

    Returns:
        (sum n, 4) float64 segments ``[x0, y0, x1, y1]``; (0, 4) for no polygons.
    """
    parts = [np.hstack([p, np.roll(p, -1, axis=0)]) for p in map(np.asarray, polygons)]
    if not parts:
        return np.zeros((0, 4), dtype=np.float64)
    return np.ascontiguousarray(np.vstack(parts), dtype=np.float64)


@njit(cache=True, fastmath=False)
def _hit_segments(
    ox: float, oy: float, dx: np.ndarray, dy: np.ndarray, segments: np.ndarray, best: np.ndarray
) -> None:
    """Lower ``best[b]`` to each beam's first hit on the segments (beams inner, SIMD-friendly)."""
    for s in range(segments.shape[0]):
        wx, wy = segments[s, 0] - ox, segments[s, 1] - oy
        ex, ey = segments[s, 2] - segments[s, 0], segments[s, 3] - segments[s, 1]
        w_e = wx * ey - wy * ex
        for b in range(dx.shape[0]):
            denom = dx[b] * ey - dy[b] * ex
            if denom != 0.0:
                t = w_e / denom
                u = (wx * dy[b] - wy * dx[b]) / denom
                if t >= 0.0 and u >= 0.0 and u <= 1.0 and t < best[b]:
                    best[b] = t


@njit(cache=True, fastmath=False)
def _hit_circles(
    ox: float, oy: float, dx: np.ndarray, dy: np.ndarray, circles: np.ndarray, best: np.ndarray
) -> None:
    """Lower ``best[b]`` to each beam's first surface crossing of the circles."""
    for c in range(circles.shape[0]):
        fx, fy = ox - circles[c, 0], oy - circles[c, 1]
        cc = fx * fx + fy * fy - circles[c, 2] * circles[c, 2]
        _hit_circle_beams(fx, fy, cc, dx, dy, best, 0, dx.shape[0])


@njit(cache=True, fastmath=False)
def _hit_circle_beams(
    fx: float, fy: float, cc: float, dx: np.ndarray, dy: np.ndarray, best: np.ndarray, lo: int, hi: int
) -> None:
    """Lower ``best[b]``, ``lo <= b < hi``, to the beam's first crossing of one circle.

    ``(fx, fy)`` is the origin minus the centre and ``cc = |f|² - r²``.
    """
    for b in range(lo, hi):
        half_b = fx * dx[b] + fy * dy[b]
        disc = half_b * half_b - cc
        if disc >= 0.0:
            root = np.sqrt(disc)
            t = -half_b - root
            if t < 0.0:
                t = -half_b + root  # origin inside: exit point (mj_ray convention)
            if t >= 0.0 and t < best[b]:
                best[b] = t


@njit(cache=True, fastmath=False)
def cast_rays_kernel(
    ox: float, oy: float, cos_a: np.ndarray, sin_a: np.ndarray, segments: np.ndarray,
    circles: np.ndarray, max_range: float,
) -> np.ndarray:
    """Numba core of :func:`cast_rays` on unit directions ``(cos_a, sin_a)``.

    Callable from other ``@njit`` code; arrays must be contiguous float64.
    """
    best = np.full(cos_a.shape[0], max_range)
    _hit_segments(ox, oy, cos_a, sin_a, segments, best)
    _hit_circles(ox, oy, cos_a, sin_a, circles, best)
    return best


@njit(cache=True, fastmath=False)
def _hit_circles_uniform(
    ox: float, oy: float, dx: np.ndarray, dy: np.ndarray, circles: np.ndarray, best: np.ndarray
) -> None:
    """:func:`_hit_circles` for ``beam_angles(B)`` directions, testing only the beams that can hit.

    A circle that does not contain the origin subtends ``±asin(r/d)`` around its centre
    direction; beams more than that plus one beam spacing away have a negative discriminant
    (by a margin far above rounding), so skipping them leaves every reading bit-identical.
    """
    n = dx.shape[0]
    spacing = 2.0 * math.pi / n
    for c in range(circles.shape[0]):
        fx, fy = ox - circles[c, 0], oy - circles[c, 1]
        cc = fx * fx + fy * fy - circles[c, 2] * circles[c, 2]
        if not cc > 0.0:  # origin inside or on the circle (or NaN): every beam
            _hit_circle_beams(fx, fy, cc, dx, dy, best, 0, n)
            continue
        dist = math.sqrt(fx * fx + fy * fy)  # origin outside: the beams of the angular shadow
        half = math.asin(min(circles[c, 2] / dist, 1.0))
        centre = math.atan2(-fy, -fx)
        first = math.floor((centre - half) / spacing) - 1  # one beam of margin each side
        last = math.ceil((centre + half) / spacing) + 1
        start = first % n
        stop = start + min(last - first + 1, n)
        _hit_circle_beams(fx, fy, cc, dx, dy, best, start, min(stop, n))
        if stop > n:  # the shadow wraps past beam B-1 to beam 0
            _hit_circle_beams(fx, fy, cc, dx, dy, best, 0, stop - n)


@njit(cache=True, fastmath=False)
def cast_uniform_rays_kernel(
    ox: float, oy: float, cos_a: np.ndarray, sin_a: np.ndarray, segments: np.ndarray,
    circles: np.ndarray, max_range: float,
) -> np.ndarray:
    """:func:`cast_rays_kernel` for the directions of ``beam_angles(B)`` only (same readings).

    Circles are tested only against the beams in their angular shadow, which is what makes a
    crowd cheap to scan.
    """
    best = np.full(cos_a.shape[0], max_range)
    _hit_segments(ox, oy, cos_a, sin_a, segments, best)
    _hit_circles_uniform(ox, oy, cos_a, sin_a, circles, best)
    return best


def _as_rows(array: np.ndarray | None, width: int, name: str) -> np.ndarray:
    if array is None:
        return np.zeros((0, width), dtype=np.float64)
    out = np.ascontiguousarray(array, dtype=np.float64)
    if out.ndim != 2 or out.shape[1] != width:
        raise ValueError(f"{name}: expected shape (N, {width}), got {out.shape}")
    return out


def cast_rays(
    origin: np.ndarray,
    angles: np.ndarray,
    segments: np.ndarray | None,
    circles: np.ndarray | None,
    max_range: float,
) -> np.ndarray:
    """Distance along each ray to the first hit, exact in 2-D.

    Args:
        origin: (2,) ray origin, metres.
        angles: (B,) ray directions, radians (0 = +x, counter-clockwise).
        segments: (S, 4) segments ``[x0, y0, x1, y1]`` in metres, or None.
        circles: (C, 3) circles ``[x, y, r]`` in metres, or None.
        max_range: Range, metres; rays without a hit within it read ``max_range``.

    Returns:
        (B,) float64 distances in [0, max_range], metres. A ray starting inside a circle
        or polygon reads the distance to its exit (MuJoCo ``mj_ray`` convention).
    """
    angles = np.asarray(angles, dtype=np.float64)
    return cast_rays_kernel(
        float(origin[0]),
        float(origin[1]),
        np.cos(angles),
        np.sin(angles),
        _as_rows(segments, 4, "segments"),
        _as_rows(circles, 3, "circles"),
        float(max_range),
    )


def add_noise(
    ranges: np.ndarray, std: float, max_range: float, rng: np.random.Generator
) -> np.ndarray:
    """Add Gaussian range noise and clip to the sensor's range.

    One normal draw per beam is always taken (also for ``std == 0``), so the random
    stream does not depend on the noise level.

    Args:
        ranges: (B,) clean ranges, metres.
        std: Noise standard deviation, metres.
        max_range: Upper clip, metres (lower clip is 0).
        rng: Random generator.

    Returns:
        (B,) float64 noisy ranges in [0, max_range], metres (a new array).
    """
    noisy = rng.normal(0.0, std, size=np.shape(ranges))
    if noisy.ndim == 1 and np.shape(ranges) == noisy.shape:
        _add_clip(noisy, np.asarray(ranges, dtype=np.float64), float(max_range))  # one pass, no ufunc dispatch
        return noisy
    noisy += ranges
    np.maximum(noisy, 0.0, out=noisy)
    return np.minimum(noisy, max_range, out=noisy)


@njit(cache=True)
def _add_clip(noisy: np.ndarray, ranges: np.ndarray, max_range: float) -> None:  # pragma: no cover - numba
    """``noisy ← min(max(noisy + ranges, 0), max_range)`` in place (as the three ufuncs, one pass)."""
    for i in range(noisy.shape[0]):
        noisy[i] = min(max(noisy[i] + ranges[i], 0.0), max_range)
