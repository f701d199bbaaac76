"""Crowd: mocap pedestrian slots attached through frames, radii by binding, parking."""

from __future__ import annotations

import mujoco
import numpy as np
import pytest
from dm_control import mjcf

from mjnav.entities.arena import PARK_DEPTH, NavArena
from mjnav.entities.crowd import Crowd
from mjnav.schema import ArenaConfig, CrowdConfig, ObstacleConfig

CROWD = CrowdConfig(count=3, slots=5, radius=(0.1, 0.4))


def _world(config: CrowdConfig = CROWD):
    arena = NavArena(ArenaConfig(size=(10.0, 10.0)), ObstacleConfig(count=0, slots=0))
    crowd = Crowd(config)
    crowd.attach_to(arena)
    return crowd, mjcf.Physics.from_mjcf_model(arena.mjcf_model)


def test_slots_compile_as_mocap_bodies():
    """Every slot is a mocap body (attachment frame) named ped_XX with one cylinder geom."""
    crowd, physics = _world()
    assert physics.model.nmocap == 5
    assert sorted(crowd.mocap_ids(physics)) == list(range(5))
    names = [physics.model.id2name(int(g), "geom") for g in crowd.geom_ids(physics)]
    assert names == [f"ped_{i:02d}/body" for i in range(5)]


def test_positions_move_the_cylinders():
    """set_positions writes mocap_pos; after kinematics the geoms stand on the floor there."""
    crowd, physics = _world()
    crowd.set_radii(physics, [0.2, 0.3, 0.4])
    xy = np.array([[1.0, 2.0], [-3.0, 0.5], [0.0, -4.0]])
    crowd.set_positions(physics, xy)
    mujoco.mj_kinematics(physics.model.ptr, physics.data.ptr)
    pos = physics.data.geom_xpos[crowd.geom_ids(physics)]
    np.testing.assert_allclose(pos[:3, :2], xy)
    np.testing.assert_allclose(pos[:3, 2], CROWD.height / 2)
    assert np.all(pos[3:, 2] < -PARK_DEPTH + CROWD.height)


def test_radius_binding_matches_compiled_cylinder():
    """Size, rbound and aabb written for radius r equal those of a slot compiled with radius r."""
    crowd, physics = _world()
    crowd.set_radii(physics, [0.17, 0.4, 0.1])
    ref_crowd, ref = _world(CrowdConfig(count=1, slots=1, radius=(0.17, 0.17)))
    gid, ref_gid = crowd.geom_ids(physics)[0], ref_crowd.geom_ids(ref)[0]
    for field in ("geom_size", "geom_rbound", "geom_aabb"):
        np.testing.assert_allclose(getattr(physics.model, field)[gid], getattr(ref.model, field)[ref_gid], atol=1e-12)


def test_parked_slots_do_not_collide_or_show():
    """Unused slots sit below the floor: no contacts and no hit for a horizontal ray."""
    crowd, physics = _world()
    crowd.set_radii(physics, [0.3])
    crowd.set_positions(physics, np.array([[2.0, 0.0]]))
    model, data = physics.model.ptr, physics.data.ptr
    mujoco.mj_forward(model, data)
    assert data.ncon == 0
    geomid = np.zeros(1, np.int32)
    dist = mujoco.mj_ray(model, data, np.array([-4.0, 0.0, 0.3]), np.array([1.0, 0.0, 0.0]), None, 1, -1, geomid)
    assert dist == pytest.approx(5.7) and geomid[0] == crowd.geom_ids(physics)[0]
    assert np.all(data.mocap_pos[crowd.mocap_ids(physics)[1:], 2] == -PARK_DEPTH)


def test_radius_above_compiled_maximum_rejected():
    """Radii beyond the compiled maximum (or too many pedestrians) fail loudly."""
    crowd, physics = _world()
    with pytest.raises(ValueError):
        crowd.set_radii(physics, [0.5])
    with pytest.raises(ValueError):
        crowd.set_radii(physics, np.full(6, 0.2))
