"""Tests for the action -> reference point mapping (spec §4)."""

from __future__ import annotations

import math

import numpy as np
import pytest
import shapely

from mjnav.control.action import (
    ActionConfig,
    boundary_distance,
    goal_inside,
    heading_angle,
    map_action,
    map_action_values,
    radii,
    reach_distance,
)
from mjnav.geometry.polygon import points_in_convex, points_in_polygon
from mjnav.geometry.region import compute_region
from tests.geometry.scans import ANGLES, random_scan

JERK = 8.0 * math.sqrt(2.0)


def _open_region():
    return compute_region(np.full(360, 10.0), ANGLES)


def test_config_rejects_bad_values_naming_the_field():
    """Invalid config values raise ValueError naming the field."""
    for field, value in [("heading", "north"), ("long_circle", "x"), ("t_c", 0.0), ("jerk_max", -1.0)]:
        with pytest.raises(ValueError, match=field):
            ActionConfig(**{field: value})


def test_reach_at_rest_is_the_pure_jerk_distance():
    """At rest the reach over t is |j| t³/6 with |j| = 8√2."""
    assert reach_distance(np.zeros(2), np.zeros(2), 0.1, JERK) == pytest.approx(JERK * 1e-3 / 6)
    assert reach_distance(np.zeros(2), np.zeros(2), 1.0, JERK) == pytest.approx(JERK / 6)


def test_reach_maximises_over_the_four_jerk_directions():
    """Velocity along +x, acceleration along +y: the reach is the best of the four directions."""
    v, a, t = np.array([2.0, 0.0]), np.array([0.0, 3.0]), 0.1
    base = v * t + a * t * t / 2
    dirs = [0.0, math.pi / 2, math.pi / 4, math.pi / 4 + math.pi]
    expected = max(
        np.linalg.norm(base + JERK * t**3 / 6 * np.array([math.cos(d), math.sin(d)])) for d in dirs
    )
    assert reach_distance(v, a, t, JERK) == pytest.approx(expected)


def test_radii_code_and_paper_long_circle():
    """R_s = 3 × one-period reach; R_l is max(10, 1-s reach) (code) or the 1-s reach (paper)."""
    v, a = np.array([1.0, 1.0]), np.zeros(2)
    r_s, r_l = radii(v, a, ActionConfig())
    assert r_s == pytest.approx(3 * reach_distance(v, a, 0.1, JERK))
    assert r_l == 10.0
    _, r_paper = radii(v, a, ActionConfig(long_circle="paper"))
    assert r_paper == pytest.approx(reach_distance(v, a, 1.0, JERK))


def test_beta_one_in_open_space_reaches_the_circles():
    """In an empty scan β = 1 puts Q_s on the short circle and Q_l on the polygon ∩ long circle."""
    region = _open_region()
    v = np.array([1.0, 0.0])
    pts = map_action(np.array([0.25, 1.0, 0.0, 1.0]), region, v, np.zeros(2), np.array([50.0, 0.0]))
    assert pts.theta_s == pytest.approx(math.pi / 2)
    assert np.linalg.norm(pts.q_s) == pytest.approx(pts.r_s)
    assert pts.q_s[0] == pytest.approx(0.0, abs=1e-12)
    assert points_in_convex(pts.q_l, region.vertices, tol=1e-9)
    assert np.min(region.offsets - region.normals @ pts.q_l) < 1e-9  # on the polygon boundary


def test_heading_option_offsets_theta_s():
    """With heading='velocity' θ_s is offset by the velocity heading; 'absolute' ignores it."""
    region = _open_region()
    v = np.array([0.0, 1.0])
    act = np.array([0.0, 0.5, 0.0, 0.5])
    code = map_action(act, region, v, np.zeros(2), np.array([50.0, 0.0]))
    paper = map_action(act, region, v, np.zeros(2), np.array([50.0, 0.0]), ActionConfig(heading="absolute"))
    assert code.theta_s == pytest.approx(math.pi / 2) and paper.theta_s == pytest.approx(0.0)
    assert code.theta_l == pytest.approx(code.theta_s)


