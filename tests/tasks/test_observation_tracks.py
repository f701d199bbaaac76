"""``observation.tracks=K`` ("Ours + tracks"): the K nearest LiDAR tracks after the stacked frames,
the -v2 bounds that cover them, and an actor widened for them that acts exactly as before."""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest
import torch

from mjnav import shipped
from mjnav.envs.bounded import observation_bounds
from mjnav.envs.gym_env import NavGymEnv
from mjnav.policy import build_actor, load_actor
from mjnav.schema import ConfigError
from mjnav.stages import load_stage
from mjnav.tasks import observation as O
from mjnav.train import session
from mjnav.train.runner import widen_inputs

GOAL_FRAME = ["collision=scan", "region.margin=0.1", "action.heading=goal", "observation.frame=goal"]
ACTIVATIONS = ("relu", "relu", "hardswish")


def test_tracks_block_nearest_first_scaled_clipped_and_padded() -> None:
    """Rows [dx/10, dy/10, vx/2.5, vy/2.5, 1] by centre distance; far or fast values clipped; zeros after."""
    tracks = np.array([[4.0, 1.0, 0.5, 0.0, 0.3],     # 3 m away
                       [1.5, 1.0, 0.0, -1.0, 0.2],    # 0.5 m away
                       [1.0, 13.0, 5.0, 0.0, 0.3]])   # 12 m away, 5 m/s
    block = O.tracks_block(tracks, np.array([1.0, 1.0]), 4).reshape(4, O.TRACK_FEATURES)
    np.testing.assert_allclose(block[0], [0.05, 0.0, 0.0, -0.4, 1.0])
    np.testing.assert_allclose(block[1], [0.3, 0.0, 0.2, 0.0, 1.0])
    np.testing.assert_allclose(block[2], [0.0, 1.0, 1.0, 0.0, 1.0])
    assert not block[3].any()
    assert O.tracks_block(None, np.zeros(2), 2).tolist() == [0.0] * 10
    assert O.tracks_block(np.zeros((0, 5)), np.zeros(2), 0).shape == (0,)


def test_tracks_block_in_the_goal_frame() -> None:
    """Turning the frame by the goal direction turns offsets and velocities alike."""
    track = np.array([[0.0, 2.0, 1.0, 0.0, 0.3]])  # 2 m along +y, moving along +x
    block = O.tracks_block(track, np.zeros(2), 1, rotation=math.pi / 2)
    np.testing.assert_allclose(block, [0.2, 0.0, 0.0, -0.4, 1.0], atol=1e-12)


def test_tracks_block_refuses_bad_input() -> None:
    with pytest.raises(ValueError, match="count must be >= 0"):
        O.tracks_block(None, np.zeros(2), -1)
    with pytest.raises(ValueError, match=r"\(T, >=4\)"):
        O.tracks_block(np.zeros((2, 3)), np.zeros(2), 2)
    with pytest.raises(ConfigError, match="tracks"):
        load_stage("stage5", ["observation.tracks=-1"])


def _rollout(overrides: list[str], steps: int = 25) -> list[np.ndarray]:
    env = NavGymEnv("stage5", overrides=overrides, seed=0)
    observations = [env.reset(options={"episode_seed": 11})[0]]
    for _ in range(steps):
        obs, _, terminated, truncated, _ = env.step(np.zeros(4, np.float32))
        observations.append(obs)
        if terminated or truncated:
            break
    env.close()
    return observations


def test_env_appends_tracks_after_the_unchanged_observation() -> None:
    """With tracks the first 399 values are the paper's, bit for bit; tracks appear with valid 1,
    in the -v2 bounds; the tracker runs only when asked."""
    plain = _rollout(GOAL_FRAME)
    with_tracks = _rollout([*GOAL_FRAME, "observation.tracks=6"])
    assert len(plain) == len(with_tracks) > 10
    for a, b in zip(plain, with_tracks, strict=True):
        assert a.shape == (399,) and b.shape == (399 + 30,)
        np.testing.assert_array_equal(a, b[:399])
    valid = np.array([b[399:].reshape(6, 5)[:, 4] for b in with_tracks])
    assert valid[-1].sum() >= 1, "stage 5's walkers are tracked within a second or two"
    low, high = observation_bounds(load_stage("stage5", [*GOAL_FRAME, "observation.tracks=6"]))
    assert low.shape == (429,) and np.all(low[399:].reshape(6, 5) == [-1, -1, -1, -1, 0]) and np.all(high[399:] == 1)
    assert all(np.all((low <= b) & (b <= high)) for b in with_tracks)
    env = NavGymEnv("stage5", seed=0)
    env.reset(options={"episode_seed": 11})
    assert env.task.tracks is None, "the tracker runs only when something reads it"
    env.close()


def test_widened_actor_acts_as_before() -> None:
    """Zero columns for 30 new inputs: the same actions (to float32 rounding) on the same 399-value
    prefix, whatever the tracks."""
    saved = torch.load(shipped.get("stage5_policy").weights_path(), map_location="cpu", weights_only=True)
    old = build_actor(saved["actor_state_dict"], ACTIVATIONS)
    wanted = {k: v.new_zeros(v.shape[0], 429) if k == "mlp.0.weight" else v
              for k, v in saved["actor_state_dict"].items()}
    critic = {k: v.new_zeros(v.shape[0], 429) if k == "mlp.0.weight" else v
              for k, v in saved["critic_state_dict"].items()}
    widened = widen_inputs(saved, wanted, critic)
    assert widened["critic_state_dict"]["mlp.0.weight"].shape[1] == 429
    new = build_actor(widened["actor_state_dict"], ACTIVATIONS)
    obs = torch.rand(16, 399)
    tracks = torch.rand(16, 30) * 2 - 1
    torch.testing.assert_close(new(torch.cat([obs, tracks], 1)), old(obs))  # float32 sums in another order
    assert widen_inputs(saved, saved["actor_state_dict"], saved["critic_state_dict"]) is saved


def test_recipe_starts_as_ours(tmp_path: Path) -> None:
    """recipe=stage5_tracks_observation loads and starts from Ours' widened weights: with the actor frozen in
    its first update (critic warm-up) the exported actor is Ours on the 399-value prefix."""
    plan = session.plan_run(session.parse_args(["recipe=stage5_tracks_observation"]))
    assert plan.task.observation.tracks == 6 and plan.task.observation.frame == "goal"
    tiny = ["train.iterations=1", "train.num_envs=2", "train.steps_per_env=8", "train.minibatches=1",
            "train.epochs=1", "train.workers=0", f"out={tmp_path}"]
    run_dir = session.run(["recipe=stage5_tracks_observation", *tiny])
    trained, _ = load_actor(run_dir / "policy.pt")
    ours, _ = load_actor(shipped.get("stage5_policy").path())
    obs = torch.rand(8, 399)
    with torch.no_grad():
        torch.testing.assert_close(trained(torch.cat([obs, torch.rand(8, 30)], 1)), ours(obs))
