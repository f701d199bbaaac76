"""Random 2-D scenes and a brute-force ray caster for the region, action and MPC tests.

The robot sits at the origin; scenes mix rotated rectangular rooms, circles (pedestrians),
triangles/quadrilaterals and open space. Obstacles may come closer than the inflation (and
rarely touch the robot) so that the failure path is exercised too.
"""

from __future__ import annotations

import numpy as np

BEAMS = 360
ANGLES = np.arange(BEAMS) * (2.0 * np.pi / BEAMS)


def cast(
    angles: np.ndarray, segments: np.ndarray, circles: np.ndarray, max_range: float = 10.0
) -> np.ndarray:
    """Ranges from the origin along ``angles`` to segments ``(S, 4)`` and circles ``(C, 3)``."""
    d = np.stack([np.cos(angles), np.sin(angles)], axis=1)
    best = np.full(angles.shape, max_range)
    if segments.size:
        e = segments[:, 2:] - segments[:, :2]
        w = segments[:, :2]
        den = d[:, None, 0] * e[None, :, 1] - d[:, None, 1] * e[None, :, 0]
        ok = np.abs(den) > 1e-12
        den = np.where(ok, den, 1.0)
        t = (w[None, :, 0] * e[None, :, 1] - w[None, :, 1] * e[None, :, 0]) / den
        u = (w[None, :, 0] * d[:, None, 1] - w[None, :, 1] * d[:, None, 0]) / den
        t = np.where(ok & (t >= 0) & (u >= 0) & (u <= 1), t, np.inf)
        best = np.minimum(best, t.min(axis=1))
    if circles.size:
        cd = d @ circles[:, :2].T
        disc = cd**2 - (np.sum(circles[:, :2] ** 2, axis=1) - circles[:, 2] ** 2)[None, :]
        root = np.sqrt(np.maximum(disc, 0.0))
        t = np.where((disc >= 0) & (cd - root >= 0), cd - root, np.inf)
        best = np.minimum(best, t.min(axis=1))
    return np.clip(best, 0.0, max_range)


def _room(rng: np.random.Generator) -> np.ndarray:
    w, h = rng.uniform(1.0, 20.0, size=2)
    cx, cy = rng.uniform(-w / 2 + 0.2, w / 2 - 0.2), rng.uniform(-h / 2 + 0.2, h / 2 - 0.2)
    corners = np.array([[-w, -h], [w, -h], [w, h], [-w, h]]) / 2.0 - [cx, cy]
    rot = rng.uniform(0, 2 * np.pi)
    c, s = np.cos(rot), np.sin(rot)
    corners = corners @ np.array([[c, s], [-s, c]])
    return np.concatenate([corners, np.roll(corners, -1, axis=0)], axis=1)


def _polygons(rng: np.random.Generator, count: int) -> np.ndarray:
    segs = []
    for _ in range(count):
        k = rng.integers(3, 5)
        radius = rng.uniform(0.2, 1.5)
        centre = rng.uniform(-9, 9, size=2)
        if np.linalg.norm(centre) < radius + 0.3:
            continue
        ang = np.sort(rng.uniform(0, 2 * np.pi, size=k))
        pts = centre + radius * np.stack([np.cos(ang), np.sin(ang)], axis=1)
        segs.append(np.concatenate([pts, np.roll(pts, -1, axis=0)], axis=1))
    return np.concatenate(segs) if segs else np.zeros((0, 4))


def _circles(rng: np.random.Generator, count: int) -> np.ndarray:
    centres = rng.uniform(-9, 9, size=(count, 2))
    radii = rng.uniform(0.1, 1.0, size=count)
    gap = rng.uniform(-0.05, 1.0, size=count)  # occasionally inside the inflation, rarely touching
    keep = np.linalg.norm(centres, axis=1) > radii + np.maximum(gap, 0.005)
    return np.concatenate([centres[keep], radii[keep, None]], axis=1)


def random_scan(rng: np.random.Generator, noise: bool = True) -> np.ndarray:
    """One 360-beam scan (metres) of a random scene around the origin."""
    segments = [_polygons(rng, int(rng.integers(0, 6)))]
    if rng.random() < 0.7:
        segments.append(_room(rng))
    circles = _circles(rng, int(rng.integers(0, 31)))
    ranges = cast(ANGLES, np.concatenate(segments), circles)
    if noise and rng.random() < 0.7:
        ranges = np.clip(ranges + rng.normal(0.0, 0.05, size=ranges.shape), 0.0, 10.0)
    return ranges


def wall_ahead(distance: float) -> np.ndarray:
    """Noise-free ranges of a straight wall ``distance`` metres ahead along +x (other beams at 8 m)."""
    cos = np.cos(ANGLES)
    ranges = np.full(ANGLES.size, 8.0)
    ahead = cos > 1e-6
    ranges[ahead] = np.minimum(8.0, distance / cos[ahead])
    return ranges
