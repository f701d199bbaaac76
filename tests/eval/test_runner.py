"""Held-out runner: paired scenarios across policies, JSONL/CSV/markdown outputs."""

from __future__ import annotations

import csv
import json
import multiprocessing
import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pytest

from mjnav.eval import runner
from mjnav.eval.policies import load_policy
from mjnav.planners import dwa, mpc_goal, teb
from mjnav.eval.runner import (
    HELD_OUT_BASE,
    EvalError,
    EvalSpec,
    _results,
    evaluate,
    evaluate_tasks,
    held_out_seed,
    main,
    parse_args,
    run_episode,
)

from mjnav.schema import ConfigError
from tests.eval._same import records, summary

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
    specs, out, from_contact = parse_args(argv)
    assert [s.task for s in specs] == ["stage5", "stage6"] and from_contact is None
    assert specs[0].episodes == 7 and specs[0].overrides == ("crowd.count=3",)
    assert out.name == "teb"
    with pytest.raises(ValueError):
        parse_args(["task=stage5"])
    with pytest.raises(ValueError, match="episodes: must be >= 1"):
        parse_args(["task=stage5", "policy=teb", "episodes=0"])
    with pytest.raises(ValueError, match="workers: expected an integer"):
        parse_args(["task=stage5", "policy=teb", "workers=two"])
    with pytest.raises(ValueError, match="from_contact: no such folder"):
        parse_args(["task=stage5", "policy=teb", "from_contact=/nonexistent/evals"])


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
    """A worker whose setup fails reports the error through its first task instead of being respawned,
    and the worker processes are gone when the error arrives."""
    spec = EvalSpec("stage5", "mpc_goal", 2, 0, ("crowd.bogus=1",), 2)
    with pytest.raises(EvalError, match="crowd.bogus"):
        list(_results(spec, range(spec.episodes)))
    assert multiprocessing.active_children() == []


def test_two_local_workers_give_the_records_of_one(tmp_path):
    """Episodes spread over worker processes in chunks give the in-process records, episode for episode."""
    spec = EvalSpec("stage5", "mpc_goal", 5, 0, OVERRIDES, 1)
    evaluate_tasks([spec], tmp_path / "one", progress=False)
    evaluate_tasks([EvalSpec(**{**spec.__dict__, "workers": 2})], tmp_path / "two", progress=False)
    assert records(tmp_path / "two" / "stage5.jsonl") == records(tmp_path / "one" / "stage5.jsonl")
    assert summary(tmp_path / "two" / "summary.csv") == summary(tmp_path / "one" / "summary.csv")


def test_closing_the_stream_early_ends_the_workers():
    """A consumer that stops early (an error writing the JSONL, Ctrl-C) ends the evaluation: the
    pending chunks are dropped, the running ones end and no worker process is left."""
    stream = _results(EvalSpec("stage5", "mpc_goal", 40, 0, OVERRIDES, 2), range(40))
    first = next(stream)
    stream.close()
    assert first["index"] in range(40)
    assert multiprocessing.active_children() == []


@pytest.mark.skipif(not Path("/proc/self/task").is_dir(), reason="reads child processes from /proc")
def test_workers_end_when_the_evaluation_is_killed(tmp_path):
    """SIGKILL (a batch system's time limit) runs no cleanup in the parent; its workers exit by themselves."""
    script = ("import sys; from mjnav.eval.runner import EvalSpec, evaluate; "
              f"evaluate(EvalSpec('stage5', 'mpc_goal', 400, 0, {OVERRIDES!r}, 2), sys.argv[1], progress=False)")
    parent = subprocess.Popen([sys.executable, "-c", script, str(tmp_path)], cwd=Path(__file__).parents[2])
    try:
        jsonl = tmp_path / "stage5.jsonl"
        deadline = time.monotonic() + 120
        while not (jsonl.is_file() and jsonl.stat().st_size) and time.monotonic() < deadline:  # workers busy
            time.sleep(0.2)
        workers = _children(parent.pid)
        assert len(workers) >= 2 and parent.poll() is None
    finally:
        parent.kill()
        parent.wait()
    deadline = time.monotonic() + 20
    while _alive(workers) and time.monotonic() < deadline:
        time.sleep(0.1)
    left = _alive(workers)
    for pid in left:  # not to leave them running if this fails
        os.kill(pid, signal.SIGKILL)
    assert left == []


def _children(pid: int) -> list[int]:
    """The child processes of ``pid`` (its workers and multiprocessing's resource tracker)."""
    return [int(c) for t in Path(f"/proc/{pid}/task").iterdir() for c in (t / "children").read_text().split()]


def _alive(pids: list[int]) -> list[int]:
    """Those of ``pids`` still running (not gone, not zombies)."""
    def state(pid: int) -> str:
        try:
            return Path(f"/proc/{pid}/stat").read_text().rsplit(")", 1)[1].split()[0]
        except FileNotFoundError:
            return "gone"
    return [pid for pid in pids if state(pid) not in ("gone", "Z")]


