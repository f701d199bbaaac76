"""Tests for the polygon helpers."""

from __future__ import annotations

import math
import os
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
import shapely
from hypothesis import given, settings
from hypothesis import strategies as st
from scipy.spatial import ConvexHull

from mjnav.geometry.polygon import (
    contains_point,
    convex_hull_indices,
    halfplanes,
    is_clockwise,
    is_convex,
    orient_clockwise,
    orient_counterclockwise,
    points_in_convex,
    points_in_polygon,
    ray_circle_distance,
    ray_convex_distance,
    ray_polyline_distance,
    signed_area,
    star_hull_indices,
)

SQUARE = np.array([[1.0, -1.0], [1.0, 1.0], [-1.0, 1.0], [-1.0, -1.0]])  # CCW
STAR = np.array(
    [
        [np.cos(t) * r, np.sin(t) * r]
        for t, r in zip(np.linspace(0, 2 * np.pi, 10, endpoint=False), [2, 0.7] * 5, strict=True)
    ]
)


def _random_convex(rng: np.random.Generator) -> np.ndarray:
    """A random convex polygon (CCW) that strictly contains the origin."""
    while True:
        pts = rng.normal(size=(rng.integers(3, 30), 2)) * rng.uniform(0.2, 5.0)
        hull = pts[ConvexHull(pts).vertices]
        if shapely.Polygon(hull).buffer(-1e-3).contains(shapely.Point(0, 0)):
            return hull


def test_signed_area_and_orientation():
    """The square has area +4 counter-clockwise and -4 clockwise; orient_* flip as needed."""
    assert signed_area(SQUARE) == pytest.approx(4.0)
    cw = orient_clockwise(SQUARE)
    assert signed_area(cw) == pytest.approx(-4.0) and is_clockwise(cw)
    assert np.allclose(orient_counterclockwise(cw), SQUARE)
    assert np.allclose(orient_clockwise(cw), cw)


def test_is_convex_accepts_convex_and_rejects_star_and_bowtie():
    """Convex polygons (either orientation, collinear points allowed) pass; star and bowtie fail."""
    assert is_convex(SQUARE) and is_convex(SQUARE[::-1])
    assert is_convex(np.array([[0, 0], [1, 0], [2, 0], [2, 2], [0, 2]], dtype=float))
    assert not is_convex(STAR)
    assert not is_convex(np.array([[0, 0], [1, 1], [1, 0], [0, 1]], dtype=float))
    assert not is_convex(np.array([[0, 0], [1, 0], [1, 0], [0, 1]], dtype=float))
    assert not is_convex(np.array([[0, 0], [1, 0]], dtype=float))


def test_halfplanes_of_square_both_orientations():
    """Normals are outward unit vectors, offsets the distances to the edges."""
    for poly in (SQUARE, SQUARE[::-1]):
        normals, offsets = halfplanes(poly)
        assert np.allclose(np.linalg.norm(normals, axis=1), 1.0)
        assert np.allclose(offsets, 1.0)
        assert np.allclose(np.sort(normals @ [1.0, 0.0]), [-1, 0, 0, 1])


def test_halfplanes_rejects_zero_length_edges():
    """A repeated vertex raises ValueError."""
    with pytest.raises(ValueError, match="zero-length"):
        halfplanes(np.array([[0, 0], [1, 0], [1, 0], [0, 1]], dtype=float))


def test_points_in_convex_strict_and_tolerant():
    """Boundary points are inside with tolerance, outside with the strict test."""
    pts = np.array([[0.0, 0.0], [1.0, 0.0], [1.0 + 1e-7, 0.0], [2.0, 0.0]])
    assert points_in_convex(pts, SQUARE).tolist() == [True, True, False, False]
    assert points_in_convex(pts, SQUARE, tol=1e-6).tolist() == [True, True, True, False]
    assert points_in_convex(pts, SQUARE, strict=True).tolist() == [True, False, False, False]
    assert contains_point(SQUARE, [0.5, 0.5], strict=True)


def test_points_in_polygon_matches_shapely_on_a_star():
    """Even-odd containment agrees with shapely on a non-convex star polygon."""
    rng = np.random.default_rng(0)
    pts = rng.uniform(-2.5, 2.5, size=(2000, 2))
    expected = shapely.contains_xy(shapely.Polygon(STAR), pts[:, 0], pts[:, 1])
    assert np.array_equal(points_in_polygon(pts, STAR), expected)
    assert bool(points_in_polygon(np.zeros(2), STAR))


def test_ray_convex_distance_matches_shapely():
    """Exact ray/convex distance equals shapely's intersection for random polygons and starts."""
    rng = np.random.default_rng(1)
    for _ in range(300):
        poly = _random_convex(rng)
        normals, offsets = halfplanes(poly)
        start = np.zeros(2)
        angle = rng.uniform(0, 2 * np.pi)
        d = np.array([math.cos(angle), math.sin(angle)])
        dist = ray_convex_distance(start, d, normals, offsets)
        hit = shapely.LineString([start, start + 100 * d]).intersection(shapely.Polygon(poly).exterior)
        assert dist == pytest.approx(shapely.Point(start).distance(hit), abs=1e-9)
        assert points_in_convex(start + dist * d, poly, tol=1e-9)


