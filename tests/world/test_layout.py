"""Tests for episode layout sampling (spec §9)."""

from __future__ import annotations

import numpy as np
import pytest
from shapely.geometry import Point, Polygon

from mjnav.geometry.raycast import beam_angles, cast_rays
from mjnav.schema import ArenaConfig, CrowdConfig, LayoutConfig, LidarConfig, ObstacleConfig
from mjnav.world.layout import Layout, LayoutError, sample_layout, scene_circles, scene_segments
from mjnav.world.shapes import make_shape_bank

INFLATION = 0.325
LAYOUT = LayoutConfig()
LIDAR = LidarConfig()
STAGE4 = (
    ArenaConfig(size=(20.0, 30.0)),
    ObstacleConfig(count=10, slots=10),
    CrowdConfig(count=10, radius=(0.2, 0.3), speed=(0.3, 0.3)),
)
STAGE7 = (
    ArenaConfig(size=(10.0, 10.0)),
    ObstacleConfig(count=0),
    CrowdConfig(count=30, radius=(0.1, 0.4), speed=(0.3, 0.6)),
)


def _sample(stage, seed, layout=LAYOUT):
    arena, obstacles, crowd = stage
    bank = make_shape_bank(obstacles)
    return sample_layout(arena, obstacles, crowd, layout, LIDAR, bank, np.random.default_rng(seed), INFLATION)


def _check_obstacles(layout, arena, obstacles, bank):
    half = np.asarray(arena.size) / 2
    assert layout.obstacle_poses.shape == (obstacles.count, 3)
    for shape, pose, poly in zip(layout.obstacle_shapes, layout.obstacle_poses, layout.obstacle_polygons):
        assert np.all(np.abs(pose[:2]) <= half - bank.circumradius + 1e-12)
        c, s = np.cos(pose[2]), np.sin(pose[2])
        expected = bank.polygon(shape) @ np.array([[c, s], [-s, c]]) + pose[:2]
        np.testing.assert_allclose(poly, expected, atol=1e-12)
        assert Polygon(poly).exterior.is_ccw
        for point in (layout.start, layout.goal):
            assert np.linalg.norm(point - pose[:2]) >= LAYOUT.obstacle_clearance
            assert not Polygon(poly).contains(Point(point))
            assert Polygon(poly).distance(Point(point)) >= LAYOUT.free_clearance


def _check_points(layout, arena):
    half = np.asarray(arena.size) / 2
    for point in (layout.start, layout.goal):
        assert np.all(np.abs(point) <= half - LAYOUT.free_clearance)
    assert np.linalg.norm(layout.goal - layout.start) >= LAYOUT.start_goal_min_distance


def _check_peds(layout, arena, crowd):
    half = np.asarray(arena.size) / 2
    pos, radii = layout.ped_positions, layout.ped_radii
    assert pos.shape == (crowd.count, 2) and radii.shape == (crowd.count,)
    assert np.all(np.abs(pos) + radii[:, None] <= half + 1e-12)
    assert np.all((radii >= crowd.radius[0]) & (radii <= crowd.radius[1]))
    assert np.all((layout.ped_speeds >= crowd.speed[0]) & (layout.ped_speeds <= crowd.speed[1]))
    assert np.all((layout.ped_headings >= -np.pi) & (layout.ped_headings < np.pi))
    gaps = np.linalg.norm(pos[:, None] - pos[None], axis=-1) - radii[:, None] - radii[None]
    np.fill_diagonal(gaps, np.inf)
    assert gaps.min() >= LAYOUT.pedestrian_gap - 1e-12
    for centre, r in zip(pos, radii):
        for poly in layout.obstacle_polygons:
            assert Polygon(poly).distance(Point(centre)) >= r - 1e-12
            assert not Polygon(poly).contains(Point(centre))


def _check_start_scan(layout, arena):
    circles = scene_circles(layout.ped_positions, layout.ped_radii)
    segments = scene_segments(layout, arena)
    scan = cast_rays(layout.start, beam_angles(LIDAR.beams), segments, circles, LIDAR.max_range)
    assert np.maximum(scan - INFLATION, 0.0).min() > LAYOUT.min_start_scan


@pytest.mark.parametrize("stage", [STAGE4, STAGE7], ids=["20x30_10obs_10ped", "10x10_30ped"])
def test_invariants_hold_over_200_seeds(stage):
    """Bounds, clearances, non-overlap and the start scan hold for 200 seeds."""
    arena, obstacles, crowd = stage
    bank = make_shape_bank(obstacles)
    for seed in range(200):
        layout = _sample(stage, seed)
        _check_points(layout, arena)
        _check_obstacles(layout, arena, obstacles, bank)
        _check_peds(layout, arena, crowd)
        _check_start_scan(layout, arena)


