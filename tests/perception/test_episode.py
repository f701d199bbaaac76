"""The tracker on a real short episode: mpc_goal through the Gymnasium environment, scored against the sim."""

from __future__ import annotations

import pytest

from mjnav.bench.tracker import measure_stage
from mjnav.cli import main


def test_real_stage5_episode_recall() -> None:
    """On a short stage-5 episode (training seed 0), most pedestrians near the robot in line of sight are tracked."""
    row = measure_stage("stage5", episodes=1, seed=0, max_steps=60)
    assert row["steps"] > 10
    assert row["recall_near_los"] >= 0.8
    assert row["precision"] >= 0.6
    assert row["pos_rmse"] < 0.15


def test_held_out_seeds_are_refused() -> None:
    """The bench never runs the held-out evaluation seeds (2**32 + i)."""
    with pytest.raises(ValueError, match="training range"):
        measure_stage("stage5", episodes=2, seed=2**32 - 1, max_steps=5)


def test_bench_tracker_help(capsys: pytest.CaptureFixture[str]) -> None:
    """``mjnav bench tracker --help`` lists its keys."""
    assert main(["bench", "tracker", "--help"]) == 0
    out = capsys.readouterr().out
    assert "episodes" in out and "max_steps" in out
