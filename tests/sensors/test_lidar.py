"""LiDAR backends: MuJoCo rangefinders vs exact 2-D casting, and agreement between backends.

Known, documented exclusion: a beam passing within ~1e-8 m of a prism vertex (or exactly
through a side-face diagonal) may differ, because MuJoCo's ray-triangle test is not watertight
at shared vertices/edges while the 2-D cast is closed. Such beams have measure zero; random
scenes never produce them, and beams 1e-7 m beside a vertex agree (tested below).
"""

from __future__ import annotations

import dataclasses

import mujoco
import numpy as np
import pytest
from dm_control import mjcf

from mjnav.config import load_task
from mjnav.entities.arena import NavArena
from mjnav.entities.crowd import Crowd
from mjnav.entities.robot import OmniRobot
from mjnav.geometry.raycast import beam_angles, cast_rays, wall_segments
from mjnav.schema import ArenaConfig, CrowdConfig, LidarConfig, ObstacleConfig, RobotConfig
from mjnav.sensors import make_lidar
from mjnav.sensors.lidar import AnalyticLidar, MujocoLidar
from mjnav.sim import NavSim

ANGLES = beam_angles(360)


def _sim(stage: str, **changes):
    config = load_task(stage)
    config = dataclasses.replace(config, **changes) if changes else config
    sim = NavSim(config)
    physics = sim.make_physics()
    return sim, physics


def _both(sim: NavSim, physics) -> tuple[np.ndarray, np.ndarray]:
    return sim.scan(physics, noise=False, backend="analytic"), sim.scan(physics, noise=False, backend="mujoco")


def _teleport(sim: NavSim, physics, xy) -> None:
    sim.robot.set_state(physics, np.asarray(xy, dtype=float))
    mujoco.mj_forward(physics.model.ptr, physics.data.ptr)


def test_rangefinder_reads_distance_to_wall():
    """Beams at 0/90/180/270 degrees read the exact distance to each wall face, on both backends."""
    sim, physics = _sim("stage1")
    sim.initialize_episode(physics, np.random.default_rng(0))
    _teleport(sim, physics, (2.0, -5.0))
    analytic, mj = _both(sim, physics)
    np.testing.assert_allclose(mj[[0, 90, 180, 270]], [8.0, 10.0, 10.0, 10.0], atol=1e-12)  # 20 x 30 m
    np.testing.assert_allclose(mj, analytic, atol=1e-9)


def test_rangefinder_reads_distance_to_cylinder():
    """Rangefinders read the exact ray-circle distance to a pedestrian (1e-9 m), e.g. d - r head-on."""
    arena = NavArena(ArenaConfig(size=(10.0, 10.0)), ObstacleConfig(count=0, slots=0))
    robot = OmniRobot(RobotConfig(), LidarConfig())
    arena.attach(robot)
    crowd = Crowd(CrowdConfig(count=1, radius=(0.1, 0.4)))
    crowd.attach_to(arena)
    physics = mjcf.Physics.from_mjcf_model(arena.mjcf_model)
    crowd.set_radii(physics, [0.3])
    crowd.set_positions(physics, np.array([[2.0, 1.0]]))
    robot.set_state(physics, np.array([0.0, 1.0]))
    mujoco.mj_forward(physics.model.ptr, physics.data.ptr)  # sensors enabled in a bare physics
    ranges = physics.data.sensordata[physics.model.sensor_adr[physics.bind(robot.rangefinders).element_id]]
    ranges = np.where(ranges < 0, 10.0, np.minimum(ranges, 10.0))
    assert ranges[0] == pytest.approx(1.7, abs=1e-12)
    exact = cast_rays(np.array([0.0, 1.0]), ANGLES, wall_segments((10.0, 10.0)), np.array([[2.0, 1.0, 0.3]]), 10.0)
    np.testing.assert_allclose(ranges, exact, atol=1e-9)
    assert np.sum(ranges < 2.0) == 17  # beams within asin(0.3/2) = 8.6 degrees of +x


def test_backends_agree_on_random_scenes():
    """Analytic and MuJoCo scans agree to 1e-6 m on every beam over many random scenes."""
    worst, beams = 0.0, 0
    for stage, seeds in (("stage4", range(12)), ("stage7", range(12))):
        sim, physics = _sim(stage)
        for seed in seeds:
            rng = np.random.default_rng(seed)
            sim.initialize_episode(physics, rng)
            for _ in range(3):
                sim.control_step(physics, rng.uniform(-8.0, 8.0, 2))
                analytic, mj = _both(sim, physics)
                worst = max(worst, np.abs(analytic - mj).max())
                beams += analytic.size
            circles = sim.pedestrian_circles()
            if len(circles):  # right next to a pedestrian
                x, y, r = circles[seed % len(circles)]
                _teleport(sim, physics, (x + r + 0.23, y))
                analytic, mj = _both(sim, physics)
                worst = max(worst, np.abs(analytic - mj).max())
    assert worst < 1e-6, worst
    assert beams > 20_000


def test_backends_agree_on_beams_grazing_corners():
    """Beams passing 1e-7 m beside a prism vertex (either side) agree to 1e-6 m."""
    sim, physics = _sim("stage4")
    rng = np.random.default_rng(5)
    worst, count = 0.0, 0
    for _ in range(4):
        sim.initialize_episode(physics, rng)
        for polygon in sim.arena.obstacle_polygons(physics, sim.config.lidar.height):
            for vertex in polygon:
                beam = int(rng.integers(360))
                direction = np.array([np.cos(ANGLES[beam]), np.sin(ANGLES[beam])])
                for offset in (1e-7, -1e-7):
                    origin = vertex - 1.5 * direction + offset * np.array([-direction[1], direction[0]])
                    if np.abs(origin).max() > 9.5:
                        continue
                    _teleport(sim, physics, origin)
                    analytic, mj = _both(sim, physics)
                    worst = max(worst, np.abs(analytic - mj).max())
                    count += 1
    assert count > 40
    assert worst < 1e-6, worst


def test_multiray_equals_rangefinder_sensors():
    """The mj_multiRay method returns the rangefinder sensor values (robot body excluded)."""
    sim, physics = _sim("stage4")
    sim.initialize_episode(physics, np.random.default_rng(3))
    sim.control_step(physics, np.array([3.0, -2.0]))
    multiray = sim.scan(physics, noise=False, backend="mujoco")
    sensor = MujocoLidar(sim.config.lidar, sim.robot, method="sensor")
    np.testing.assert_allclose(sensor.scan(physics, None), multiray, atol=1e-12)
    assert physics.model.opt.disableflags & mujoco.mjtDisableBit.mjDSBL_SENSOR  # restored


def test_make_lidar_selects_backend():
    """make_lidar returns the backend named by LidarConfig.backend."""
    assert isinstance(make_lidar(LidarConfig(backend="analytic")), AnalyticLidar)
    sim, _ = _sim("stage1")
    assert isinstance(make_lidar(LidarConfig(backend="mujoco"), sim.robot), MujocoLidar)
    with pytest.raises(ValueError):
        make_lidar(LidarConfig(backend="mujoco"))
