"""Tests for the GALAXY convex region (spec §3)."""

from __future__ import annotations

import math

import numpy as np
import pytest
import shapely
from hypothesis import given, settings
from hypothesis import strategies as st
from scipy.spatial import ConvexHull

from mjnav.geometry.polygon import is_clockwise, is_convex
from mjnav.geometry.region import Region, RegionConfig, RegionFinder, compute_region
from tests.geometry.scans import ANGLES, cast, random_scan, wall_ahead

CFG = RegionConfig()


def _shrunk_points(ranges: np.ndarray, angles: np.ndarray = ANGLES) -> np.ndarray:
    s = np.maximum(np.clip(ranges, 0, CFG.max_range) - CFG.inflation, 0.0)
    return s[:, None] * np.stack([np.cos(angles), np.sin(angles)], axis=1)


def _check_invariants(region: Region, ranges: np.ndarray) -> None:
    """Convex, clockwise, origin strictly inside, no shrunk point inside, boundary on the polygon."""
    v = region.vertices
    assert 3 <= v.shape[0] <= CFG.num_points
    assert is_convex(v) and is_clockwise(v)
    poly = shapely.Polygon(v)
    assert poly.is_valid and abs(poly.convex_hull.area - poly.area) < 1e-9
    assert poly.contains(shapely.Point(0.0, 0.0)) and poly.exterior.distance(shapely.Point(0.0, 0.0)) > 1e-9
    pts = _shrunk_points(ranges)
    assert not shapely.contains_xy(poly.buffer(-1e-5), pts[:, 0], pts[:, 1]).any()
    b = region.boundary
    assert b.shape == (CFG.num_points, 2)
    assert np.all(np.diff(b[:, 1]) > 0) and 0.0 <= b[0, 1] and b[-1, 1] < 2 * math.pi
    assert np.allclose(region.boundary_xy, b[:, :1] * np.stack([np.cos(b[:, 1]), np.sin(b[:, 1])], axis=1))
    dist = shapely.distance(poly.exterior, shapely.points(region.boundary_xy))
    assert np.max(dist) < 1e-9
    for vert in v:  # every vertex is emitted as a boundary point
        assert np.min(np.linalg.norm(region.boundary_xy - vert, axis=1)) < 1e-12


def _reference_polygon(ranges: np.ndarray) -> np.ndarray | None:
    """Independent GALAXY: qhull hulls and a brute-force half-plane intersection (CCW vertices)."""
    p = _shrunk_points(ranges)
    norm = np.linalg.norm(p, axis=1)
    if np.any(norm < 1e-6):
        return None
    star = p[ConvexHull(p * (2 * CFG.flip_radius / norm - 1)[:, None]).vertices]
    hull = ConvexHull(star).vertices
    normals, offsets = [], []
    for e, a in enumerate(hull):
        b = hull[(e + 1) % len(hull)]
        edge = star[b] - star[a]
        n = np.array([edge[1], -edge[0]]) / np.linalg.norm(edge)
        span = [(a + i) % len(star) for i in range((b - a) % len(star))]
        normals.append(n)
        offsets.append(min(star[span] @ n) + CFG.push)
    normals, offsets = np.array(normals), np.array(offsets)
    if np.any(offsets <= 0):
        return None
    i, j = np.triu_indices(len(normals), 1)
    det = normals[i, 0] * normals[j, 1] - normals[i, 1] * normals[j, 0]
    ok = np.abs(det) > 1e-12
    i, j, det = i[ok], j[ok], det[ok]
    x = (offsets[i] * normals[j, 1] - offsets[j] * normals[i, 1]) / det
    y = (normals[i, 0] * offsets[j] - normals[j, 0] * offsets[i]) / det
    pts = np.stack([x, y], axis=1)
    pts = pts[np.all(pts @ normals.T <= offsets + 1e-9, axis=1)]
    return pts[ConvexHull(pts).vertices]


def test_config_rejects_bad_values_naming_the_field():
    """Invalid config values raise ValueError whose message names the field."""
    for field, value in [("inflation", -0.1), ("flip_radius", 5.0), ("num_points", 2), ("max_vertices", 1)]:
        with pytest.raises(ValueError, match=field):
            RegionConfig(**{field: value})


