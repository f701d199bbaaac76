"""Lab scripts of the crowd stages (``experiments/``): ``search.py``, outcome-verified
search, and ``group_pg.py``, policy gradient with scenario groups, which compare actions on a shared
crowd future; ``privileged_actor.py``, PPO whose actor reads the crowd's true state."""

from __future__ import annotations

import importlib.util
import sys

import numpy as np
import pytest
import torch

from tests._scripts import ROOT

FOLDER = ROOT / "experiments"
CHECKPOINT = str(ROOT / "docs" / "policies" / "stage6_checkpoint.pt")


def _load(name: str, monkeypatch: pytest.MonkeyPatch):
    monkeypatch.syspath_prepend(str(FOLDER))
    spec = importlib.util.spec_from_file_location(name, FOLDER / f"{name}.py")
    module = importlib.util.module_from_spec(spec)
    monkeypatch.setitem(sys.modules, name, module)
    spec.loader.exec_module(module)
    return module


def test_replay_is_exact_and_an_offset_changes_only_its_steps(monkeypatch: pytest.MonkeyPatch) -> None:
    """Re-playing a seed repeats the episode; an offset at step t leaves steps < t as they were."""
    search = _load("search", monkeypatch)
    env, actor = search._env("stage7", CHECKPOINT), search._actor(CHECKPOINT)
    try:
        first = search.play(env, 123, actor)
        again = search.play(env, 123, actor)
        shifted = search.play(env, 123, actor, (3, np.array([0, 0, 1.0, 0], np.float32)))
    finally:
        env.close()
    assert first[0] == again[0] and np.array_equal(np.array(first[2]), np.array(again[2]))
    assert np.array_equal(np.array(first[1][:4]), np.array(shifted[1][:4]))  # observations up to the offset
    assert np.allclose(shifted[2][3], actor(shifted[1][3]) + [0, 0, 1.0, 0])


def test_group_pg_writes_checkpoints_that_evaluate_reads(monkeypatch: pytest.MonkeyPatch, tmp_path) -> None:
    """One iteration with one group of two writes model_1.pt and config.yaml; the policy loader reads them."""
    from mjnav.eval.policies import load_policy

    monkeypatch.setenv("GPG_SCENARIOS", "1")
    monkeypatch.setenv("GPG_GROUP", "2")
    group_pg = _load("group_pg", monkeypatch)
    group_pg.main([str(tmp_path), CHECKPOINT, "stage5", "1", "7"])
    saved = torch.load(tmp_path / "model_1.pt", map_location="cpu", weights_only=False)
    assert saved["iter"] == 1 and (tmp_path / "config.yaml").is_file()
    assert load_policy(str(tmp_path / "model_1.pt")) is not None


def test_privileged_actor_starts_as_the_policy_it_widens(monkeypatch: pytest.MonkeyPatch, tmp_path) -> None:
    """``privileged_actor.py``: the widened checkpoint acts as INIT whatever the crowd inputs say,
    and the patched runner config gives the actor the critic's privileged group."""
    from mjnav.train import runner as runner_lib
    from mjnav.train.config import load_train

    module = _load("privileged_actor", monkeypatch)
    widened = torch.load(str(module.widen(CHECKPOINT, tmp_path / "w.pt", 36)), weights_only=False)
    before = torch.load(CHECKPOINT, weights_only=False)["actor_state_dict"]["mlp.0.weight"]
    after = widened["actor_state_dict"]["mlp.0.weight"]
    assert after.shape == (before.shape[0], before.shape[1] + 36)
    obs = torch.rand(5, before.shape[1])
    crowd = torch.randn(5, 36)
    torch.testing.assert_close(torch.cat([obs, crowd], 1) @ after.T, obs @ before.T)
    patched = module._actor_reads_the_crowd(runner_lib.rsl_config)
    assert patched(load_train([]), "", privileged_critic=True)["obs_groups"]["actor"] == ["policy", "critic"]
    assert patched(load_train([]), "", privileged_critic=False)["obs_groups"]["actor"] == ["policy"]
