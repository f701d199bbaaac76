"""``mjnav sweep``: the grid's cells (overrides × seeds), each trained then evaluated in its own
folder, one table with the mean and 95 % interval over seeds, done cells skipped on a restart."""

from __future__ import annotations

import contextlib
import json
import math
import os
import signal
import socket
import subprocess
import sys
import time
from collections.abc import Sequence
from pathlib import Path

import pytest
import yaml

from mjnav.args import parse
from mjnav.cli import main
from mjnav.jobs import holding, usable_cores
from mjnav.train.runner import checkpoints
from mjnav.verbs import sweep

TINY = ["task=stage1", "train.iterations=1", "train.num_envs=2", "train.steps_per_env=8", "train.workers=0",
        "train.epochs=1", "train.minibatches=1", "train.policy.actor_hidden_dims=[16,16,16]",
        "train.policy.critic_hidden_dims=[16,16,16]", "timing.episode_steps=20", "episodes=2", "workers=1"]


def _cells(argv: list[str]) -> list[sweep.Cell]:
    return sweep.cells(parse(argv, sweep.grammar()), argv)


def test_the_grid_is_every_combination_checked_before_any_run(tmp_path: Path) -> None:
    argv = ["task=stage2", "grid=task.design=design1,design2", "grid=train.entropy=0.005,0.01", "seeds=0,1,2",
            "crowd.count=3", f"out={tmp_path}"]
    cells = _cells(argv)
    assert len(cells) == 2 * 2 * 3
    first = cells[0]
    assert first.point == (("task.design", "design1"), ("train.entropy", "0.005")) and first.seed == 0
    assert first.folder == tmp_path / "design-design1_entropy-0.005_seed-0"
    assert first.train == ("task=stage2", "start=scratch", "task.crowd.count=3", "task.design=design1",
                           "train.entropy=0.005", "seed=0")
    assert first.evaluate == ("task=stage2", "episodes=100", f"workers={usable_cores()}")
    assert len({c.folder for c in cells}) == len(cells)


def test_a_ray_cell_uses_only_the_cpus_it_reserves(tmp_path: Path) -> None:
    argv = ["task=stage2", "seeds=0", "backend=ray", "cpus_per_run=2", f"out={tmp_path}"]
    cell = _cells(argv)[0]
    assert cell.train[-3:-1] == ("train.workers=2", "train.update_threads=2")
    assert cell.evaluate[-1] == "workers=2"
    given = _cells([*argv, "train.update_threads=1", "workers=3"])[0]
    assert "train.update_threads=1" in given.train and "train.update_threads=2" not in given.train
    assert "train.workers=2" in given.train and given.evaluate[-1] == "workers=3"


@pytest.mark.parametrize(("token", "message"), [
    ("grid=task.design", "grid: expected KEY=V1,V2"),
    ("grid=task.desing=design1", "desing"),
    ("grid=train.entropy=high", "entropy"),
    ("seeds=a,b", "seeds: expected comma-separated integers"),
    ("backend=slurm", "backend: expected one of local, ray"),
    ("address=auto", "address: a Ray cluster address; needs backend=ray"),
    ("seeds=0,0", "seeds: a seed is listed twice"),
    ("grid=crowd.count=3,3", "crowd.count lists a value twice"),
    ("grid=crowd.count=3 grid=task.crowd.count=4", "an override key is given twice"),
    ("grid=crowd.count=3,4 task.crowd.count=5", "task.crowd.count is also given to every run"),
    ("workers=-1", "workers: must be >= 0"),
    ("task=nonexist", "unknown stage 'nonexist'"),
])
def test_a_bad_grid_is_one_error_line_and_runs_nothing(tmp_path, capsys, token, message) -> None:
    assert main(["sweep", "task=stage1", *token.split(), f"out={tmp_path / 's'}"]) == 2
    err = capsys.readouterr().err
    assert err.startswith("error:") and message in err
    assert not (tmp_path / "s").exists()


