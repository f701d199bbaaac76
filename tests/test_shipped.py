"""Shipped policies through policies/manifest.yaml and tasks/recipes: names, checksums, recipes, retraining."""

from __future__ import annotations

import re
import shutil
from pathlib import Path

import pytest
import torch

from mjnav import shipped
from mjnav.eval.policies import load_policy
from mjnav.policy import training_overrides
from mjnav.resources import policies_dir
from mjnav.schema import ConfigError
from mjnav.train import session

PACKAGE = Path(__file__).parents[1] / "mjnav"


def test_every_manifest_entry_checks_out() -> None:
    """Each shipped file exists with its manifest SHA-256 and each entry has a loadable recipe."""
    for name in shipped.names():
        entry = shipped.get(name)
        assert entry.path().is_file() and entry.tables
        recipe = shipped.load_recipe(entry.recipe)
        assert recipe.task.startswith("stage") and (recipe.start is None or recipe.start in shipped.names())
        if entry.weights:
            state = torch.load(entry.weights_path(), map_location="cpu", weights_only=True)
            assert set(state) >= {"actor_state_dict", "critic_state_dict"} and "optimizer_state_dict" not in state
            assert "distribution.log_std_param" in state["actor_state_dict"]


def test_recipe_starts_are_shipped_with_weights() -> None:
    """A recipe's start and start=auto's previous-stage policies all ship weights-only checkpoints."""
    starts = {shipped.load_recipe(shipped.get(n).recipe).start for n in shipped.names()} - {None}
    stages = {shipped.get(n).name for n in shipped.names() if shipped.get(n).stage not in (None, "stage7")}
    assert all(shipped.get(name).weights for name in starts | stages)


def test_a_shipped_name_is_a_policy() -> None:
    """policy=stage6_policy loads the shipped actor and evaluation takes its recipe's task overrides."""
    agent = load_policy("stage6_policy")
    assert agent.kind == "learned" and agent.input_size == 399
    assert training_overrides("stage6_policy") == shipped.load_recipe("stage6_policy").task_overrides
    assert load_policy("stage5_policy.weights", mode="sample").kind == "learned"


def test_checksum_mismatch_is_a_clear_error(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    """An altered shipped file is refused, naming the file and the manifest."""
    folder = tmp_path / "policies"
    folder.mkdir()
    shutil.copy(policies_dir() / "manifest.yaml", folder)
    shutil.copy(policies_dir() / "stage6_policy.pt", folder)
    with open(folder / "stage6_policy.pt", "ab") as f:
        f.write(b"\0")
    monkeypatch.setattr(shipped, "policies_dir", lambda: folder)
    with pytest.raises(shipped.ShippedError, match=r"checksum mismatch for .*stage6_policy\.pt.*manifest"):
        load_policy("stage6_policy")
    with pytest.raises(shipped.ShippedError, match="is missing"):
        shipped.resolve("stage7_policy")


def test_unknown_names_are_named() -> None:
    """A misspelt shipped policy or recipe lists the known names and the closest."""
    with pytest.raises(shipped.ShippedError, match="closest: stage6_policy"):
        shipped.get("stage6_polcy")
    with pytest.raises(ConfigError, match="unknown recipe 'stage9_policy'"):
        session.plan_run(session.parse_args(["recipe=stage9_policy"]))
    with pytest.raises(ConfigError, match="cannot be combined"):
        session.plan_run(session.parse_args(["recipe=stage6_policy", "task=stage5"]))


def test_retrain_from_a_recipe(tmp_path: Path) -> None:
    """recipe=stage6_policy trains stage 6 from stage5_policy's weights with the recipe's overrides and
    writes the exported actor and a weights-only checkpoint that init= takes."""
    tiny = ["train.iterations=1", "train.num_envs=2", "train.steps_per_env=8", "train.minibatches=1",
            "train.epochs=1", "train.workers=0", f"out={tmp_path}"]
    run_dir = session.run(["recipe=stage6_policy", *tiny])
    weights = torch.load(run_dir / "checkpoint_weights.pt", map_location="cpu", weights_only=True)
    assert set(weights) == {"actor_state_dict", "critic_state_dict", "iter"}
    assert (run_dir / "policy.pt").is_file()
    saved = (run_dir / "config.yaml").read_text()
    assert "stage5_weights.pt" in saved and "observation.frame=goal" in saved
    plan = session.plan_run(session.parse_args(["task=stage6", f"init={run_dir / 'checkpoint_weights.pt'}"]))
    assert plan.init == run_dir / "checkpoint_weights.pt"


def test_the_package_never_reads_docs() -> None:
    """No module under mjnav/ refers to docs/ (code, strings or docstrings)."""
    found = [f"{path.relative_to(PACKAGE.parent)}:{i}" for path in sorted(PACKAGE.rglob("*.py"))
             for i, line in enumerate(path.read_text(encoding="utf-8").splitlines(), 1)
             if re.search(r"docs/|[\"']docs[\"']", line)]
    assert found == []


def test_a_name_sharing_an_actor_file_keeps_its_own_recipe() -> None:
    """stage6_tracks_policy ships stage6_policy's actor file: its name, not the file, picks the recipe,
    so evaluating it turns the crowd shield on and evaluating Ours does not."""
    from mjnav.policy import training_overrides

    assert shipped.get("stage6_tracks_policy").file == shipped.get("stage6_policy").file
    assert "shield.enabled=true" in training_overrides("stage6_tracks_policy")
    assert "shield.enabled=true" not in training_overrides("stage6_policy")
    assert training_overrides(str(shipped.get("stage6_policy").path())) == training_overrides("stage6_policy")
