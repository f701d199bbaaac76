"""mjnav.bench.collect (``mjnav bench collect``): the collection profile adds up and prints the ratios."""

import dataclasses

import numpy as np
import pytest

from mjnav.bench import collect
from mjnav.cli import main
from mjnav.config import load_task
from mjnav.train.config import load_train

TINY = ["num_envs=4", "steps_per_env=4", "epochs=1", "minibatches=1", "update_threads=1"]


@pytest.mark.parametrize("rollouts", [False, True])
def test_step_parts_add_up_to_the_collection_time(tmp_path, rollouts: bool) -> None:
    """The parts of a rollout step add up to rsl-rl's collection time; the worker process is timed,
    and with worker rollouts the rollout is split into this process's own block and the rest."""
    train = dataclasses.replace(load_train(["num_envs=8", *TINY[1:]]), workers=2, rollouts=rollouts)
    bench = collect.CollectBench(load_task("stage1"), train, str(tmp_path))
    try:
        assert bench.iterations == 0 and not bench.seconds  # the warm-up iteration is not counted
        assert bench.block() == 32
        parts = bench.step_parts()
    finally:
        bench.close()
    assert list(parts) == list(collect.STEP_PARTS)
    assert bench.seconds["steps"] == 4
    assert (bench.seconds["rollout"] > 0) == rollouts
    assert np.isclose(sum(parts.values()), 1e3 * bench.seconds["collection"] / 4)
    assert parts["policy"] > 0 and parts["own block"] > 0 and bench.seconds["worker_step"] > 0
    assert all(value >= 0 for name, value in parts.items() if name != "rest")
    assert bench.seconds["update"] > 0
    trainer, worker, rate = bench.cpu_estimate()
    assert 0 < trainer <= 1e3 * bench.seconds["collection"] / 4 * 1.5 and worker > 0
    assert np.isclose(rate, 1e3 * 8 / max(trainer, worker))


def test_cli_prints_rates_ratios_and_parts(capsys: pytest.CaptureFixture) -> None:
    argv = ["bench", "collect", "task=stage1", "workers=1,2", "main_envs=-1,1", "pipeline=true,false",
            "rollouts=true,false", "rollout_envs=2,0", "rounds=1", "single_steps=5", *(f"train.{t}" for t in TINY)]
    assert main(argv) == 0
    out = capsys.readouterr().out
    assert out.count("| 1, parts of 2 | ") == 5 and out.count("| 2, parts of 0 | ") == 5  # five tables
    assert out.count("| 2, main 1, parts of 2 | ") == 5
    assert out.count("| 2, rsl-rl order | ") == 5 and out.count("| 2, main 1, rsl-rl order | ") == 5
    assert out.count("| 2, step by step | ") == 5 and out.count("| 1, step by step | ") == 5
    assert "| 1, parts of 2 | 1.00 (1.00-1.00) | 1.00 (1.00-1.00) | " in out and "paired by round" in out
    assert "x one environment" in out and "PPO update" in out and "estimate on cores of their own" in out


@pytest.mark.parametrize(("arg", "key"), [("workers=1,0", "workers"), ("main_envs=x", "main_envs"),
                                          ("main_envs=64", "main_envs"), ("pipeline=yes", "pipeline"),
                                          ("rollouts=maybe", "rollouts"),
                                          ("rollout_envs=-1", "rollout_envs"), ("rollout_envs=a", "rollout_envs")])
def test_bad_list_is_one_error_line(capsys: pytest.CaptureFixture, arg: str, key: str) -> None:
    assert main(["bench", "collect", arg]) == 2
    err = capsys.readouterr().err
    assert err.startswith("error:") and key in err


def test_paired_ratios_are_taken_round_by_round() -> None:
    """Rounds in which the host slows every configuration alike leave the paired ratio alone, where
    the ratio of medians moves."""
    first = np.array([100.0, 100.0, 50.0])  # round 2: the second configuration alone is slow; round 3: the host
    second = np.array([180.0, 90.0, 90.0])
    assert collect._paired(second, first) == "1.80 (0.90-1.80)"
    assert np.median(second) / np.median(first) == pytest.approx(0.9)