def _fake_mjnav(calls: list[list[str]], fail: str | None = None):
    """``python -m mjnav`` stand-in: a run folder per train, a summary per evaluate (success = seed / 10)."""
    def fake(args, log: Path) -> int:
        calls.append(list(args))
        log.write_text("fake\n")
        if fail and any(fail in a for a in args):
            return 1
        values = dict(a.split("=", 1) for a in args[1:])
        if args[0] == "train" and "resume" in values:  # the stopped run goes on and ends
            (Path(values["resume"]) / "policy.pt").write_bytes(b"")
        elif args[0] == "train":
            run = Path(values["out"]) / f"stage1-{len(calls)}"
            run.mkdir(parents=True)
            (run / "policy.pt").write_bytes(b"")
            (run / "seed").write_text(values["seed"])
        else:
            seed = int((Path(values["policy"]) / "seed").read_text())
            (Path(values["out"])).mkdir(parents=True, exist_ok=True)
            (Path(values["out"]) / "summary.csv").write_text(
                f"task,policy,success_rate,collision_rate,timeout_rate,time_s,distance_m\n"
                f"stage1,x,{seed / 10},0.1,{0.9 - seed / 10},,5.0\n")
        return 0
    return fake


def test_table_means_and_intervals_over_seeds_and_restart_skips_done(tmp_path, monkeypatch, capsys) -> None:
    calls: list[list[str]] = []
    monkeypatch.setattr(sweep, "_mjnav", _fake_mjnav(calls))
    argv = ["sweep", "task=stage1", "grid=train.entropy=0.005,0.01", "seeds=1,2,3", f"out={tmp_path}"]
    assert main(argv) == 0
    assert len(calls) == 2 * 3 * 2  # train + evaluate per cell
    record = json.loads((tmp_path / "sweep.json").read_text())
    row = record["rows"][0]
    assert row["train.entropy"] == "0.005" and row["seeds"] == [1, 2, 3] and row["failed"] == []
    assert row["success_rate"] == pytest.approx(0.2)
    half = 4.302652729911275 * 0.1 / math.sqrt(3)  # t(0.975, 2) * s / sqrt(n)
    assert (row["success_rate_lo"], row["success_rate_hi"]) == pytest.approx((max(0.2 - half, 0.0), 0.2 + half))  # a rate stops at 0
    assert row["time_s"] is None  # no value: null in the JSON, "–" in the table
    table = (tmp_path / "sweep.md").read_text()
    assert "| train.entropy | seeds | Success (%) |" in table
    assert f"| 0.005 | 1,2,3 | 20.0 [{100 * max(0.2 - half, 0.0):.1f}, {100 * (0.2 + half):.1f}] |" in table
    assert table in capsys.readouterr().out
    cell = (tmp_path / "entropy-0.005_seed-1" / "result.json").read_text()
    assert "NaN" not in cell and json.loads(cell)["summary"]["time_s"] is None  # strict JSON
    # started again: every cell is done, nothing runs, the same table, said so
    calls.clear()
    assert main(argv) == 0 and calls == []
    assert (tmp_path / "sweep.md").read_text() == table
    assert "entropy-0.005_seed-1: done before (its result.json)" in capsys.readouterr().err
    written = (tmp_path / "sweep.json").read_text()
    assert "skipped" not in written and '"file"' not in written


def test_a_failed_cell_is_recorded_and_the_others_go_on(tmp_path, monkeypatch, capsys) -> None:
    calls: list[list[str]] = []
    monkeypatch.setattr(sweep, "_mjnav", _fake_mjnav(calls, fail="seed=2"))
    assert main(["sweep", "task=stage1", "seeds=1,2,3", f"out={tmp_path}"]) == 1
    failed = json.loads((tmp_path / "seed-2" / "failed.json").read_text())
    assert failed["failed"] == "train" and failed["log"].endswith("train.log")
    assert (tmp_path / "seed-3" / "result.json").is_file()
    assert "| 1,3 (1 failed) |" in (tmp_path / "sweep.md").read_text()
    assert "seed-2: failed in train" in capsys.readouterr().err
    # the failed cell runs again on a restart (and only it)
    monkeypatch.setattr(sweep, "_mjnav", _fake_mjnav(calls := []))
    assert main(["sweep", "task=stage1", "seeds=1,2,3", f"out={tmp_path}"]) == 0
    assert [c[0] for c in calls] == ["train", "evaluate"] and not (tmp_path / "seed-2" / "failed.json").exists()


