"""NavArena: walls, prism meshes and the obstacle-slot (mesh id swap) mechanism."""

from __future__ import annotations

import mujoco
import numpy as np
import pytest
from dm_control import mjcf

from mjnav.entities.arena import PARK_DEPTH, NavArena, body_bvh_order, prism_mesh, refit_body_bvh
from mjnav.entities.robot import OmniRobot
from mjnav.geometry.raycast import beam_angles, cast_rays, polygon_segments, wall_segments
from mjnav.schema import ArenaConfig, LidarConfig, ObstacleConfig, RobotConfig
from mjnav.world.shapes import make_shape_bank

OBSTACLES = ObstacleConfig(count=4, slots=6, bank_size=12, bank_seed=3)


ARENA = ArenaConfig(size=(10.0, 10.0))


def _world(arena_config: ArenaConfig = ARENA, obstacles: ObstacleConfig = OBSTACLES):
    arena = NavArena(arena_config, obstacles)
    robot = OmniRobot(RobotConfig(), LidarConfig())
    arena.attach(robot)
    return arena, robot, mjcf.Physics.from_mjcf_model(arena.mjcf_model)


def _place_random(arena: NavArena, physics, rng: np.random.Generator, count: int):
    shapes = rng.integers(0, len(arena.bank), size=count)
    poses = np.c_[rng.uniform(-3.5, 3.5, size=(count, 2)), rng.uniform(-np.pi, np.pi, size=count)]
    arena.set_obstacles(physics, shapes, poses)
    polygons = []
    for shape, (x, y, yaw) in zip(shapes, poses):
        c, s = np.cos(yaw), np.sin(yaw)
        polygons.append(arena.bank.polygon(shape) @ np.array([[c, s], [-s, c]]) + (x, y))
    return polygons


def _rangefinder_scan(physics, robot: OmniRobot, origin: np.ndarray) -> np.ndarray:
    robot.set_state(physics, origin)
    mujoco.mj_forward(physics.model.ptr, physics.data.ptr)  # sensors enabled: rangefinders evaluated
    ids = physics.bind(robot.rangefinders).element_id
    ranges = physics.data.sensordata[physics.model.sensor_adr[ids]].copy()
    ranges[(ranges < 0) | (ranges > 10.0)] = 10.0
    return ranges


def test_prism_mesh_is_closed_with_outward_faces():
    """The prism's faces are oriented outward: the divergence-theorem volume equals area x height."""
    polygon = make_shape_bank(OBSTACLES).polygon(1)
    verts, faces = prism_mesh(polygon, 0.6)
    tri = verts[faces]
    volume = np.einsum("ij,ij->i", tri[:, 0], np.cross(tri[:, 1], tri[:, 2])).sum() / 6
    x, y = polygon.T
    area = 0.5 * (x @ np.roll(y, -1) - np.roll(x, -1) @ y)
    assert volume == pytest.approx(area * 0.6, rel=1e-12)


def test_walls_surround_interior():
    """From the origin the rangefinders read the interior half extents along the axes."""
    _, robot, physics = _world(ArenaConfig(size=(6.0, 8.0)), ObstacleConfig(count=0, slots=0))
    ranges = _rangefinder_scan(physics, robot, np.zeros(2))
    np.testing.assert_allclose(ranges[[0, 90, 180, 270]], [3.0, 4.0, 3.0, 4.0], atol=1e-12)


def test_slot_bounds_match_what_the_compiler_produces():
    """Per-mesh geom_size/aabb/rbound used for swapping equal MuJoCo's compiled values for that mesh."""
    arena, _, physics = _world()
    cache = arena._bind(physics)
    probe = NavArena(ArenaConfig(size=(10.0, 10.0)), OBSTACLES)
    for b, mesh in enumerate(probe.meshes):
        probe.mjcf_model.worldbody.add("geom", name=f"probe_{b}", type="mesh", mesh=mesh)
    compiled = mjcf.Physics.from_mjcf_model(probe.mjcf_model)
    for b in range(len(arena.bank)):
        geom = compiled.named.model
        name = f"probe_{b}"
        np.testing.assert_allclose(geom.geom_size[name], cache.size[b], rtol=1e-6, atol=1e-12)
        np.testing.assert_allclose(geom.geom_aabb[name], cache.aabb[b], rtol=1e-6, atol=1e-7)
        assert geom.geom_rbound[name] == pytest.approx(cache.rbound[b], rel=1e-6)


