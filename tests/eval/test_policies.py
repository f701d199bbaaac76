"""Policy loading: rsl-rl checkpoints, TorchScript exports, run folders and baseline names."""

from __future__ import annotations

import numpy as np
import pytest
import torch

from mjnav.eval.policies import load_policy
from mjnav.policy import policy_name, resolve_checkpoint


@pytest.fixture(scope="module")
def run_dir(tmp_path_factory):
    from mjnav.train.config import TrainConfig
    from mjnav.train.export import build_actor, export_actor

    torch.manual_seed(0)
    actor = build_actor(TrainConfig(), 399, 4)
    out = tmp_path_factory.mktemp("run")
    torch.save({"actor_state_dict": actor.state_dict(), "iter": 3}, out / "model_3.pt")
    torch.save({"actor_state_dict": actor.state_dict(), "iter": 12}, out / "model_12.pt")
    export_actor(actor, out, onnx=False)
    return out


def test_checkpoint_and_torchscript_agree(run_dir):
    """The actor rebuilt from model_<it>.pt gives the same means as the exported policy.pt."""
    obs = np.random.default_rng(0).normal(size=399).astype(np.float32)
    from_ckpt = load_policy(run_dir / "model_3.pt").act(obs)
    from_jit = load_policy(run_dir / "policy.pt").act(obs)
    assert from_ckpt.shape == (4,)
    np.testing.assert_allclose(from_ckpt, from_jit, rtol=1e-5, atol=1e-6)


def test_run_dir_resolution(run_dir):
    """A run folder resolves to policy.pt, else to the latest checkpoint."""
    assert resolve_checkpoint(run_dir).name == "policy.pt"
    (run_dir / "policy.pt").rename(run_dir / "policy.bak")
    try:
        assert resolve_checkpoint(run_dir).name == "model_12.pt"
        assert policy_name(run_dir) == f"{run_dir.name}/model_12"
    finally:
        (run_dir / "policy.bak").rename(run_dir / "policy.pt")


def test_baseline_names_and_errors(tmp_path):
    """Baseline names load planners (or the random actor); unknown names raise FileNotFoundError."""
    assert load_policy("teb").planner is not None
    random = load_policy("random")
    assert random.planner is None and random.act(np.zeros(399)).shape == (4,)
    with pytest.raises(FileNotFoundError):
        load_policy("no_such_policy", runs_dir=tmp_path)


def test_training_overrides_come_from_the_policy_config(tmp_path):
    """A shipped NAME_policy.pt is evaluated with NAME_config.yaml's task overrides; baselines have none."""
    import yaml

    from mjnav.policy import policy_config, training_overrides

    (tmp_path / "stage4_policy.pt").write_bytes(b"x")
    (tmp_path / "stage4_config.yaml").write_text(yaml.safe_dump({"run": {"task_overrides": ["design=design2",
                                                                                          "collision=scan"]}}))
    assert policy_config(tmp_path / "stage4_policy.pt") == tmp_path / "stage4_config.yaml"
    assert training_overrides(tmp_path / "stage4_policy.pt") == ("design=design2", "collision=scan")
    assert training_overrides("mpc_goal") == ()
    (tmp_path / "stage4_config.yaml").write_text("just: text\n")
    with pytest.raises(ValueError, match="not a training config"):
        training_overrides(tmp_path / "stage4_policy.pt")


def test_sampled_actions_follow_the_checkpoint_gaussian(run_dir):
    """action=sample draws mean + std·N(0,1) per episode seed; exported policy.pt cannot sample."""
    from mjnav.eval.policies import _SampledActor

    agent = load_policy(run_dir / "model_3.pt", mode="sample")
    assert isinstance(agent._actor, _SampledActor)
    obs = np.zeros(399, np.float32)
    mean = load_policy(run_dir / "model_3.pt").act(obs)
    agent._actor.reset(np.random.default_rng(0))
    draws = np.array([agent.act(obs) for _ in range(2000)])
    assert np.allclose(draws.mean(0), mean, atol=0.05) and np.allclose(draws.std(0), np.exp(-0.5), atol=0.05)
    with pytest.raises(ValueError, match="needs an rsl-rl checkpoint"):
        load_policy(run_dir / "policy.pt", mode="sample")