def test_a_short_grid_key_is_its_long_form(tmp_path: Path) -> None:
    short, long = (_cells(["task=stage1", f"grid={k}=3,4", "seeds=0", f"out={tmp_path}"]) for k in
                   ("crowd.count", "task.crowd.count"))
    assert short == long and short[0].point == (("task.crowd.count", "3"),)


def test_a_cell_trained_with_other_arguments_is_refused_before_anything_runs(tmp_path, monkeypatch, capsys) -> None:
    """The folder name (grid point and seed) does not show the overrides given to every run."""
    monkeypatch.setattr(sweep, "_mjnav", _fake_mjnav(calls := []))
    argv = ["sweep", "task=stage1", "seeds=1,2", f"out={tmp_path}"]
    assert main([*argv, "train.iterations=1"]) == 0
    calls.clear()
    assert main([*argv, "train.iterations=3"]) == 2 and calls == []
    err = capsys.readouterr().err
    assert "2 cell(s) hold a run trained with other arguments" in err
    assert "its result.json: train.iterations=1; now: train.iterations=3" in err
    assert json.loads((tmp_path / "seed-1" / "result.json").read_text())["train"][-2] == "train.iterations=1"


def test_a_cell_killed_while_evaluating_is_evaluated_not_trained_again(tmp_path, monkeypatch, capsys) -> None:
    """An earlier call's run is evaluated again (more episodes, or its evaluation cut short); a
    ``result.json`` from before the arguments were recorded is used as it is, and said so."""
    monkeypatch.setattr(sweep, "_mjnav", _fake_mjnav(calls := []))
    argv = ["sweep", "task=stage1", "seeds=1,2", f"out={tmp_path}"]
    assert main(argv) == 0
    runs = sorted(tmp_path.glob("seed-*/stage1-*"))
    (tmp_path / "seed-1" / "result.json").unlink()  # killed while evaluating
    calls.clear()
    assert main(argv) == 0 and [c[0] for c in calls] == ["evaluate"]
    assert calls[0][1] == f"policy={runs[0]}"
    calls.clear()
    assert main([*argv, "episodes=300"]) == 0 and [c[0] for c in calls] == ["evaluate", "evaluate"]
    assert sorted(tmp_path.glob("seed-*/stage1-*")) == runs  # nothing trained again
    old = json.loads((tmp_path / "seed-2" / "result.json").read_text())
    del old["train"], old["evaluate"]
    (tmp_path / "seed-2" / "result.json").write_text(json.dumps(old))
    calls.clear()
    capsys.readouterr()
    assert main([*argv, "episodes=300"]) == 0 and calls == []
    said = capsys.readouterr().err
    assert "seed-2: done before (its result.json), recorded without its arguments: not checked" in said


def _stopped_run(cell: sweep.Cell, train: Sequence[str], *iterations: int) -> Path:
    """A run folder as a stopped ``mjnav train`` leaves it: config.yaml, checkpoints, no policy.pt."""
    run = cell.folder / "stage1-20261207-010203-42-abcd"
    run.mkdir(parents=True)
    (run / "config.yaml").write_text(yaml.safe_dump({"run": {"argv": [*train, f"out={cell.folder}"]}}))
    for it in iterations:
        (run / f"model_{it}.pt").write_bytes(b"")
    (run / "seed").write_text(str(cell.seed))
    return run


