"""Behaviour of the composer task and its Gymnasium view."""

import numpy as np
import pytest
from absl.testing import absltest
from dm_env import test_utils
from gymnasium.utils.env_checker import check_env

import mjnav
from mjnav.envs.gym_env import NavGymEnv
from mjnav.tasks.core import Outcome

ZERO = np.zeros(4, dtype=np.float32)


class _Hold:
    """A planner that holds the robot still (zero jerk from rest)."""

    def reset(self, config, rng) -> None:
        del config, rng

    def act(self, inp) -> np.ndarray:
        return -inp.acceleration / 0.1


@pytest.fixture(scope="module")
def stage4() -> NavGymEnv:
    env = NavGymEnv("stage4", seed=0)
    yield env
    env.close()


def test_teleport_onto_goal_is_success(stage4: NavGymEnv) -> None:
    """A robot put on the goal succeeds on the next step with +140 and discount 0."""
    stage4.reset(seed=3)
    task = stage4.task
    task.sim.robot.set_state(stage4.physics, task.layout.goal + 0.05)
    _, reward, terminated, truncated, info = stage4.step(ZERO)
    assert info["outcome"] == "success" and terminated and not truncated
    assert info["reward_terms"]["success"] == 140.0
    assert reward == pytest.approx(sum(info["reward_terms"].values()))
    assert task.get_discount(stage4.physics) == 0.0


def test_overlapping_a_pedestrian_is_collision(stage4: NavGymEnv) -> None:
    """A robot put on a pedestrian collides (a real contact) with −30 and discount 0."""
    stage4.reset(seed=5)
    task = stage4.task
    task.sim.robot.set_state(stage4.physics, task.sim.pedestrian_circles()[0, :2])
    _, _, terminated, _, info = stage4.step(ZERO)
    assert info["outcome"] == "collision" and terminated
    assert info["reward_terms"]["collision"] == -30.0
    assert task.get_discount(stage4.physics) == 0.0


def test_timeout_is_truncation() -> None:
    """A robot that never moves is truncated (not terminated) after exactly 300 control steps."""
    env = NavGymEnv("stage1", seed=0)
    env.task.planner = _Hold()
    env.reset(seed=1)
    for step in range(1, 301):
        _, _, terminated, truncated, info = env.step(ZERO)
        assert not terminated
        if truncated:
            break
    assert step == 300 and info["outcome"] == "timeout"
    assert env.task.get_discount(env.physics) == 1.0


def test_nan_action_is_rejected(stage4: NavGymEnv) -> None:
    """A NaN action raises a clear ValueError instead of reaching the MPC."""
    stage4.reset(seed=1)
    with pytest.raises(ValueError, match="finite"):
        stage4.step(np.array([0, np.nan, 0, 0], dtype=np.float32))


def test_non_finite_robot_state_is_rejected(stage4: NavGymEnv) -> None:
    """A NaN velocity (diverged physics) raises a clear ValueError before the action layer."""
    stage4.reset(seed=1)
    core = stage4.task.core
    with pytest.raises(ValueError, match="robot state is not finite"):
        core.plan(np.zeros(4), np.zeros(2), np.array([np.nan, 0.0]), np.zeros(2))


def test_same_seed_same_rollout() -> None:
    """Two environments with the same seed give bit-identical observations and rewards."""
    runs = []
    for _ in range(2):
        env = NavGymEnv("stage6", seed=11)
        obs, _ = env.reset(seed=4)
        rng = np.random.default_rng(0)
        trace = [obs]
        for _ in range(20):
            obs, reward, term, trunc, _ = env.step(rng.normal(size=4).astype(np.float32))
            trace.append(np.append(obs, reward))
            if term or trunc:
                obs, _ = env.reset()
        runs.append(np.concatenate(trace))
    np.testing.assert_array_equal(runs[0], runs[1])


def test_the_crowd_does_not_depend_on_the_robots_actions() -> None:
    """Same episode seed, different actions: the pedestrians walk the same paths (common random
    numbers: they ignore the robot and draw from their own stream), so re-played episodes compare
    actions on the same crowd future."""
    env = NavGymEnv("stage7", overrides=["collision=contact"], seed=0)
    paths, robots = [], []
    for scale in (0.0, 2.0):
        env.reset(options={"episode_seed": 5})
        rng, path = np.random.default_rng(1), []
        for _ in range(15):
            path.append(env.task.sim.pedestrian_circles()[:, :2].copy())
            robot = env.task.sim.robot_state(env.physics)[0][:2].copy()
            _, _, term, trunc, _ = env.step((scale * rng.normal(size=4)).astype(np.float32))
            if term or trunc:
                break
        paths.append(np.array(path))
        robots.append(robot)
    env.close()
    n = min(len(p) for p in paths)
    assert n >= 5 and np.linalg.norm(robots[0] - robots[1]) > 0.1  # the robot did go elsewhere
    np.testing.assert_array_equal(paths[0][:n], paths[1][:n])


def test_episode_seed_option_selects_scenario(stage4: NavGymEnv) -> None:
    """options={'episode_seed': k} reproduces the same world regardless of history."""
    stage4.reset(options={"episode_seed": 42})
    first = stage4.task.layout
    stage4.reset(seed=9)
    stage4.reset(options={"episode_seed": 42})
    assert stage4.task.layout == first and stage4.task.episode_seed == 42