def test_goal_heading_measures_both_points_from_the_goal_direction():
    """heading='goal': α_s = 0.5 puts Q_s straight away from the goal, α_l = 0.5 points Q_l at it."""
    region = _open_region()
    goal = np.array([-30.0, 30.0])  # direction 3π/4
    act = np.array([0.5, 0.3, 0.5, 0.5])
    pts = map_action(act, region, np.array([1.0, 0.0]), np.zeros(2), goal, ActionConfig(heading="goal"))
    assert pts.theta_s == pytest.approx(-math.pi / 4)
    assert pts.theta_l == pytest.approx(3 * math.pi / 4)
    assert float(np.dot(pts.q_l - pts.q_s, goal)) > 0.0


def test_heading_of_a_zero_vector_is_zero():
    """heading_angle: 0 for a zero (or negative-zero) vector and for 'absolute', else the direction."""
    assert heading_angle("velocity", [-0.0, -0.0], [1.0, 1.0]) == 0.0
    assert heading_angle("goal", [1.0, 1.0], [0.0, -0.0]) == 0.0
    assert heading_angle("absolute", [0.0, 1.0], [0.0, 1.0]) == 0.0
    assert heading_angle("velocity", [0.0, 2.0], [1.0, 0.0]) == pytest.approx(math.pi / 2)
    assert heading_angle("goal", [0.0, 2.0], [-1.0, 0.0]) == pytest.approx(math.pi)


def test_goal_inside_overrides_only_the_mpc_reference():
    """A goal inside the polygon becomes q_l_ref; the network's q_l is kept."""
    region = _open_region()
    goal = np.array([2.0, -1.0])
    pts = map_action(np.array([0.1, 0.5, 0.3, 0.5]), region, np.zeros(2), np.zeros(2), goal)
    assert pts.goal_inside and np.allclose(pts.q_l_ref, goal) and not np.allclose(pts.q_l, goal)
    far = map_action(np.array([0.1, 0.5, 0.3, 0.5]), region, np.zeros(2), np.zeros(2), np.array([30.0, 0.0]))
    assert not far.goal_inside and np.allclose(far.q_l_ref, far.q_l)


def test_random_actions_stay_inside_polygon_and_circles():
    """Over random scans, states and actions, Q_s and Q_l lie in polygon ∩ their circles."""
    rng = np.random.default_rng(0)
    checked = 0
    for _ in range(400):
        region = compute_region(random_scan(rng), ANGLES)
        if not region.success:
            continue
        for _ in range(5):
            act = rng.uniform(0, 1, size=4)
            v, a = rng.uniform(-2.5, 2.5, size=2), rng.uniform(-4, 4, size=2)
            cfg = ActionConfig(long_circle="paper" if rng.random() < 0.5 else "code")
            pts = map_action(act, region, v, a, rng.uniform(-12, 12, size=2), cfg)
            assert points_in_convex(pts.q_s, region.vertices, tol=1e-9)
            assert points_in_convex(pts.q_l, region.vertices, tol=1e-9)
            assert np.linalg.norm(pts.q_s) <= pts.r_s + 1e-9
            assert np.linalg.norm(pts.q_l) <= pts.r_l + 1e-9
            assert np.linalg.norm(pts.q_s) == pytest.approx(act[1] * pts.d_theta_s)
            checked += 1
    assert checked > 1500


def test_ray_distance_is_exact_against_shapely():
    """d_θ^s equals the shapely distance to polygon ∩ disc(R_s) along the ray."""
    rng = np.random.default_rng(1)
    for _ in range(100):
        region = compute_region(random_scan(rng), ANGLES)
        if not region.success:
            continue
        v = rng.uniform(-2.5, 2.5, size=2)
        pts = map_action(rng.uniform(0, 1, size=4), region, v, np.zeros(2), np.array([40.0, 0.0]))
        area = shapely.Polygon(region.vertices).intersection(shapely.Point(0, 0).buffer(pts.r_s, 4096))
        d = np.array([math.cos(pts.theta_s), math.sin(pts.theta_s)])
        hit = shapely.LineString([[0, 0], 30 * d]).intersection(area.exterior)
        assert pts.d_theta_s == pytest.approx(shapely.Point(0, 0).distance(hit), abs=2e-4 * pts.r_s + 1e-9)