def test_all_beams_at_max_range_give_a_near_circle():
    """An empty scan yields a thinned polygon inscribed in the shrunk max-range circle."""
    ranges = np.full(360, 10.0)
    region = compute_region(ranges, ANGLES)
    assert region.success and region.status == "ok"
    _check_invariants(region, ranges)
    radius = np.linalg.norm(region.vertices, axis=1)
    assert np.allclose(radius, 10.0 - CFG.inflation, atol=1e-5)


def test_all_beams_at_zero_fail_with_the_fallback():
    """A zero scan fails; the boundary is every 6th beam's (zero) shrunk point, vertices empty."""
    region = compute_region(np.zeros(360), ANGLES)
    assert not region.success and region.status == "touching"
    assert region.vertices.shape == (0, 2) and region.constraint_polygon is None
    assert np.allclose(region.boundary[:, 0], 0.0)
    assert np.allclose(region.boundary[:, 1], ANGLES[::6])


def test_obstacle_touching_the_robot_fails_and_falls_back_to_every_sixth_beam():
    """A beam within the inflation (shrunk range 0) fails; fallback radii are beams 0, 6, 12, ..."""
    ranges = np.full(360, 5.0) + np.arange(360) * 0.01
    ranges[100] = 0.2
    region = compute_region(ranges, ANGLES)
    assert not region.success
    assert np.allclose(region.boundary[:, 0], ranges[::6] - CFG.inflation)
    assert np.allclose(region.boundary_xy, _shrunk_points(ranges)[::6])


def test_single_beam_hit_is_excluded():
    """One close beam among max-range beams is cut off by the region, which stays large."""
    ranges = np.full(360, 10.0)
    ranges[45] = 1.0
    region = compute_region(ranges, ANGLES)
    assert region.success
    _check_invariants(region, ranges)
    point = _shrunk_points(ranges)[45]
    assert np.max(region.normals @ point - region.offsets) > -1e-5


def test_collinear_wall_points_give_one_edge():
    """Beams hitting a straight wall (collinear points) produce an edge on the shrunk wall."""
    wall = np.array([[-20.0, 2.0, 20.0, 2.0]])
    ranges = cast(ANGLES, wall, np.zeros((0, 3)))
    region = compute_region(ranges, ANGLES)
    assert region.success
    _check_invariants(region, ranges)
    top = region.vertices[:, 1].max()
    assert top <= 2.0 - CFG.inflation + 1e-5
    assert np.sum(np.abs(region.vertices[:, 1] - top) < 1e-6) >= 2


def test_duplicate_and_unordered_beams_match_the_ordered_scan():
    """Shuffled and duplicated beams (general hull path) give the same polygon as the ordered scan."""
    rng = np.random.default_rng(3)
    for _ in range(20):
        ranges = random_scan(rng)
        ordered = compute_region(ranges, ANGLES)
        perm = rng.permutation(720) % 360
        shuffled = compute_region(ranges[perm], ANGLES[perm])
        assert ordered.success == shuffled.success
        if ordered.success:
            assert np.allclose(ordered.vertices, shuffled.vertices, atol=1e-9)
            assert np.allclose(ordered.boundary, shuffled.boundary, atol=1e-9)


def test_non_finite_ranges_raise_naming_the_beams():
    """NaN or inf ranges raise ValueError listing the beam indices."""
    ranges = np.full(360, 5.0)
    ranges[[7, 300]] = [np.nan, np.inf]
    with pytest.raises(ValueError, match=r"\[7, 300\]"):
        compute_region(ranges, ANGLES)


def test_region_finder_equals_compute_region():
    """A RegionFinder for the beam layout gives compute_region's regions, failures included."""
    rng = np.random.default_rng(12)
    cfg = RegionConfig(inflation=0.4)
    find = RegionFinder(ANGLES, cfg)
    statuses = set()
    for k in range(80):
        ranges = random_scan(rng)
        if k % 4 == 0:
            ranges[rng.integers(0, 360)] = 0.1
        a, b = find(ranges), compute_region(ranges, ANGLES, cfg)
        for name in ("vertices", "normals", "offsets", "boundary", "boundary_xy"):
            np.testing.assert_array_equal(getattr(a, name), getattr(b, name))
        assert (a.success, a.status) == (b.success, b.status)
        statuses.add(a.status)
    assert "ok" in statuses and len(statuses) > 1


