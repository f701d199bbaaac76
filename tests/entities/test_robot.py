"""OmniRobot: degrees of freedom, LiDAR sites and free-space tracking of the triple integrator."""

from __future__ import annotations

import mujoco
import numpy as np
import pytest
from dm_control import mjcf

from mjnav.entities.arena import NavArena
from mjnav.entities.robot import OmniRobot, integrator_value, plan_substeps
from mjnav.schema import ArenaConfig, LidarConfig, ObstacleConfig, RobotConfig

ROBOT = RobotConfig()
PERIOD, SUBSTEPS = 0.1, 5


def _free_space(integrator: str = "RK4", config: RobotConfig = ROBOT):
    arena = NavArena(ArenaConfig(size=(100.0, 100.0)), ObstacleConfig(count=0, slots=0))
    robot = OmniRobot(config, LidarConfig())
    arena.attach(robot)
    arena.mjcf_model.option.timestep = PERIOD / SUBSTEPS
    arena.mjcf_model.option.integrator = integrator
    return robot, mjcf.Physics.from_mjcf_model(arena.mjcf_model)


def _tracking_errors(integrator: str, trials: int = 100) -> tuple[np.ndarray, np.ndarray]:
    """Max |position| (m) and |velocity| (m/s) errors after one period over random states."""
    robot, physics = _free_space(integrator)
    model, data = physics.model.ptr, physics.data.ptr
    rng = np.random.default_rng(0)
    pos_err, vel_err = [], []
    for _ in range(trials):
        p = rng.uniform(-10, 10, 2)
        v = rng.uniform(-ROBOT.v_max, ROBOT.v_max, 2)
        a = rng.uniform(-ROBOT.a_max, ROBOT.a_max, 2)
        j = rng.uniform(-ROBOT.j_max, ROBOT.j_max, 2)
        mujoco.mj_resetData(model, data)
        robot.set_state(physics, p, v)
        robot.set_reference(p, v, a, j, substeps=SUBSTEPS)
        for _ in range(SUBSTEPS):
            robot.apply_tracking_force(physics)
            mujoco.mj_step(model, data)
        t = PERIOD
        p_pred = p + v * t + a * t**2 / 2 + j * t**3 / 6
        v_pred = v + a * t + j * t**2 / 2
        pos, vel = robot.get_state(physics)
        pos_err.append(np.abs(pos - p_pred).max())
        vel_err.append(np.abs(vel - v_pred).max())
        np.testing.assert_allclose(robot.acceleration, a + j * t, atol=1e-12)
    return np.asarray(pos_err), np.asarray(vel_err)


@pytest.mark.parametrize("integrator", ["Euler", "RK4", "implicitfast"])
def test_period_ends_on_the_triple_integrator(integrator):
    """With every integrator the planned forces land on the triple integrator to rounding."""
    pos_err, vel_err = _tracking_errors(integrator)
    assert pos_err.max() < 1e-9 and vel_err.max() < 1e-9


def test_plan_stays_near_the_continuous_reference():
    """Inside the period the Euler plan stays within 1 mm and 7 cm/s of the continuous reference.

    Its accelerations back-load the period's velocity change (Euler moves each substep with its
    end velocity): a ramp of at most 5.5·(|a|·T + |j|·T²/2) around the mean reference accelerations.
    """
    rng = np.random.default_rng(1)
    dt = PERIOD / SUBSTEPS
    for _ in range(50):
        p, v = rng.uniform(-5, 5, 2), rng.uniform(-ROBOT.v_max, ROBOT.v_max, 2)
        a, j = rng.uniform(-ROBOT.a_max, ROBOT.a_max, 2), rng.uniform(-ROBOT.j_max, ROBOT.j_max, 2)
        plan = np.array(plan_substeps(p, v, a, j, SUBSTEPS, dt, 1.0))
        t = np.arange(SUBSTEPS)[:, None] * dt
        np.testing.assert_allclose(plan[:, 4:], p + v * t + a * t**2 / 2 + j * t**3 / 6, atol=1e-3)
        np.testing.assert_allclose(plan[:, 2:4], v + a * t + j * t**2 / 2, atol=0.07)
        bound = 5.5 * (np.abs(a) * PERIOD + np.abs(j) * PERIOD**2 / 2) + 1e-9
        assert np.all(np.abs(plan[:, :2] - (a + j * (t + dt / 2))) <= bound)


def test_without_the_plan_euler_misses_by_millimetres():
    """The correction matters: Euler with the mean reference accelerations misses by mm."""
    dt = PERIOD / SUBSTEPS
    p, v, a, j = np.zeros(2), np.array([1.0, -1.0]), np.array([4.0, 2.0]), np.array([8.0, -8.0])
    u = a + j * (np.arange(SUBSTEPS)[:, None] + 0.5) * dt
    pos, vel = p.copy(), v.copy()
    for k in range(SUBSTEPS):  # semi-implicit Euler
        vel = vel + dt * u[k]
        pos = pos + dt * vel
    p_pred = p + v * PERIOD + a * PERIOD**2 / 2 + j * PERIOD**3 / 6
    assert 1e-3 < np.abs(pos - p_pred).max() < 1e-2
    plan = np.array(plan_substeps(p, v, a, j, SUBSTEPS, dt, 1.0))
    assert np.abs(plan[:, :2] - u).max() > 0.1