def test_failed_region_uses_the_star_polyline():
    """With a failed region the points stay inside the fallback star polygon; no override outside."""
    ranges = np.where(np.arange(360) % 12 < 6, 4.0, 1.5)  # every 6th beam alternates: a star
    ranges[10] = 0.1  # touching: region fails
    region = compute_region(ranges, ANGLES)
    assert not region.success
    rng = np.random.default_rng(2)
    for _ in range(200):
        pts = map_action(
            rng.uniform(0, 1, size=4), region, rng.uniform(-2, 2, 2), np.zeros(2), np.array([1.0, 1.0])
        )
        star = shapely.Polygon(region.boundary_xy)
        for q in (pts.q_s, pts.q_l):
            assert star.buffer(1e-9).contains(shapely.Point(q))
    assert pts.goal_inside == bool(points_in_polygon(np.array([1.0, 1.0]), region.boundary_xy))


def _random_regions(rng: np.random.Generator, count: int):
    """Regions of random scans; every third scan touches an obstacle (the fallback star polyline)."""
    for k in range(count):
        ranges = random_scan(rng)
        if k % 3 == 0:
            ranges[rng.integers(0, 360)] = 0.05
        yield compute_region(ranges, ANGLES)


def test_jitted_mapping_agrees_with_the_public_geometry():
    """map_action's kernel gives what radii, boundary_distance and goal_inside give, on both region kinds."""
    rng = np.random.default_rng(3)
    kinds = set()
    for k, region in enumerate(_random_regions(rng, 300)):
        kinds.add(region.success)
        cfg = ActionConfig(heading="absolute" if k % 2 else "velocity", long_circle="paper" if k % 4 < 2 else "code")
        act, v, a = rng.uniform(0, 1, 4), rng.uniform(-2.5, 2.5, 2), rng.uniform(-4, 4, 2)
        goal = rng.uniform(-6, 6, 2)
        pts = map_action(act, region, v, a, goal, cfg)
        assert (pts.r_s, pts.r_l) == pytest.approx(radii(v, a, cfg), rel=1e-12)
        d_s = np.array([math.cos(pts.theta_s), math.sin(pts.theta_s)])
        d_l = np.array([math.cos(pts.theta_l), math.sin(pts.theta_l)])
        assert pts.d_theta_s == pytest.approx(min(boundary_distance(region, np.zeros(2), d_s), pts.r_s), abs=1e-9)
        assert pts.d_theta_l <= boundary_distance(region, pts.q_s, d_l) + 1e-9
        assert pts.goal_inside == goal_inside(region, goal)
        np.testing.assert_allclose(pts.q_l_ref, goal if pts.goal_inside else pts.q_l)
    assert kinds == {True, False}


def test_invalid_inputs_raise():
    """NaN inputs and actions outside [0, 1] raise ValueError."""
    region = _open_region()
    with pytest.raises(ValueError, match="action01"):
        map_action(np.array([0.5, 1.5, 0.5, 0.5]), region, np.zeros(2), np.zeros(2), np.ones(2))
    with pytest.raises(ValueError, match="velocity"):
        map_action(np.full(4, 0.5), region, np.array([np.nan, 0.0]), np.zeros(2), np.ones(2))
    with pytest.raises(ValueError, match="goal_rel"):
        map_action(np.full(4, 0.5), region, np.zeros(2), np.zeros(2), np.ones(3))


def test_unchecked_mapping_is_map_action_on_floats():
    """map_action_values on the ten floats gives exactly map_action's points, on both region kinds."""
    rng = np.random.default_rng(8)
    kinds = set()
    for region in _random_regions(rng, 60):
        kinds.add(region.success)
        act, v, a, goal = rng.uniform(0, 1, 4), rng.uniform(-2.5, 2.5, 2), rng.uniform(-4, 4, 2), rng.uniform(-6, 6, 2)
        checked = map_action(act, region, v, a, goal)
        unchecked = map_action_values([*act.tolist(), *v.tolist(), *a.tolist(), *goal.tolist()], region)
        for name in ("q_s", "q_l", "q_l_ref"):
            np.testing.assert_array_equal(getattr(unchecked, name), getattr(checked, name))
        assert (unchecked.theta_s, unchecked.d_theta_l, unchecked.goal_inside) == (
            checked.theta_s, checked.d_theta_l, checked.goal_inside)
    assert kinds == {True, False}
