"""An evaluation never loses results: the JSONL only grows, a smaller ``episodes=`` keeps it, another
evaluation's file is refused untouched, and a kill during the final sorted rewrite leaves the old or the
new file, never a truncated one."""

from __future__ import annotations

import json
import os
import random
import signal
import subprocess
import sys
import time
from pathlib import Path

import pytest

from mjnav.eval import runner
from mjnav.eval.metrics import EpisodeMetrics, aggregate
from mjnav.eval.runner import EvalError, EvalSpec, evaluate, read_jsonl

OVERRIDES = ("timing.episode_steps=20",)


@pytest.fixture(scope="module")
def four(tmp_path_factory: pytest.TempPathFactory) -> bytes:
    """The JSONL of a 4-episode evaluation (run once)."""
    out = tmp_path_factory.mktemp("four")
    evaluate(EvalSpec("stage5", "mpc_goal", 4, 0, OVERRIDES, 1), out, progress=False)
    return (out / "stage5.jsonl").read_bytes()


def _runs(monkeypatch: pytest.MonkeyPatch) -> list[list[int]]:
    """Record the episode indices each evaluation plays."""
    calls: list[list[int]] = []
    original = runner._results
    monkeypatch.setattr(runner, "_results", lambda spec, todo: (calls.append(list(todo)), original(spec, todo))[1])
    return calls


def test_fewer_episodes_summarise_the_first_and_keep_the_file(tmp_path, four, monkeypatch) -> None:
    """episodes=2 after episodes=4: nothing runs, the file keeps its 4 lines byte for byte, the summary is
    that of episodes 0 and 1; episodes=5 then plays episode 4 only."""
    path = tmp_path / "stage5.jsonl"
    path.write_bytes(four)
    calls = _runs(monkeypatch)
    row = evaluate(EvalSpec("stage5", "mpc_goal", 2, 0, OVERRIDES, 1), tmp_path, progress=False)
    assert calls == [[]] and path.read_bytes() == four
    first = [EpisodeMetrics.from_dict(r["metrics"]) for r in read_jsonl(path)[:2]]
    assert row["episodes"] == 2 and row["success_rate"] == aggregate(first)["success_rate"]
    evaluate(EvalSpec("stage5", "mpc_goal", 5, 0, OVERRIDES, 1), tmp_path, progress=False)
    assert calls[-1] == [4] and [r["index"] for r in read_jsonl(path)] == [0, 1, 2, 3, 4]
    assert path.read_bytes().startswith(four)


@pytest.mark.parametrize(("field", "change", "named"), [
    ("commit", "0" * 40, "commit"),
    ("overrides", ["timing.episode_steps=20", "crowd.count=3"], "overrides"),
    ("policy_sha256", "feedfeedfeedfeed", "policy_sha256"),
    ("seed", 2**32 + 1000, "seed_offset"),
])
def test_another_evaluations_file_is_refused_untouched(tmp_path, four, field, change, named, capsys) -> None:
    """A file whose records differ in commit, overrides, planner/policy version or seeds is never deleted
    or rewritten: evaluate raises naming the field and out=; the command line exits 2 with that message."""
    records = [json.loads(x) for x in four.decode().splitlines()]
    records[2][field] = change
    path = tmp_path / "stage5.jsonl"
    path.write_text("".join(json.dumps(r) + "\n" for r in records))
    before = path.read_bytes()
    with pytest.raises(EvalError, match=rf"{named}.*out=DIR"):
        evaluate(EvalSpec("stage5", "mpc_goal", 4, 0, OVERRIDES, 1), tmp_path, progress=False)
    assert path.read_bytes() == before
    code = runner.main(["task=stage5", "policy=mpc_goal", "episodes=6", "workers=1", f"out={tmp_path}",
                        *(f"task.{o}" for o in OVERRIDES)])
    assert code == 2 and named in capsys.readouterr().err and path.read_bytes() == before


def test_a_line_cut_by_a_kill_never_swallows_the_next(tmp_path, four, monkeypatch) -> None:
    """A file ending in half a record (no newline): the missing episodes are appended on lines of their
    own, and the final rewrite holds every episode once, sorted."""
    lines = four.decode().splitlines(keepends=True)
    path = tmp_path / "stage5.jsonl"
    path.write_text(lines[3] + lines[0] + lines[1][:50])
    calls = _runs(monkeypatch)
    evaluate(EvalSpec("stage5", "mpc_goal", 4, 0, OVERRIDES, 1), tmp_path, progress=False)
    assert calls == [[1, 2]]
    assert [r["index"] for r in read_jsonl(path)] == [0, 1, 2, 3] and len(path.read_text().splitlines()) == 4


