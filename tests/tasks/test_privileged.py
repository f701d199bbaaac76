"""Privileged critic inputs (``observation.critic_pedestrians``): features, and what the env reports."""

from __future__ import annotations

import math

import numpy as np
import pytest

from mjnav.envs.gym_env import NavGymEnv
from mjnav.tasks.privileged import PEDESTRIAN_FEATURES, critic_size, pedestrian_features

GOAL_FRAME = ["observation.frame=goal", "action.heading=goal"]


def test_nearest_surface_first_with_units_and_padding() -> None:
    """Slots hold [x/10, y/10, v_x, v_y, r, 1], nearest surface first; missing slots are zeros."""
    circles = np.array([[3.0, 0.0, 0.1], [0.0, 2.0, 0.9], [-5.0, 0.0, 0.2]])  # surfaces 2.9, 1.1, 4.8 m
    velocities = np.array([[0.1, 0.0], [0.0, -0.5], [0.3, 0.3]])
    f = pedestrian_features(np.array([0.0, 0.0]), circles, velocities, 4).reshape(4, PEDESTRIAN_FEATURES)
    np.testing.assert_allclose(f[0], [0.0, 0.2, 0.0, -0.5, 0.9, 1.0], atol=1e-6)
    np.testing.assert_allclose(f[1], [0.3, 0.0, 0.1, 0.0, 0.1, 1.0], atol=1e-6)
    np.testing.assert_allclose(f[2], [-0.5, 0.0, 0.3, 0.3, 0.2, 1.0], atol=1e-6)
    assert not f[3].any()
    assert pedestrian_features(np.zeros(2), circles, velocities, 1).shape == (critic_size(1),)
    assert pedestrian_features(np.zeros(2), np.zeros((0, 3)), np.zeros((0, 2)), 3).shape == (18,)


def test_goal_frame_turns_positions_and_velocities() -> None:
    """With the goal along +y, a pedestrian ahead walking at the robot reads as ahead on x, moving -x."""
    f = pedestrian_features(np.array([1.0, 1.0]), np.array([[1.0, 3.0, 0.2]]), np.array([[0.0, -0.4]]), 1,
                            rotation=math.pi / 2)
    np.testing.assert_allclose(f, [0.2, 0.0, -0.4, 0.0, 0.2, 1.0], atol=1e-6)


def test_bad_input_is_refused() -> None:
    """Mismatched velocities or a negative count raise a clear ValueError."""
    with pytest.raises(ValueError, match="velocities for"):
        pedestrian_features(np.zeros(2), np.zeros((2, 3)), np.zeros((1, 2)), 2)
    with pytest.raises(ValueError, match="count"):
        pedestrian_features(np.zeros(2), np.zeros((1, 3)), np.zeros((1, 2)), -1)


def _rollout(overrides: list[str], steps: int = 4) -> tuple[list[np.ndarray], list[dict], NavGymEnv]:
    env = NavGymEnv("stage5", overrides=overrides)
    obs, info = env.reset(options={"episode_seed": 11})
    observations, infos = [obs], [info]
    for _ in range(steps):
        obs, _, _, _, info = env.step(np.zeros(4, np.float32))
        observations.append(obs)
        infos.append(info)
    return observations, infos, env


def test_env_reports_true_crowd_to_the_critic_only() -> None:
    """info['critic'] holds the K nearest pedestrians' true state; the policy's observation is unchanged."""
    plain, plain_infos, env = _rollout(GOAL_FRAME)
    env.close()
    assert env.critic_size == 0 and "critic" not in plain_infos[-1]
    observations, infos, env = _rollout([*GOAL_FRAME, "observation.critic_pedestrians=3"])
    assert env.critic_size == 18
    for a, b in zip(plain, observations, strict=True):
        np.testing.assert_array_equal(a, b)
    first = infos[0]["critic"].reshape(3, PEDESTRIAN_FEATURES)
    assert not first[:, 2:4].any(), "velocities are unknown at first sight"
    last = infos[-1]["critic"].reshape(3, PEDESTRIAN_FEATURES)
    speeds = np.hypot(last[:, 2], last[:, 3])
    assert np.all(last[:, 5] == 1.0) and np.all((speeds > 0.05) & (speeds < 1.0)), speeds  # stage 5: 0.3-0.6 m/s
    p = env.physics.data.qpos[:2]
    circles = env.task.sim.pedestrian_circles()
    nearest = np.sort(np.hypot(*(circles[:, :2] - p).T) - circles[:, 2])[:3]
    np.testing.assert_allclose(np.hypot(last[:, 0], last[:, 1]) * 10 - last[:, 4], nearest, atol=1e-4)
    env.close()