def test_region_finder_rejects_bad_scans():
    """Non-finite ranges raise naming the beams; a scan of another length or bad angles raise too."""
    find = RegionFinder(ANGLES)
    ranges = np.full(360, 5.0)
    ranges[[7, 300]] = [np.nan, np.inf]
    with pytest.raises(ValueError, match=r"\[7, 300\]"):
        find(ranges)
    with pytest.raises(ValueError, match="beams"):
        find(np.full(359, 5.0))
    with pytest.raises(ValueError, match="angles"):
        RegionFinder(np.where(ANGLES > 1.0, np.nan, ANGLES))


def test_out_of_range_readings_are_clipped():
    """Ranges above max_range or below 0 are clipped into [0, max_range]."""
    ranges = np.full(360, 10.0)
    clipped = compute_region(ranges, ANGLES)
    raw = compute_region(np.full(360, 25.0), ANGLES)
    assert np.allclose(raw.vertices, clipped.vertices)
    assert not compute_region(np.full(360, -1.0), ANGLES).success


def _largest_remainder(weights: np.ndarray, total: int) -> np.ndarray:
    quota = weights / weights.sum() * total
    counts = np.floor(quota).astype(int)
    order = sorted(range(len(quota)), key=lambda i: (-(quota[i] - counts[i]), i))
    for i in order[: total - counts.sum()]:
        counts[i] += 1
    return counts


def test_resampling_splits_points_by_subtended_angle():
    """Each CCW edge gets its start vertex plus largest-remainder extra points, evenly spaced."""
    rng = np.random.default_rng(5)
    for _ in range(50):
        region = compute_region(random_scan(rng), ANGLES)
        if not region.success:
            continue
        ccw = region.vertices[::-1]
        k = len(ccw)
        theta = np.arctan2(ccw[:, 1], ccw[:, 0])
        subtended = np.mod(np.roll(theta, -1) - theta, 2 * np.pi)
        expected = _largest_remainder(subtended, CFG.num_points - k)
        xy = region.boundary_xy
        start = int(np.argmin(np.linalg.norm(xy - ccw[0], axis=1)))
        xy = np.roll(xy, -start, axis=0)
        row = 0
        for i in range(k):
            a, b = ccw[i], ccw[(i + 1) % k]
            steps = np.arange(expected[i] + 1) / (expected[i] + 1.0)
            assert np.allclose(xy[row : row + expected[i] + 1], a + steps[:, None] * (b - a), atol=1e-12)
            row += expected[i] + 1
        assert row == CFG.num_points


def test_random_scans_satisfy_the_invariants():
    """Over 2000 random scans: success implies every invariant; only touching scans fail."""
    rng = np.random.default_rng(0)
    successes = 0
    for _ in range(2000):
        ranges = random_scan(rng)
        region = compute_region(ranges, ANGLES)
        touching = np.min(ranges) - CFG.inflation < 1e-6
        assert region.success != touching
        if region.success:
            _check_invariants(region, ranges)
            successes += 1
        else:
            assert region.status == "touching" and region.boundary.shape == (60, 2)
            assert np.all(np.diff(region.boundary[:, 1]) > 0)
    assert successes > 1500


def test_random_scans_match_the_independent_reference():
    """Polygon equals a qhull + brute-force half-plane reference (a vertex subset when thinned)."""
    rng = np.random.default_rng(1)
    compared = 0
    for _ in range(300):
        ranges = random_scan(rng)
        region = compute_region(ranges, ANGLES)
        ref = _reference_polygon(ranges)
        if ref is None or not shapely.Polygon(ref).contains(shapely.Point(0, 0)):
            assert not region.success
            continue
        if not region.success:  # only the final origin check (after thinning) may fail here
            assert region.status == "origin_outside_final" and len(ref) > CFG.num_points
            continue
        dist = np.min(np.linalg.norm(region.vertices[:, None] - ref[None], axis=2), axis=1)
        assert np.max(dist) < 1e-7
        if len(ref) <= CFG.num_points:
            assert len(ref) == len(region.vertices)
        compared += 1
    assert compared > 250