def test_step_info_reports_terms_and_mpc(stage4: NavGymEnv) -> None:
    """Each step reports every enabled reward term and MPC statistics."""
    stage4.reset(seed=2)
    _, _, _, _, info = stage4.step(ZERO)
    assert set(info["reward_terms"]) >= {"success", "collision", "approach", "feasibility", "change"}
    assert {"fallback", "region_success"} <= set(info["mpc"]) and "solve_time_ms" not in info["mpc"]
    timed = NavGymEnv("stage1", seed=0, timing_info=True)
    timed.reset(seed=0)
    assert timed.step(ZERO)[-1]["mpc"]["solve_time_ms"] > 0


@pytest.mark.parametrize("env_id", mjnav.ENV_IDS)
def test_gymnasium_checker(env_id: str) -> None:
    """Every registered id passes Gymnasium's own environment checker."""
    import gymnasium as gym

    env = gym.make(env_id)
    check_env(env.unwrapped, skip_render_check=True)
    env.close()


def test_close_twice_is_allowed() -> None:
    """Gymnasium requires close() to be idempotent (its checker warns otherwise)."""
    env = NavGymEnv("stage1", seed=0)
    env.reset(seed=0)
    env.close()
    env.close()


def test_outcome_flags() -> None:
    """Only success and collision are terminal; timeout ends the episode as truncation."""
    assert Outcome.SUCCESS.terminal and Outcome.COLLISION.terminal
    assert not Outcome.TIMEOUT.terminal and Outcome.TIMEOUT.done and not Outcome.RUNNING.done


class DmEnvTest(test_utils.EnvironmentTestMixin, absltest.TestCase):
    """dm_env's conformance tests on stage 3 (obstacles and pedestrians)."""

    def make_object_under_test(self):
        return mjnav.make_env("stage3", seed=0)


def test_rangefinder_sites_optional_for_analytic_lidar() -> None:
    """The task compiles no rangefinders by default and scans the same as with them."""
    with_sites = NavGymEnv("stage5", overrides=["lidar.rangefinders=true"], seed=0)
    without = NavGymEnv("stage5", seed=0)
    assert with_sites.physics.model.nsensor == 360 and without.physics.model.nsensor == 0
    obs_a, _ = with_sites.reset(seed=2)
    obs_b, _ = without.reset(seed=2)
    np.testing.assert_array_equal(obs_a, obs_b)


def test_step_record_is_in_the_world_frame(stage4: NavGymEnv) -> None:
    """The record's points, prediction and polygon are the plan's, shifted by the robot position."""
    stage4.reset(seed=2)
    core = stage4.task.core
    position, velocity, accel = np.array([3.0, -2.0]), np.array([0.5, 0.2]), np.zeros(2)
    region = core.region
    core.plan(np.array([0.3, -0.2, 0.5, 0.1]), position, velocity, accel)
    record, pending = core.record, core._pending
    np.testing.assert_array_equal(record.q_s, pending["q_s"])
    np.testing.assert_array_equal(record.predicted[0], pending["q1"])
    np.testing.assert_array_equal(record.predicted[-1], pending["qn"])
    relative = region.vertices if region.success else region.boundary_xy
    np.testing.assert_allclose(record.polygon - position, relative, atol=1e-12)
    assert np.linalg.norm(record.q_l_target - position) <= core.config.lidar.max_range  # a point of the region
    assert record.plan_ok == pending["plan_ok"] and record.region_ok == bool(region.success)


def _gym_trace(env: NavGymEnv, steps: int = 620) -> list:
    obs, info = env.reset(seed=4)
    rng = np.random.default_rng(0)
    trace = [obs, info]
    for _ in range(steps):
        out = env.step(rng.normal(size=4).astype(np.float32) * 2)
        trace.append(out)
        if out[2] or out[3]:
            trace.append(env.reset())
    return trace


@pytest.mark.parametrize("stage", ["stage1", "stage7"])
def test_task_steps_equal_composer_steps(stage: str) -> None:
    """Stepping through the task alone gives composer's observations, rewards, flags and info."""
    fast, slow = NavGymEnv(stage, seed=2), NavGymEnv(stage, seed=2, task_steps=False)
    ours, theirs = _gym_trace(fast), _gym_trace(slow)
    assert fast._step_task and not slow._step_task
    assert sum(isinstance(x, tuple) and len(x) == 2 for x in ours) >= 2  # episodes ended and reset
    for a, b in zip(ours, theirs, strict=True):
        np.testing.assert_equal(a, b)


def test_another_step_hook_means_composer_steps() -> None:
    """An extra composer hook is honoured: from the next reset the environment steps through composer."""
    env = NavGymEnv("stage4", seed=0)
    calls = []
    env.reset(seed=1)
    assert env._step_task
    env._env.add_extra_hook("after_step", lambda physics, random_state: calls.append(1))
    env.reset(seed=1)
    assert not env._step_task
    for _ in range(3):
        env.step(ZERO)
    assert len(calls) == 3


def test_task_step_raises_physics_errors() -> None:
    """A MuJoCo warning inside a task step raises PhysicsError naming it, as composer's step does."""
    from dm_control.rl import control

    env = NavGymEnv("stage4", seed=0)
    env.reset(seed=1)
    assert env._step_task
    _, gains = env.task.sim.robot.tracking_arrays(env.physics)
    gains[0] = np.nan  # the tracking force (mass × acceleration) turns NaN
    with pytest.raises(control.PhysicsError, match="mjWARN_BADCTRL"):
        env.step(ZERO)