def test_same_seed_same_layout_different_seed_different_layout():
    """A seed fixes the layout; other seeds change it."""
    assert _sample(STAGE4, 3) == _sample(STAGE4, 3)
    assert _sample(STAGE7, 3) == _sample(STAGE7, 3)
    assert _sample(STAGE4, 3) != _sample(STAGE4, 4)
    assert _sample(STAGE7, 3) != _sample(STAGE7, 4)


def test_layout_ignores_global_random_state():
    """Seeding numpy's global generator does not change the layout."""
    np.random.seed(0)
    a = _sample(STAGE4, 11)
    np.random.seed(1)
    assert _sample(STAGE4, 11) == a


def test_layout_arrays_are_read_only():
    """A sampled layout cannot be mutated in place."""
    layout = _sample(STAGE7, 0)
    with pytest.raises(ValueError):
        layout.start[0] = 0.0


def test_start_goal_max_distance_is_respected():
    """With a 3 m upper bound every start-goal distance lies in [1, 3] m."""
    layout_config = LayoutConfig(start_goal_max_distance=3.0)
    for seed in range(50):
        layout = _sample(STAGE4, seed, layout_config)
        assert 1.0 <= np.linalg.norm(layout.goal - layout.start) <= 3.0


def test_scene_helpers_shapes():
    """scene_segments has 4 walls plus one segment per polygon edge; scene_circles is (P, 3)."""
    layout = _sample(STAGE4, 1)
    edges = sum(len(p) for p in layout.obstacle_polygons)
    assert scene_segments(layout, STAGE4[0]).shape == (4 + edges, 4)
    circles = scene_circles(layout.ped_positions, layout.ped_radii)
    np.testing.assert_array_equal(circles[:, 2], layout.ped_radii)


def test_too_many_obstacles_raise_after_bounded_attempts():
    """200 obstacles in a 10x10 arena leave no free start: LayoutError names that constraint."""
    arena, obstacles = ArenaConfig(size=(10.0, 10.0)), ObstacleConfig(count=200, slots=200)
    with pytest.raises(LayoutError, match="attempts") as info:
        sample_layout(arena, obstacles, CrowdConfig(), LayoutConfig(max_attempts=20), LIDAR,
                      make_shape_bank(obstacles), np.random.default_rng(0))
    assert "start in free space" in str(info.value) and "20 attempts" in str(info.value)


def test_unreachable_scan_threshold_names_the_scan():
    """A min_start_scan beyond the LiDAR range can never pass: the error names the start scan."""
    with pytest.raises(LayoutError, match="start scan"):
        _sample(STAGE7, 0, LayoutConfig(min_start_scan=20.0, max_attempts=10))


def test_items_that_cannot_fit_raise_immediately():
    """Pedestrians wider than the interior raise LayoutError naming the radius."""
    crowd = CrowdConfig(count=1, radius=(1.0, 1.5))
    with pytest.raises(LayoutError, match="pedestrian radius"):
        sample_layout(ArenaConfig(size=(2.5, 2.5)), ObstacleConfig(), crowd, LAYOUT, LIDAR,
                      make_shape_bank(ObstacleConfig()), np.random.default_rng(0))


def test_layout_equality_is_by_value():
    """Layouts compare by array values, not identity, and never equal other types."""
    layout = _sample(STAGE7, 5)
    assert isinstance(layout, Layout) and layout != "layout"


def test_pedestrian_clearance_keeps_the_crowd_off_start_and_goal():
    """Spec §9: obstacle centres, pedestrians included, >= 1.95 m from start and goal (default)."""
    assert LAYOUT.pedestrian_clearance == 1.95
    for seed in range(50):
        sampled = _sample(STAGE7, seed)
        for point in (sampled.start, sampled.goal):
            assert np.linalg.norm(sampled.ped_positions - point, axis=1).min() >= 1.95
    # 0 gives task version 1's layouts, where stage-7 pedestrians do start near the goal
    old = [_sample(STAGE7, seed, LayoutConfig(pedestrian_clearance=0.0)) for seed in range(20)]
    assert any(np.linalg.norm(s.ped_positions - s.goal, axis=1).min() < 1.95 for s in old)


def test_negative_pedestrian_clearance_is_refused():
    with pytest.raises(ValueError, match="pedestrian_clearance: must be >= 0"):
        LayoutConfig(pedestrian_clearance=-0.1)