def test_bad_task_is_one_error_line(capsys):
    assert main(["task=stage9", "policy=mpc_goal", "episodes=1", "workers=1"]) == 2
    assert capsys.readouterr().err.startswith("error: unknown task 'stage9'")


def test_interrupted_evaluation_resumes_without_duplicates(tmp_path):
    """A JSONL cut short (with a truncated last line and a duplicate) is completed, not redone;
    a file from another evaluation is refused and left as it is."""
    spec = EvalSpec("stage5", "mpc_goal", 4, 0, OVERRIDES, 1)
    evaluate(spec, tmp_path, progress=False)
    path = tmp_path / "stage5.jsonl"
    full = path.read_text().splitlines()
    path.write_text("\n".join([full[1], full[1], full[2][:40]]) + "\n")  # index 1 twice, index 2 cut
    calls = []
    original = runner._results
    try:
        runner._results = lambda s, todo: (calls.append(list(todo)), original(s, todo))[1]
        evaluate(spec, tmp_path, progress=False)
    finally:
        runner._results = original
    assert calls == [[0, 2, 3]]
    records = [json.loads(x) for x in path.read_text().splitlines()]
    assert [r["index"] for r in records] == [0, 1, 2, 3]
    assert [r["outcome"] for r in records] == [json.loads(x)["outcome"] for x in full]
    other = EvalSpec("stage5", "mpc_goal", 4, 0, (*OVERRIDES, "crowd.count=3"), 1)
    before = path.read_bytes()
    with pytest.raises(EvalError, match="overrides.*out="):
        evaluate(other, tmp_path, progress=False)
    assert path.read_bytes() == before


def test_planner_overrides_and_tuning_scenarios(tmp_path):
    """planner.KEY=VALUE reaches the baseline's config and the JSONL; a typo or a planner without
    parameters is an error; the tuning scenarios lie outside every evaluation set."""
    specs, _, _ = parse_args(["task=stage5", "policy=dwa", "planner.w_clearance=0.8", "episodes=1", "workers=1"])
    assert specs[0].planner == ("w_clearance=0.8",)
    agent = load_policy("dwa", planner=specs[0].planner)
    assert agent.planner.planner.config.w_clearance == 0.8
    with pytest.raises(ConfigError, match="w_clearnce"):
        load_policy("teb", planner=("w_clearnce=1",))
    with pytest.raises(ConfigError, match="random_jerk has no parameters"):
        load_policy("random_jerk", planner=("safety=1",))
    with pytest.raises(ConfigError, match="safety"):  # mpc_goal's parameters are its tracks only
        load_policy("mpc_goal", planner=("safety=1",))
    assert runner.held_out_seed(0, runner.TUNING_SEED_OFFSET) > runner.held_out_seed(10**8)  # eval and dev sets
    for module in (dwa, teb, mpc_goal):
        assert "TUNING_SEED_OFFSET" in module.__doc__ and "777" not in module.__doc__


def test_from_contact_settles_on_the_command_line(tmp_path, capsys):
    """evaluate.py from_contact=DIR takes what the contact run settles and plays only the rest;
    settling again never duplicates; a contact-rule evaluation or other records are refused or unused."""
    common = ["task=stage2", "policy=mpc_goal", "episodes=4", "workers=1", "task.timing.episode_steps=60"]
    assert runner.main([*common, "task.collision=contact", f"out={tmp_path / 'contact'}"]) == 0
    calls = []
    original = runner._results
    try:
        runner._results = lambda s, todo: (calls.append(list(todo)), original(s, todo))[1]
        for _ in range(2):
            assert runner.main([*common, "task.collision=scan", f"from_contact={tmp_path / 'contact'}",
                                f"out={tmp_path / 'scan'}"]) == 0
    finally:
        runner._results = original
    settled = [r for r in runner.read_jsonl(tmp_path / "scan" / "stage2.jsonl") if r.get("derived_from") == "contact"]
    contact = runner.read_jsonl(tmp_path / "contact" / "stage2.jsonl")
    assert len(settled) == sum(r["paper_rule"] is not None for r in contact) >= 3
    assert len(runner.read_jsonl(tmp_path / "scan" / "stage2.jsonl")) == 4
    assert calls[0] == sorted(set(range(4)) - {r["index"] for r in settled}) and calls[1] == []
    err = capsys.readouterr().err
    assert f"{len(settled)} of 4 episodes settled by" in err
    assert runner.main([*common, "task.collision=contact", f"from_contact={tmp_path / 'contact'}",
                        f"out={tmp_path / 'again'}"]) == 2
    assert "must use task.collision=scan" in capsys.readouterr().err
    other = EvalSpec("stage2", "mpc_goal", 4, 0, ("timing.episode_steps=50", "collision=scan"), 1)
    assert runner.settle_from_contact(other, tmp_path / "contact", tmp_path / "other") == 0
    assert "not a contact run of this policy" in capsys.readouterr().err