def test_single_substep_plan_is_least_squares():
    """One substep cannot end on both p and v: its acceleration is the least-squares compromise.

    a = 1 m/s² over one Euler step of 0.1 s: Δv = 0.1·u should be 0.1 and Δp = 0.01·u should be
    0.005, so u = (0.1·0.1 + 0.01·0.005) / (0.1² + 0.01²) = 0.995 m/s², not 1.
    """
    plan = plan_substeps(np.zeros(2), np.zeros(2), np.ones(2), np.zeros(2), 1, 0.1, 1.0)
    assert len(plan) == 1
    np.testing.assert_allclose(plan[0][:2], [0.01005 / 0.0101] * 2, rtol=1e-12)
    np.testing.assert_allclose(plan[0][2:], 0.0, atol=1e-15)  # state at the substep start


def test_contact_feedback_pushes_towards_the_plan():
    """Held back (velocity below the plan), the velocity feedback adds force along the plan."""
    robot, physics = _free_space("Euler")
    robot.set_reference(np.zeros(2), np.array([1.0, 0.0]), np.zeros(2), np.zeros(2), substeps=SUBSTEPS)
    robot.set_state(physics, np.zeros(2), np.zeros(2))  # stopped, the plan says 1 m/s along x
    robot.apply_tracking_force(physics)
    assert physics.data.ctrl[0] == pytest.approx(ROBOT.mass * ROBOT.kv * 1.0)
    assert physics.data.ctrl[1] == pytest.approx(0.0)


def test_tracking_force_goes_to_the_physics_it_is_given():
    """Alternating between two compiled copies, each gets the force of its own velocity."""
    arena = NavArena(ArenaConfig(size=(100.0, 100.0)), ObstacleConfig(count=0, slots=0))
    robot = OmniRobot(ROBOT, LidarConfig())
    arena.attach(robot)
    stopped, moving = (mjcf.Physics.from_mjcf_model(arena.mjcf_model) for _ in range(2))
    robot.set_state(stopped, np.zeros(2), np.zeros(2))
    robot.set_state(moving, np.zeros(2), np.array([1.0, 0.0]))
    expected = {id(stopped): ROBOT.mass * ROBOT.kv * 1.0, id(moving): 0.0}
    for physics in (stopped, moving, stopped, moving):
        robot.set_reference(np.zeros(2), np.array([1.0, 0.0]), np.zeros(2), np.zeros(2), substeps=SUBSTEPS)
        physics.data.ctrl[:] = np.nan
        robot.apply_tracking_force(physics)
        assert physics.data.ctrl[0] == pytest.approx(expected[id(physics)])
        assert physics.data.ctrl[1] == pytest.approx(0.0)


def test_only_planar_translation():
    """The robot has exactly two slide dofs (x, y), no rotation or vertical motion, and floats."""
    robot, physics = _free_space()
    model = physics.model.ptr
    assert model.nq == 2 and model.nv == 2
    assert list(model.jnt_type) == [mujoco.mjtJoint.mjJNT_SLIDE] * 2
    np.testing.assert_allclose(model.jnt_axis, [[1, 0, 0], [0, 1, 0]])
    mujoco.mj_forward(model, physics.data.ptr)
    bottom = physics.data.geom_xpos[robot.geom_id(physics), 2] - ROBOT.height / 2
    assert bottom > 0 and physics.data.ncon == 0
    assert physics.model.body_mass[robot.body_id(physics)] == pytest.approx(ROBOT.mass)


def test_rangefinder_sites_point_along_beams():
    """Site i's +z axis is beam i: angle i degrees from +x, counter-clockwise, horizontal."""
    robot, physics = _free_space()
    mujoco.mj_forward(physics.model.ptr, physics.data.ptr)
    zaxes = physics.bind(robot.ray_sites).xmat.reshape(-1, 3, 3)[:, :, 2]
    angles = np.deg2rad(np.arange(360))
    np.testing.assert_allclose(zaxes, np.c_[np.cos(angles), np.sin(angles), np.zeros(360)], atol=1e-12)
    assert [s.name for s in robot.rangefinders[:2]] == ["ray_000", "ray_001"]


def test_force_is_clipped_to_actuator_limits():
    """A huge reference error saturates the motors at force_max."""
    robot, physics = _free_space()
    robot.set_reference(np.zeros(2), np.array([100.0, -100.0]), np.zeros(2), np.zeros(2), substeps=SUBSTEPS)
    robot.apply_tracking_force(physics)
    np.testing.assert_allclose(physics.data.ctrl, [ROBOT.force_max, -ROBOT.force_max])
    np.testing.assert_allclose(physics.model.actuator_ctrlrange, [[-ROBOT.force_max, ROBOT.force_max]] * 2)


def test_integrator_names():
    """Integrator names map to MuJoCo enums; unknown names fail."""
    assert integrator_value("RK4") == mujoco.mjtIntegrator.mjINT_RK4
    with pytest.raises(ValueError):
        integrator_value("verlet")


@pytest.mark.parametrize("integrator", ["Euler", "RK4"])
def test_robot_plan_equals_plan_substeps(integrator):
    """The robot's in-place plan is exactly the public plan_substeps, period after period."""
    robot, physics = _free_space(integrator)
    c = 0.5 if integrator == "RK4" else 1.0
    rng = np.random.default_rng(3)
    for substeps in (SUBSTEPS, SUBSTEPS, 3, SUBSTEPS):
        p, v, a, j = rng.normal(size=(4, 2)) * 3.0
        robot.set_reference(p, v, a, j, substeps=substeps)
        expected = plan_substeps(p, v, a, j, substeps, PERIOD / SUBSTEPS, c)
        assert robot.plan(physics) == [list(row) for row in expected]
        assert robot.acceleration.tolist() == a.tolist()
