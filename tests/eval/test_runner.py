"""Held-out runner: paired scenarios across policies, JSONL/CSV/markdown outputs."""

from __future__ import annotations

import csv
import json

import numpy as np
import pytest

from mjnav.eval.runner import (
    HELD_OUT_BASE,
    EvalError,
    EvalSpec,
    _results,
    evaluate_tasks,
    held_out_seed,
    main,
    parse_args,
    run_episode,
)

OVERRIDES = ("timing.episode_steps=20",)


@pytest.fixture(scope="module")
def env():
    from mjnav.envs.gym_env import NavGymEnv

    env = NavGymEnv("stage5", overrides=list(OVERRIDES), seed=0)
    yield env
    env.close()


def test_held_out_seeds_are_disjoint_from_training(env):
    """Held-out seeds lie above every episode seed an environment draws for training."""
    from mjnav.tasks.nav import TRAINING_SEED_LIMIT

    assert held_out_seed(0) == HELD_OUT_BASE > TRAINING_SEED_LIMIT
    assert held_out_seed(5, seed_offset=10) == HELD_OUT_BASE + 15
    drawn = []
    for k in range(20):
        env.reset(seed=k) if k % 2 else env.reset()
        drawn.append(env.task.episode_seed)
    assert max(drawn) < TRAINING_SEED_LIMIT < held_out_seed(0)


def test_two_policies_see_the_same_scenarios(env):
    """The same held-out seed gives the same layout and the same crowd motion for different policies."""
    from mjnav.eval.policies import load_policy

    seed = held_out_seed(3)
    layouts, peds = [], []
    for name in ("mpc_goal", "random_jerk"):
        _, _, trace = run_episode(env, load_policy(name), seed)
        layouts.append(env.task.layout)
        peds.append(np.asarray(trace.pedestrians))
    assert layouts[0] == layouts[1]
    common = min(len(peds[0]), len(peds[1]))
    assert common > 1
    np.testing.assert_array_equal(peds[0][:common], peds[1][:common])


def test_evaluate_writes_jsonl_csv_markdown(tmp_path):
    """Two policies × 3 episodes: one JSON line per episode with paired seeds, a summary per task."""
    lines = {}
    for name in ("mpc_goal", "dwa"):
        out = tmp_path / name
        rows = evaluate_tasks([EvalSpec("stage5", name, 3, 0, OVERRIDES, 1)], out, progress=False)
        assert rows[0]["policy"] == name and rows[0]["episodes"] == 3
        lines[name] = [json.loads(x) for x in (out / "stage5.jsonl").read_text().splitlines()]
        assert (out / "summary.md").read_text().count("| stage5 |") == 1
        with open(out / "summary.csv", encoding="utf-8") as f:
            assert next(csv.DictReader(f))["task"] == "stage5"
    for a, b in zip(lines["mpc_goal"], lines["dwa"]):
        assert a["seed"] == b["seed"] and a["start"] == b["start"] and a["goal"] == b["goal"]
    first = lines["mpc_goal"][0]
    assert {"seed", "outcome", "metrics", "policy", "task", "task_version", "commit"} <= set(first)


def test_parse_args_multi_task():
    """tasks= gives one spec per stage; task.KEY=VALUE become overrides."""
    argv = ["tasks=stage5,stage6", "policy=teb", "episodes=7", "workers=1", "task.crowd.count=3"]
    specs, out = parse_args(argv)
    assert [s.task for s in specs] == ["stage5", "stage6"]
    assert specs[0].episodes == 7 and specs[0].overrides == ("crowd.count=3",)
    assert out.name == "teb"
    with pytest.raises(ValueError):
        parse_args(["task=stage5"])
    with pytest.raises(ValueError, match="episodes: must be >= 1"):
        parse_args(["task=stage5", "policy=teb", "episodes=0"])
    with pytest.raises(ValueError, match="workers: expected an integer"):
        parse_args(["task=stage5", "policy=teb", "workers=two"])


@pytest.mark.parametrize("workers", [1, 2])
def test_unloadable_policy_is_one_error_line_not_a_hang(tmp_path, capsys, workers):
    """A file that is no policy fails before any episode, in one line (a Pool used to respawn forever)."""
    bogus = tmp_path / "policy.pt"
    bogus.write_text("not a torch file")
    argv = ["task=stage5", f"policy={bogus}", "episodes=2", f"workers={workers}", f"out={tmp_path / 'out'}"]
    assert main(argv) == 2
    err = capsys.readouterr().err
    assert err.startswith("error: ") and "not a loadable TorchScript policy.pt" in err
    assert not (tmp_path / "out").exists()


def test_worker_setup_failure_reaches_the_parent(tmp_path):
    """A worker whose setup fails reports the error through its first task instead of being respawned."""
    spec = EvalSpec("stage5", "mpc_goal", 2, 0, ("crowd.bogus=1",), 2)
    with pytest.raises(EvalError, match="crowd.bogus"):
        list(_results(spec))


def test_bad_task_is_one_error_line(capsys):
    assert main(["task=stage9", "policy=mpc_goal", "episodes=1", "workers=1"]) == 2
    assert capsys.readouterr().err.startswith("error: unknown task 'stage9'")