# ---------------------------------------------------------------------------- kills during the rewrite

_CHILD = """
import os, sys, time
from pathlib import Path
from mjnav.eval import runner
stage = sys.argv[2]
real_fsync, real_replace = os.fsync, os.replace
def fsync(fd):
    real_fsync(fd)
    if stage == "fsync":
        print("PAUSED", flush=True); time.sleep(60)
def replace(a, b):
    real_replace(a, b)
    if stage == "replace":
        print("PAUSED", flush=True); time.sleep(60)
os.fsync, os.replace = fsync, replace
print("STARTED", flush=True)
runner._rewrite_sorted(Path(sys.argv[1]))
print("DONE", flush=True)
"""


def _unsorted(path: Path, count: int = 4000) -> tuple[bytes, bytes]:
    """Write ``count`` records in reverse index order (~1 kB each); returns (old bytes, sorted bytes)."""
    records = [{"index": i, "seed": 2**32 + i, "outcome": "success", "pad": "x" * 1000} for i in range(count)]
    old = "".join(json.dumps(r) + "\n" for r in reversed(records))
    path.write_text(old)
    return old.encode(), "".join(json.dumps(r) + "\n" for r in records).encode()


def _child(path: Path, stage: str) -> subprocess.Popen:
    proc = subprocess.Popen([sys.executable, "-c", _CHILD, str(path), stage], stdout=subprocess.PIPE, text=True,
                            env={**os.environ, "PYTHONPATH": os.pathsep.join(sys.path)})
    assert proc.stdout is not None and proc.stdout.readline().strip() == "STARTED"
    return proc


@pytest.mark.parametrize(("stage", "expect"), [("fsync", "old"), ("replace", "new")])
def test_sigkill_at_each_step_of_the_rewrite_leaves_a_whole_file(tmp_path, stage, expect) -> None:
    """SIGKILL after the temporary file is synced (before the replace): the old file, whole; after the
    replace: the new, sorted one. A later rewrite ignores the leftover temporary file."""
    path = tmp_path / "stage5.jsonl"
    old, new = _unsorted(path)
    proc = _child(path, stage)
    assert proc.stdout.readline().strip() == "PAUSED"
    proc.send_signal(signal.SIGKILL)
    proc.wait(timeout=30)
    assert path.read_bytes() == (old if expect == "old" else new)
    runner._rewrite_sorted(path)
    assert path.read_bytes() == new
    assert {p.name for p in tmp_path.iterdir() if not p.name.startswith(".")} == {"stage5.jsonl"}


def test_sigkill_at_random_moments_never_truncates(tmp_path) -> None:
    """Kills at random moments of the rewrite of a 4 MB file: every time the file is the old or the new one."""
    rng = random.Random(37)
    path = tmp_path / "stage5.jsonl"
    seen = set()
    for _ in range(6):
        old, new = _unsorted(path)
        proc = _child(path, "none")
        time.sleep(rng.uniform(0.0, 0.15))
        proc.send_signal(signal.SIGKILL)
        proc.wait(timeout=30)
        content = path.read_bytes()
        assert content in (old, new), f"{len(content)} bytes: neither the old nor the new file"
        seen.add("old" if content == old else "new")
    assert seen  # which one depends on timing; both are whole


def test_tables_keep_longer_and_other_evaluations(tmp_path, monkeypatch) -> None:
    """The tables command answers a shorter request from a longer file's first episodes, and when it
    re-evaluates a changed policy, the earlier records are moved aside, not deleted."""
    from mjnav.eval import tables

    def lines(n: int, sha: str) -> str:
        return "".join(json.dumps({"index": i, "seed": 2**32 + i, "policy_sha256": sha, "commit": "c" * 40,
                                   "outcome": "success", "metrics": {}}) + "\n" for i in range(n))

    assert [r["index"] for r in tables._first(json.loads("[" + lines(6, "a").replace("\n", ",")[:-1] + "]"), 4)] \
        == [0, 1, 2, 3]
    path, new = tmp_path / "stage5_scan.jsonl", tmp_path / "stage5.jsonl"
    path.write_text(lines(6, "old"))
    new.write_text(lines(4, "new"))
    tables._replace_keeping(new, path)
    assert (tmp_path / "stage5_scan.cccccccc-old.jsonl").read_text() == lines(6, "old")
    assert path.read_text() == lines(4, "new") and not new.exists()