def test_refit_reproduces_compiled_worldbody_bvh():
    """Refitting the worldbody BVH on an untouched model reproduces the compiler's boxes."""
    _, _, physics = _world()
    model = physics.model.ptr
    order, leaves = body_bvh_order(model, 0)
    compiled = model.bvh_aabb[order].copy()
    refit_body_bvh(model, order, leaves)
    np.testing.assert_allclose(model.bvh_aabb[order], compiled, atol=1e-9)


def test_placed_prisms_match_polygons_in_rangefinder_readings():
    """After mesh-id swaps, rangefinder readings equal exact 2-D casts on the layout polygons (1e-6 m)."""
    arena, robot, physics = _world()
    rng = np.random.default_rng(0)
    angles = beam_angles(360)
    checked = 0
    for _ in range(8):
        polygons = _place_random(arena, physics, rng, count=4)
        origin = rng.uniform(-4.5, 4.5, size=2)
        ranges = _rangefinder_scan(physics, robot, origin)
        segments = np.vstack([wall_segments((10.0, 10.0)), polygon_segments(polygons)])
        exact = cast_rays(origin, angles, segments, None, 10.0)
        compiled = cast_rays(origin, angles, np.vstack([wall_segments((10.0, 10.0)), polygon_segments(
            arena.obstacle_polygons(physics, 0.3))]), None, 10.0)
        np.testing.assert_allclose(ranges, compiled, atol=1e-9)  # the compiled cross-section, every beam
        ok = _clear_of_vertices(origin, angles, exact, polygons, clearance=1e-4, min_incidence=np.deg2rad(2))
        np.testing.assert_allclose(ranges[ok], exact[ok], atol=1e-6)
        checked += ok.sum()
    assert checked > 2000


def _clear_of_vertices(origin, angles, ranges, polygons, clearance, min_incidence):
    """Beams not passing within ``clearance`` of a vertex and not hitting an edge within min_incidence."""
    ok = np.ones(len(angles), dtype=bool)
    dirs = np.c_[np.cos(angles), np.sin(angles)]
    for polygon in polygons:
        for i, vertex in enumerate(polygon):
            rel = vertex - origin
            along = dirs @ rel
            perp = np.abs(dirs[:, 0] * rel[1] - dirs[:, 1] * rel[0])
            ok &= ~((along > 0) & (perp < clearance))
            edge = polygon[(i + 1) % len(polygon)] - vertex
            edge = edge / np.linalg.norm(edge)
            sin = np.abs(dirs[:, 0] * edge[1] - dirs[:, 1] * edge[0])
            hit = origin + ranges[:, None] * dirs
            on_edge = np.abs((hit - vertex) @ np.array([-edge[1], edge[0]])) < 1e-6
            ok &= ~(on_edge & (sin < np.sin(min_incidence)))
    return ok


def test_parked_slots_are_far_below_and_unseen():
    """Parked slots sit below the floor; rangefinders only see the walls and the placed prisms."""
    arena, robot, physics = _world()
    rng = np.random.default_rng(1)
    _place_random(arena, physics, rng, count=2)
    ids = physics.bind(arena.obstacle_slots).element_id
    mujoco.mj_forward(physics.model.ptr, physics.data.ptr)
    assert np.all(physics.data.geom_xpos[ids[2:], 2] == -PARK_DEPTH)
    arena.set_obstacles(physics, np.zeros(0, int), np.zeros((0, 3)))
    ranges = _rangefinder_scan(physics, robot, np.array([1.0, -2.0]))
    walls = cast_rays(np.array([1.0, -2.0]), beam_angles(360), wall_segments((10.0, 10.0)), None, 10.0)
    np.testing.assert_allclose(ranges, walls, atol=1e-9)


def test_too_many_obstacles_rejected():
    """Placing more obstacles than slots fails loudly."""
    arena, _, physics = _world()
    with pytest.raises(ValueError, match="slots"):
        arena.set_obstacles(physics, np.zeros(7, int), np.zeros((7, 3)))