def test_a_stopped_training_goes_on_from_its_checkpoint(tmp_path, monkeypatch, capsys) -> None:
    """A sweep stopped while training (SIGTERM, a time limit) resumes that training when started
    again, instead of training the cell from the start."""
    monkeypatch.setattr(sweep, "_mjnav", _fake_mjnav(calls := []))
    argv = ["sweep", "task=stage1", "seeds=1,2", f"out={tmp_path}"]
    first, second = _cells(argv[1:])
    run = _stopped_run(first, first.train, 5, 40, 10)
    _stopped_run(second, second.train)  # stopped before its first checkpoint: trained again
    assert main(argv) == 0
    assert [c[:2] for c in calls[:2]] == [["train", f"resume={run}"], ["evaluate", f"policy={run}"]]
    assert [c[0] for c in calls[2:]] == ["train", "evaluate"] and calls[2][1] == "task=stage1"
    result = json.loads((first.folder / "result.json").read_text())
    assert result["run"] == str(run) and result["resumed"] == "model_40.pt"
    assert json.loads((first.folder / "trained.json").read_text())["resumed"] == "model_40.pt"
    assert "seed-1: done (its stopped training went on from model_40.pt)" in capsys.readouterr().err
    calls.clear()
    assert main([*argv, "episodes=300"]) == 0 and [c[0] for c in calls] == ["evaluate", "evaluate"]
    said = capsys.readouterr().err
    assert "seed-1: done\n" in said and "went on" not in said  # said once, when it went on
    assert json.loads((first.folder / "result.json").read_text())["resumed"] == "model_40.pt"


def test_a_cell_another_process_is_training_is_left_out(tmp_path, monkeypatch, capsys) -> None:
    """A second sweep on the same ``out`` does not resume (or train again) a training that is still
    running: the run folder's lock is held by a live process."""
    monkeypatch.setattr(sweep, "_mjnav", _fake_mjnav(calls := []))
    argv = ["sweep", "task=stage1", "seeds=1,2", f"out={tmp_path}"]
    first, _ = _cells(argv[1:])
    run = _stopped_run(first, first.train, 50)
    with holding(run):
        assert main(argv) == 1
    assert [c[0] for c in calls] == ["train", "evaluate"] and "seed=2" in calls[0]
    me = f"{os.getpid()} on {socket.gethostname()}"
    assert f"seed-1: left out: {run} is being trained by another process (pid {me})" in capsys.readouterr().err
    assert not (first.folder / "failed.json").exists()
    assert "| 2 (1 left out: running elsewhere) |" in (tmp_path / "sweep.md").read_text()
    calls.clear()
    assert main(argv) == 0 and [c[:2] for c in calls[:1]] == [["train", f"resume={run}"]]  # once it has ended


def test_a_cell_another_sweep_is_running_is_left_out(tmp_path, monkeypatch, capsys) -> None:
    """Two sweeps on one ``out``: the cell a live sweep holds (training, or evaluating after its
    training released the run folder) is neither trained nor evaluated by the other."""
    monkeypatch.setattr(sweep, "_mjnav", _fake_mjnav(calls := []))
    argv = ["sweep", "task=stage1", "seeds=1,2", f"out={tmp_path}"]
    first, _ = _cells(argv[1:])
    first.folder.mkdir(parents=True)
    with holding(first.folder):
        assert main(argv) == 1
    assert [c[0] for c in calls] == ["train", "evaluate"] and "seed=2" in calls[0]
    me = f"{os.getpid()} on {socket.gethostname()}"
    assert f"seed-1: left out: another process (pid {me}) is running this cell" in capsys.readouterr().err
    assert not [*tmp_path.rglob("*.partial"), *tmp_path.rglob(".*.tmp")]  # written whole, then renamed


def test_a_cell_that_cannot_be_locked_is_a_failed_cell(tmp_path, monkeypatch, capsys) -> None:
    monkeypatch.setattr(sweep, "_mjnav", _fake_mjnav(calls := []))
    argv = ["sweep", "task=stage1", "seeds=1,2", f"out={tmp_path}"]
    first, _ = _cells(argv[1:])
    (first.folder / ".lock").mkdir(parents=True)  # no file to lock
    assert main(argv) == 1 and [c[0] for c in calls] == ["train", "evaluate"]
    assert "seed-1: failed in locking the cell ([Errno 21] Is a directory" in capsys.readouterr().err
    assert "| 2 (1 failed) |" in (tmp_path / "sweep.md").read_text()