@settings(max_examples=150, deadline=None)
@given(
    st.lists(st.tuples(st.floats(-8, 8), st.floats(-8, 8), st.floats(0.05, 2.0)), min_size=0, max_size=25),
    st.floats(0.0, 0.2),
)
def test_hypothesis_circle_scenes(circles, noise_seed):
    """Circle scenes from hypothesis: success implies the invariants, else a 60-point fallback."""
    circ = np.array([c for c in circles if math.hypot(c[0], c[1]) > c[2] + 1e-3]).reshape(-1, 3)
    ranges = cast(ANGLES, np.zeros((0, 4)), circ)
    ranges = np.clip(ranges + noise_seed * np.sin(np.arange(360) * 7.3), 0.0, 10.0)
    region = compute_region(ranges, ANGLES)
    if region.success:
        _check_invariants(region, ranges)
    else:
        assert region.boundary.shape == (60, 2)


def test_recovery_keeps_a_convex_region_clear_of_the_scan_near_a_wall():
    """Within R_inf of a wall the scan fails, but the recovered polygon keeps 0.275 m from every return."""
    ranges = wall_ahead(0.30)
    region = compute_region(ranges, ANGLES)
    assert not region.success and region.status == "touching"
    assert region.recovered and region.has_polygon and region.inflation == pytest.approx(0.275)
    poly = shapely.Polygon(region.vertices)
    assert is_convex(region.vertices) and poly.contains(shapely.Point(0.0, 0.0))
    pts = np.clip(ranges - 0.275, 0, None)[:, None] * np.stack([np.cos(ANGLES), np.sin(ANGLES)], axis=1)
    assert not shapely.contains_xy(poly.buffer(-1e-5), pts[:, 0], pts[:, 1]).any()
    assert region.vertices[:, 0].max() <= 0.30 - 0.275 + 1e-5  # cannot move closer than 0.275 m (push 1e-6)


def test_recovery_ladder_uses_the_floor_then_gives_up():
    """Closer than 0.285 m the floor 0.235 m is used; closer than 0.245 m there is no polygon."""
    assert compute_region(wall_ahead(0.26), ANGLES).inflation == pytest.approx(0.235)
    below = compute_region(wall_ahead(0.24), ANGLES)
    assert not below.has_polygon and below.constraint_polygon is None


def test_paper_failure_mode_drops_the_polygon():
    """``on_failure='paper'`` gives the spec's failure: no polygon, fallback star boundary."""
    region = compute_region(wall_ahead(0.30), ANGLES, RegionConfig(on_failure="paper"))
    assert not region.success and not region.recovered and region.constraint_polygon is None
    assert region.boundary.shape == (CFG.num_points, 2)


def test_region_config_rejects_unknown_failure_mode():
    """A bad ``on_failure`` names the field."""
    with pytest.raises(ValueError, match="on_failure"):
        RegionConfig(on_failure="ignore")


def test_margin_keeps_extra_clearance_and_falls_back_to_the_paper_region():
    """With a margin the polygon keeps ``inflation + margin`` from every return while it can, and
    where it cannot (a return between the two) it is the paper's region, reported as a success."""
    margin = RegionConfig(margin=0.1)
    ranges = np.full(360, 10.0)
    ranges[45] = 1.0
    region = compute_region(ranges, ANGLES, margin)
    assert region.success and math.isclose(region.inflation, 0.425)
    point = 0.575 * np.array([math.cos(ANGLES[45]), math.sin(ANGLES[45])])  # shrunk by R_inf + margin
    assert np.max(region.normals @ point - region.offsets) > -1e-5
    assert np.allclose(np.linalg.norm(compute_region(np.full(360, 10.0), ANGLES, margin).vertices, axis=1),
                       10.0 - 0.425, atol=1e-5)
    ranges[45] = 0.4  # inside the margin, outside R_inf
    paper = compute_region(ranges, ANGLES, margin)
    assert paper.success and math.isclose(paper.inflation, CFG.inflation)
    assert np.allclose(paper.vertices, compute_region(ranges, ANGLES).vertices)
    ranges[45] = 0.3  # inside R_inf: the failure is the one without a margin
    assert compute_region(ranges, ANGLES, margin).status == compute_region(ranges, ANGLES).status == "touching"
    with pytest.raises(ValueError, match="margin"):
        RegionConfig(margin=-0.1)
