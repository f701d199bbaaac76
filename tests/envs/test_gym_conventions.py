"""Gymnasium conventions: the spec's episode length, render_mode and render_fps, make_vec, and
evaluation through wrapped environments."""

from __future__ import annotations

import gymnasium as gym
import numpy as np
import pytest

import mjnav  # noqa: F401 - registers the ids
from mjnav.envs.gym_env import NavGymEnv
from mjnav.eval.policies import load_policy
from mjnav.eval.runner import held_out_seed, run_episode
from mjnav.viz.gl import probe_gl_backend

HAS_GL = any(probe_gl_backend(b) for b in ("egl", "osmesa"))


def test_spec_reports_the_configured_episode_length() -> None:
    """``spec.max_episode_steps`` is 300, or the overridden ``timing.episode_steps``, which the TimeLimit enforces."""
    env = gym.make("mjnav/Stage1-v1")
    assert env.spec.max_episode_steps == 300
    env.close()
    short = gym.make("mjnav/Stage1-v1", overrides=["timing.episode_steps=7"])
    assert short.spec.max_episode_steps == 7
    short.reset(seed=0)
    steps, done = 0, False
    while not done:
        _, _, terminated, truncated, _ = short.step(np.full(4, -10.0, np.float32))  # stay near the start
        steps, done = steps + 1, terminated or truncated
    assert steps <= 7 and (terminated or steps == 7)
    short.close()


def test_render_mode_and_fps() -> None:
    """render_fps follows the control period; render() without render_mode warns and returns None;
    a bad mode, camera or size is a ValueError naming it."""
    env = NavGymEnv("stage1", overrides=["timing.control_period=0.05"], seed=0)
    assert env.metadata["render_fps"] == 20 and NavGymEnv.metadata["render_fps"] == 10
    with pytest.warns(UserWarning, match="render_mode"):
        assert env.render() is None
    env.close()
    with pytest.raises(ValueError, match="render_mode"):
        NavGymEnv("stage1", render_mode="human")
    with pytest.raises(ValueError, match="render_camera"):
        NavGymEnv("stage1", render_mode="rgb_array", render_camera="side")
    with pytest.raises(ValueError, match="640 x 480"):
        NavGymEnv("stage1", render_mode="rgb_array", render_size=(2000, 100))


@pytest.mark.skipif(not HAS_GL, reason="no off-screen GL backend")
def test_rgb_array_frames_have_the_requested_size_and_overlays() -> None:
    """make(..., render_mode="rgb_array") returns frames of render_size; overlays change the picture."""
    plain = gym.make("mjnav/Stage2-v1", render_mode="rgb_array", render_size=(96, 64))
    drawn = gym.make("mjnav/Stage2-v1", render_mode="rgb_array", render_size=(96, 64), render_overlays=True)
    frames = []
    for env in (plain, drawn):
        env.reset(options={"episode_seed": 5})
        env.step(np.zeros(4, np.float32))
        frame = env.render()
        assert frame.shape == (64, 96, 3) and frame.dtype == np.uint8 and frame.std() > 0
        frames.append(frame)
        env.close()
    assert np.any(frames[0] != frames[1])


@pytest.mark.parametrize("mode", ["sync", "async"])
def test_make_vec(mode: str) -> None:
    """gymnasium.make_vec steps two environments in both vectorisation modes."""
    envs = gym.make_vec("mjnav/Stage1-v1", num_envs=2, vectorization_mode=mode)
    obs, _ = envs.reset(seed=3)
    assert obs.shape == (2, 399)
    for _ in range(3):
        obs, reward, terminated, truncated, _ = envs.step(np.zeros((2, 4), np.float32))
    assert obs.shape == (2, 399) and reward.shape == (2,) and np.all(np.isfinite(reward))
    envs.close()


def test_evaluation_runs_through_wrappers() -> None:
    """run_episode takes what gymnasium.make returns (wrappers do not forward ``task``/``physics``)."""
    wrapped = gym.wrappers.RecordEpisodeStatistics(
        gym.make("mjnav/Stage1-v1", overrides=["timing.episode_steps=15"]))
    bare = NavGymEnv("stage1", overrides=["timing.episode_steps=15"], seed=0)
    seed = held_out_seed(0)
    a, _, _ = run_episode(wrapped, load_policy("mpc_goal"), seed)
    b, _, _ = run_episode(bare, load_policy("mpc_goal"), seed)
    assert a.outcome == b.outcome and a.steps == b.steps and a.distance_m == pytest.approx(b.distance_m)
    wrapped.close()
    bare.close()