@settings(max_examples=200, deadline=None)
@given(st.floats(0, 2 * np.pi), st.floats(-0.9, 0.9), st.floats(-0.9, 0.9))
def test_ray_convex_distance_from_interior_points(angle, x, y):
    """From any interior point of the square the ray ends exactly on the boundary."""
    normals, offsets = halfplanes(SQUARE)
    d = np.array([math.cos(angle), math.sin(angle)])
    end = np.array([x, y]) + ray_convex_distance(np.array([x, y]), d, normals, offsets) * d
    assert np.max(np.abs(end)) == pytest.approx(1.0, abs=1e-12)


def test_ray_polyline_distance_on_star():
    """Rays from the centre of the star hit its boundary at the shapely distance."""
    for angle in np.linspace(0, 2 * np.pi, 37):
        d = np.array([math.cos(angle), math.sin(angle)])
        dist = ray_polyline_distance(np.zeros(2), d, STAR)
        hit = shapely.LineString([[0, 0], 10 * d]).intersection(shapely.Polygon(STAR).exterior)
        assert dist == pytest.approx(shapely.Point(0, 0).distance(hit), abs=1e-9)
    assert math.isinf(ray_polyline_distance(np.array([5.0, 5.0]), np.array([1.0, 0.0]), STAR))


def test_ray_circle_distance():
    """From the centre the distance is the radius; from outside it is 0."""
    assert ray_circle_distance(np.zeros(2), np.array([0.0, 1.0]), 2.0) == pytest.approx(2.0)
    assert ray_circle_distance(np.array([1.0, 0.0]), np.array([1.0, 0.0]), 2.0) == pytest.approx(1.0)
    assert ray_circle_distance(np.array([1.0, 0.0]), np.array([-1.0, 0.0]), 2.0) == pytest.approx(3.0)
    assert ray_circle_distance(np.array([3.0, 0.0]), np.array([1.0, 0.0]), 2.0) == 0.0


def test_convex_hull_indices_matches_qhull_with_duplicates_and_collinear_points():
    """The monotone chain gives qhull's vertex set, CCW, ignoring duplicates and collinear points."""
    rng = np.random.default_rng(2)
    for _ in range(200):
        pts = rng.integers(-12, 13, size=(rng.integers(3, 80), 2)).astype(float)  # exact ties, collinear
        pts = np.concatenate([pts, pts[:5]])
        idx = convex_hull_indices(pts[:, 0].copy(), pts[:, 1].copy())
        try:
            expected = ConvexHull(pts).vertices
        except Exception:  # noqa: BLE001 - qhull rejects degenerate (collinear) sets
            assert len(idx) < 3 or abs(signed_area(pts[idx])) < 1e-12
            continue
        assert sorted(map(tuple, pts[idx])) == sorted(map(tuple, pts[expected]))
        assert signed_area(pts[idx]) > 0


def test_star_hull_matches_monotone_chain_or_reports_origin_outside():
    """The O(n) angular hull equals the monotone chain if the origin is inside, else is empty."""
    rng = np.random.default_rng(3)
    for _ in range(300):
        n = int(rng.integers(3, 200))
        ang = np.sort(rng.uniform(0, 2 * np.pi, size=n))
        ang = ang[np.concatenate([[True], np.diff(ang) > 0])]
        r = rng.uniform(0.1, 5.0, size=ang.size)
        if rng.random() < 0.3:
            ang = ang[ang < rng.uniform(0.5, 2 * np.pi)]
            r = r[: ang.size]
        x, y = r * np.cos(ang), r * np.sin(ang)
        star = star_hull_indices(x, y)
        mono = convex_hull_indices(x.copy(), y.copy())
        inside = len(mono) >= 3 and shapely.Polygon(np.stack([x, y], 1)[mono]).contains(shapely.Point(0, 0))
        if inside:
            assert sorted(star.tolist()) == sorted(mono.tolist())
        elif len(star):
            assert shapely.Polygon(np.stack([x, y], 1)[star]).contains(shapely.Point(0, 0))


def test_public_kernels_work_after_cached_jitted_callers():
    """Public jitted entry points still box their results after cached callers loaded the kernels."""
    code = (
        "import numpy as np\n"
        "from mjnav.geometry.region import compute_region\n"
        "from mjnav.control.mpc import Mpc\n"
        "from mjnav.control.dynamics import rollout\n"
        "from mjnav.geometry.polygon import convex_hull_indices, star_hull_indices\n"
        "a = np.arange(360) * np.pi / 180\n"
        "compute_region(np.full(360, 5.0) + np.sin(a), a)\n"
        "square = np.array([[1.0, 1], [1, -1], [-1, -1], [-1, 1]])\n"
        "Mpc().solve(np.zeros((3, 2)), np.ones(2), np.ones(2), square)\n"
        "assert len(convex_hull_indices(np.cos(a), np.sin(a))) == 360\n"
        "assert len(star_hull_indices(np.cos(a), np.sin(a))) == 360\n"
        "assert rollout(np.zeros((3, 2)), np.ones((3, 2)), 0.1).shape == (3, 3, 2)\n"
    )
    root = Path(__file__).resolve().parents[2]
    env = {**os.environ, "PYTHONPATH": str(root) + os.pathsep + os.environ.get("PYTHONPATH", "")}
    for _ in range(2):  # the second run loads everything from the numba cache
        subprocess.run([sys.executable, "-c", code], check=True, cwd=root, env=env, timeout=300)
