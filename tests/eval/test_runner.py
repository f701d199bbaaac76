"""Held-out runner: paired scenarios across policies, JSONL/CSV/markdown outputs."""

from __future__ import annotations

import csv
import json

import numpy as np
import pytest

from mjnav.eval.runner import HELD_OUT_BASE, EvalSpec, evaluate_tasks, held_out_seed, parse_args, run_episode

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