@pytest.mark.parametrize("text", ["", "run: {}\n", "run:\n  argv: 3\n"])
def test_an_unreadable_stopped_run_is_one_error_line(tmp_path, monkeypatch, capsys, text) -> None:
    monkeypatch.setattr(sweep, "_mjnav", _fake_mjnav(calls := []))
    argv = ["sweep", "task=stage1", "seeds=1", f"out={tmp_path}"]
    (cell,) = _cells(argv[1:])
    run = _stopped_run(cell, cell.train, 3)
    (run / "config.yaml").write_text(text)  # a kill while it was written (before it was atomic)
    assert main(argv) == 2 and calls == []
    err = capsys.readouterr().err
    assert err.startswith(f"error: {run / 'config.yaml'}: not a readable run record") and "move that run" in err


def test_a_second_sigterm_stops_waiting_for_the_cancelled_ray_tasks() -> None:
    waited: list[int] = []

    class FakeRay:
        def cancel(self, ref: object) -> None:
            pass

        def wait(self, refs: list, num_returns: int, timeout: float) -> tuple[list, list]:
            waited.append(len(refs))
            stopped.append(True)  # the second SIGTERM arrives while waiting
            return [], refs

    stopped = [True]
    sweep._cancel(FakeRay(), {"a": None, "b": None}, stopped)
    assert waited == [2]  # one slice, then it returned with the tasks still running


def test_a_stopped_training_with_other_arguments_is_refused(tmp_path, monkeypatch, capsys) -> None:
    monkeypatch.setattr(sweep, "_mjnav", _fake_mjnav(calls := []))
    argv = ["sweep", "task=stage1", "seeds=1", f"out={tmp_path}"]
    (cell,) = _cells(argv[1:])
    _stopped_run(cell, [*cell.train[:-1], "train.iterations=7", cell.train[-1]], 3)
    assert main(argv) == 2 and calls == []
    assert "its stage1-20261207-010203-42-abcd/config.yaml: train.iterations=7; now: -" in capsys.readouterr().err


def test_a_real_tiny_sweep_trains_evaluates_and_resumes(tmp_path, capsys) -> None:
    argv = ["sweep", *TINY, "seeds=0,1", f"out={tmp_path}"]
    assert main(argv) == 0
    for seed in (0, 1):
        result = json.loads((tmp_path / f"seed-{seed}" / "result.json").read_text())
        assert result["seed"] == seed and result["summary"]["episodes"] == 2
        assert Path(result["run"]).parent == tmp_path / f"seed-{seed}"
        assert (tmp_path / f"seed-{seed}" / "eval" / "stage1.jsonl").is_file()
    assert "| 0,1 |" in (tmp_path / "sweep.md").read_text()
    runs = sorted(tmp_path.glob("seed-*/stage1-*"))
    assert main(argv) == 0 and sorted(tmp_path.glob("seed-*/stage1-*")) == runs  # nothing trained again


def test_cells_as_ray_tasks(tmp_path) -> None:
    pytest.importorskip("ray")
    assert main(["sweep", *TINY, "seeds=0", "backend=ray", f"out={tmp_path}"]) == 0
    assert json.loads((tmp_path / "seed-0" / "result.json").read_text())["summary"]["episodes"] == 2


