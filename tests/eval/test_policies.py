"""Policy loading: rsl-rl checkpoints, TorchScript exports, run folders and baseline names."""

from __future__ import annotations

import numpy as np
import pytest
import torch

from mjnav.eval.policies import load_policy, policy_name, resolve_checkpoint


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