@pytest.mark.parametrize("policy", ["mpc_goal", "dwa"])
def test_contact_run_settles_the_paper_rule_exactly(tmp_path, policy):
    """Episodes the contact run settles under the paper's rule match a direct run of that rule, metrics
    and all; the paper's-rule run then plays only the rest; another evaluation's records are not used."""
    common = ("timing.episode_steps=150", "region.on_failure=paper")
    contact = EvalSpec("stage2", policy, 8, 0, (*common, "collision=contact"), 1)
    scan = EvalSpec("stage2", policy, 8, 0, (*common, "collision=scan"), 1)
    evaluate(contact, tmp_path / "contact", progress=False)
    evaluate(scan, tmp_path / "direct", progress=False)
    direct = {r["index"]: r for r in runner.read_jsonl(tmp_path / "direct" / "stage2.jsonl")}
    contact_rows = runner.read_jsonl(tmp_path / "contact" / "stage2.jsonl")
    settled = runner.seed_paper_rule(tmp_path / "contact" / "stage2.jsonl", scan, tmp_path / "derived")
    derived = runner.read_jsonl(tmp_path / "derived" / "stage2.jsonl")
    assert settled == len(derived) == sum(r["paper_rule"] is not None for r in contact_rows) >= 6
    by_index = {c["index"]: c for c in contact_rows}
    cut = [r["index"] for r in derived if r["outcome"] == "collision" != by_index[r["index"]]["outcome"]]
    assert cut or policy == "dwa"  # mpc_goal comes within R_inf of obstacles; DWA (a baseline) keeps clear
    for r in derived:  # all but the wall-clock solve times, of which there are as many
        mine, theirs = dict(r["metrics"]), dict(direct[r["index"]]["metrics"])
        assert len(mine.pop("solve_times_ms")) == len(theirs.pop("solve_times_ms"))
        assert (r["outcome"], mine) == (direct[r["index"]]["outcome"], theirs)
        same = ("collision_kind", "social")  # what was hit (shortest beam's object) and the social metrics too
        assert [r[k] for k in same] == [direct[r["index"]][k] for k in same]
        assert (r["collision_kind"] is not None) == (r["outcome"] == "collision")
    calls = []
    original = runner._results
    try:
        runner._results = lambda s, todo: (calls.append(list(todo)), original(s, todo))[1]
        evaluate(scan, tmp_path / "derived", progress=False)
    finally:
        runner._results = original
    assert calls == [sorted(set(range(8)) - {r["index"] for r in derived})]
    final = runner.read_jsonl(tmp_path / "derived" / "stage2.jsonl")
    assert [r["outcome"] for r in final] == [direct[i]["outcome"] for i in range(8)]
    other = EvalSpec("stage2", policy, 8, 0, ("timing.episode_steps=100", "collision=scan"), 1)
    assert runner.seed_paper_rule(tmp_path / "contact" / "stage2.jsonl", other, tmp_path / "other") == 0


def test_a_later_task_in_the_same_folder_keeps_the_earlier_rows(tmp_path):
    """The summary gets a row per task evaluated into the folder; re-evaluating a task replaces its row."""
    stage5 = EvalSpec("stage5", "mpc_goal", 1, 0, OVERRIDES, 1)
    evaluate_tasks([stage5], tmp_path, progress=False)
    first = (tmp_path / "summary.csv").read_text().splitlines()
    evaluate_tasks([EvalSpec("stage2", "mpc_goal", 1, 0, OVERRIDES, 1)], tmp_path, progress=False)
    evaluate_tasks([EvalSpec(**{**stage5.__dict__, "episodes": 2})], tmp_path, progress=False)
    rows = list(csv.DictReader((tmp_path / "summary.csv").open()))
    assert [(r["task"], float(r["episodes"])) for r in rows] == [("stage5", 2), ("stage2", 1)]
    assert first[1].startswith("stage5,mpc_goal,")
    table = (tmp_path / "summary.md").read_text().splitlines()
    assert [line.split(" | ")[0] for line in table[2:]] == ["| stage5", "| stage2"]


def test_two_task_files_of_one_name_are_two_evaluations(tmp_path):
    """A task is named by its file's stem; its resolved config's hash tells two ``stage5.yaml`` apart."""
    other = tmp_path / "mine" / "stage5.yaml"
    other.parent.mkdir()
    other.write_text("extends: stage5\ncrowd:\n  count: 3\n")
    evaluate_tasks([EvalSpec("stage5", "mpc_goal", 1, 0, OVERRIDES, 1)], tmp_path / "out", progress=False)
    with pytest.raises(EvalError, match="task_sha256"):
        evaluate_tasks([EvalSpec(str(other), "mpc_goal", 1, 0, OVERRIDES, 1)], tmp_path / "out", progress=False)
