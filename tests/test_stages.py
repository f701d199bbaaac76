"""Stage ids come from the YAML files: a new tasks/stage8.yaml is a task, a Gymnasium id and a curriculum stage."""

from __future__ import annotations

import shutil
from collections.abc import Iterator
from pathlib import Path

import gymnasium as gym
import numpy as np
import pytest

from mjnav import stages
from mjnav.config import load_task
from mjnav.envs.registration import ENV_IDS, register_envs
from mjnav.registry import RegistryError
from mjnav.resources import TASKS_ENV, tasks_dir
from mjnav.train.config import CurriculumConfig, load_train


@pytest.fixture
def stage8_tasks(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> Iterator[Path]:
    """A copy of the tasks folder with a stage8.yaml (stage 5 with 25 pedestrians), made the tasks folder."""
    folder = tmp_path / "tasks"
    shutil.copytree(tasks_dir(), folder, ignore=shutil.ignore_patterns("recipes"))
    (folder / "stage8.yaml").write_text("# Stage 8: stage 5 with 25 pedestrians.\n"
                                        "extends: stage5\ncrowd:\n  count: 25\n")
    monkeypatch.setenv(TASKS_ENV, str(folder))
    yield folder
    gym.registry.pop("mjnav/Stage8-v1", None)  # later tests see the shipped stages only


def test_shipped_stages_are_the_files() -> None:
    """Without an override the stages are stage1..stage7, one Gymnasium id each."""
    assert stages.stage_numbers() == list(range(1, 8))
    assert ENV_IDS == tuple(f"mjnav/Stage{n}-v1" for n in range(1, 8))


def test_stage8_from_one_file(stage8_tasks: Path) -> None:
    """stage8.yaml alone makes task=stage8, mjnav/Stage8-v1 and the curriculum's eighth stage."""
    assert load_task("stage8").crowd.count == 25
    assert stages.load_stage("stage8", ["crowd.count=3"]).crowd.count == 3
    assert "mjnav/Stage8-v1" in register_envs()
    env = gym.make("mjnav/Stage8-v1")
    try:
        env.reset(seed=0)
        env.step(np.zeros(env.action_space.shape, np.float32))
        assert env.unwrapped.config.name == "stage8"
    finally:
        env.close()
    assert stages.stage_numbers() == list(range(1, 9)) and stages.next_stage(7) == 8
    assert CurriculumConfig().stages() == list(range(1, 9))
    assert load_train(["curriculum.first_stage=8"]).curriculum.first_stage == 8


def test_unknown_stage_is_named() -> None:
    """A stage number without a file is refused with the known stages listed."""
    with pytest.raises(RegistryError, match="closest"):
        stages.stage_name(9)
    with pytest.raises(Exception, match="stage9"):
        CurriculumConfig(last_stage=9)


def test_removed_file_leaves_the_registry(stage8_tasks: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    """The registry follows the folder: after the override is lifted stage8 is gone again."""
    assert "stage8" in stages.stage_names()
    monkeypatch.delenv(TASKS_ENV)
    assert "stage8" not in stages.stage_names()
