"""The paper's state/action designs (``task.design``): spaces, action paths, MPC, training, evaluation."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from mjnav.config import load_task
from mjnav.envs.gym_env import NavGymEnv
from mjnav.schema import ConfigError
from mjnav.tasks.design import DESIGNS, get_design

SIZES = {"ours": (399, 4), "design1": (372, 2), "design2": (372, 2), "design3": (387, 2), "design4": (396, 4)}


@pytest.mark.parametrize("design", sorted(DESIGNS))
def test_design_spaces_and_a_rollout(design: str) -> None:
    """Each design has the paper's observation and action sizes and runs episodes with finite values."""
    env = NavGymEnv("stage2", overrides=[f"design={design}"], seed=0)
    obs_size, act_size = SIZES[design]
    assert env.observation_space.shape == (obs_size,) and env.action_space.shape == (act_size,)
    obs, _ = env.reset(seed=1)
    rng = np.random.default_rng(0)
    for _ in range(30):
        obs, reward, terminated, truncated, info = env.step(rng.normal(size=act_size).astype(np.float32))
        assert obs.shape == (obs_size,) and np.isfinite(obs).all() and np.isfinite(reward)
        if terminated or truncated:
            obs, _ = env.reset()
    with pytest.raises(ValueError, match=f"{act_size} finite values"):
        env.step(np.zeros(act_size + 1, dtype=np.float32))
    env.close()


def test_velocity_designs_follow_the_tanh_velocity_command() -> None:
    """Designs 1-2, world axes (``action.heading=absolute``): a constant raw action drives the robot
    to v = 2.5·tanh(a) per axis."""
    env = NavGymEnv("stage1", overrides=["design=design2", "action.heading=absolute"], seed=0)
    env.reset(seed=2)
    action = np.array([0.3, -0.2], dtype=np.float32)
    for _ in range(20):
        env.step(action)
    _, v, _ = env.task.sim.robot_state(env.physics)
    assert np.allclose(v, 2.5 * np.tanh(action), atol=0.05)
    env.close()


def test_velocity_designs_command_in_the_velocity_heading_frame() -> None:
    """``action.heading=velocity`` (default): x along the current velocity (+x at rest), so a
    constant (a, 0) keeps the direction and reaches 2.5·tanh(a); a lateral action turns the robot."""
    env = NavGymEnv("stage1", overrides=["design=design1"], seed=0)
    env.reset(seed=2)
    for _ in range(20):
        env.step(np.array([0.5, 0.0], dtype=np.float32))
    _, v, _ = env.task.sim.robot_state(env.physics)
    assert np.allclose(v, (2.5 * np.tanh(0.5), 0.0), atol=0.05)
    for _ in range(3):
        env.step(np.array([0.0, 1.0], dtype=np.float32))
    _, v, _ = env.task.sim.robot_state(env.physics)
    assert v[1] > 0.1 and np.hypot(*v) > 0.5  # turning left (counter-clockwise) while moving
    env.close()


def test_design3_tracks_the_long_term_point_only() -> None:
    """Design 3's MPC drops the Q_s term, its state block the Q_s and Q*_1 terms."""
    config = load_task("stage2", ["design=design3"])
    assert not config.mpc.track_short and load_task("stage2").mpc.track_short
    assert get_design("design3").state_columns == (0, 1, 2, 3, 4, 6, 8, 10, 12)


def test_design4_plans_without_the_polygon_and_sees_the_scan() -> None:
    """Design 4 observes scan' (no region flag) and its MPC has no polygon constraint."""
    env = NavGymEnv("stage2", overrides=["design=design4"], seed=0)
    env.reset(seed=3)
    env.step(np.zeros(4, dtype=np.float32))
    core = env.task.core
    assert core.region.status == "scan" and not core.region.has_polygon
    assert core.counters["region_failures"] == 0
    env.close()


def test_unknown_design_is_rejected_with_its_name() -> None:
    """``design=design5`` fails at load, naming the key."""
    with pytest.raises(ConfigError, match="design"):
        load_task("stage2", ["design=design5"])
    with pytest.raises(ValueError, match="design5"):
        get_design("design5")


def test_a_design_trains_two_iterations(tmp_path: Path) -> None:
    """The rsl-rl adapter and PPO work with a 2-value action (Design 1)."""
    from mjnav.train.config import load_train
    from mjnav.train.runner import build_runner, learn, make_vec_env

    train = load_train(["num_envs=2", "workers=0", "steps_per_env=4", "epochs=1", "minibatches=1",
                        "policy.actor_hidden_dims=[16, 16, 16]", "policy.critic_hidden_dims=[16, 16, 16]"])
    env = make_vec_env(load_task("stage1", ["design=design1"]), train)
    try:
        assert env.num_actions == 2
        runner = build_runner(env, train, tmp_path, label="design1")
        learn(runner, 2)
        assert runner.current_learning_iteration == 2
    finally:
        env.close()


def test_evaluation_agents_act_with_the_design_action_size() -> None:
    """The random agent and planners emit the design's action length (evaluation and render.py)."""
    from mjnav.eval.policies import load_policy
    from mjnav.eval.runner import run_episode

    env = NavGymEnv("stage1", overrides=["design=design1", "timing.episode_steps=20"], seed=0)
    for name in ("random", "mpc_goal"):
        metrics, _, _ = run_episode(env, load_policy(name), 2**32 + 1)
        assert metrics.steps >= 1
    env.close()