@pytest.mark.skipif(not Path("/proc/self/task").is_dir(), reason="reads child processes from /proc")
def test_sigterm_to_a_sweep_ends_its_training_too_and_a_rerun_resumes_it(tmp_path) -> None:
    """``kill`` (SIGTERM) reaches the sweep only; it passes it on, the training saves and ends, and
    the sweep exits with 143 instead of leaving the training to run on alone. Started again, the
    sweep resumes that training from the checkpoint it saved."""
    argv = ["sweep", *(a for a in TINY if not a.startswith("train.iterations")), "train.iterations=300", "seeds=0",
            f"out={tmp_path}"]  # 300 tiny iterations: ~6 s here, far more than the SIGTERM takes to arrive
    sweep_ = subprocess.Popen([sys.executable, "-m", "mjnav", *argv], cwd=Path(__file__).parents[2])
    log, children = tmp_path / "seed-0" / "train.log", []
    try:
        deadline = time.monotonic() + 120
        while "[stage1] it " not in (log.read_text() if log.is_file() else "") and time.monotonic() < deadline:
            time.sleep(0.2)
        children += [int(c) for t in Path(f"/proc/{sweep_.pid}/task").iterdir()
                     for c in (t / "children").read_text().split()]
        sweep_.terminate()
        assert sweep_.wait(timeout=60) == 143
    finally:
        sweep_.kill()
        left = [pid for pid in children if Path(f"/proc/{pid}").exists()]
        for pid in left:  # not to leave a training running if this fails
            os.kill(pid, signal.SIGKILL)
    assert len(children) == 1 and left == []  # reaped by the sweep: it waited for it
    assert "SIGTERM: finishing this iteration" in log.read_text()
    (stopped,) = [p for p in (tmp_path / "seed-0").iterdir() if p.is_dir()]
    saved = checkpoints(stopped)[-1].name
    assert not (stopped / "policy.pt").exists() and saved != "model_299.pt"
    assert main(argv) == 0
    result = json.loads((tmp_path / "seed-0" / "result.json").read_text())
    assert result["run"] == str(stopped) and result["resumed"] == saved and result["summary"]["episodes"] == 2
    assert checkpoints(stopped)[-1].name == "model_299.pt" and (stopped / "policy.pt").is_file()
    assert yaml.safe_load((stopped / "config.yaml").read_text())["run"]["resumes"] == [[f"resume={stopped}"]]


def _processes_naming(text: str) -> list[int]:
    """Processes whose command line holds ``text``."""
    found = []
    for proc in Path("/proc").iterdir():
        with contextlib.suppress(OSError):
            if proc.name.isdigit() and text in (proc / "cmdline").read_bytes().decode(errors="replace"):
                found.append(int(proc.name))
    return found


@pytest.mark.skipif(not Path("/proc/self/task").is_dir(), reason="reads processes from /proc")
def test_sigterm_to_a_ray_sweep_lets_its_training_save(tmp_path) -> None:
    """With ``backend=ray`` the sweep cancels its Ray tasks on SIGTERM; each passes it on to its
    training, which saves a checkpoint, and the sweep exits with 143 once they have ended. Started
    with SIGINT ignored, as a shell script's background job is (the cancel's interrupt goes through
    Python's SIGINT machinery)."""
    pytest.importorskip("ray")
    argv = ["sweep", *(a for a in TINY if not a.startswith("train.iterations")), "train.iterations=300", "seeds=0",
            "backend=ray", f"out={tmp_path}"]
    sweep_ = subprocess.Popen([sys.executable, "-m", "mjnav", *argv], cwd=Path(__file__).parents[2],
                              stderr=subprocess.PIPE, text=True,  # as `mjnav sweep ... &` in a script starts it:
                              preexec_fn=lambda: signal.signal(signal.SIGINT, signal.SIG_IGN))  # SIGINT ignored
    log = tmp_path / "seed-0" / "train.log"
    try:
        deadline = time.monotonic() + 120
        while "[stage1] it " not in (log.read_text() if log.is_file() else "") and time.monotonic() < deadline:
            time.sleep(0.2)
        sweep_.terminate()
        assert sweep_.wait(timeout=90) == 143
    finally:
        sweep_.kill()
        for pid in _processes_naming(str(tmp_path)):  # not to leave a training running if this fails
            os.kill(pid, signal.SIGKILL)
    assert "SIGTERM: stopping 1 cell(s)" in sweep_.stderr.read()
    assert "saved " in log.read_text()
    (stopped,) = [p for p in (tmp_path / "seed-0").iterdir() if p.is_dir()]
    assert checkpoints(stopped) and not (stopped / "policy.pt").exists()
    assert _processes_naming(str(tmp_path)) == []
