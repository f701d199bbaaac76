"""Planner evaluations record the planner (source, hash of its files, parameters, privileged data);
a changed planner is another evaluation; summaries and tables mark privileged planners."""

from __future__ import annotations

from pathlib import Path

import pytest

from mjnav.eval.metrics import format_markdown
from mjnav.eval.policies import planner_record
from mjnav.eval.runner import EvalError, EvalSpec, evaluate, read_jsonl
from mjnav.eval.tables import format_social, format_table, planner_method, table_rows
from mjnav.planners import resolve_planner

OVERRIDES = ("timing.episode_steps=20",)

PLANNER = '''
import dataclasses
import numpy as np


@dataclasses.dataclass(frozen=True)
class BrakeConfig:
    gain: float = 1.0


class Brake:
    config_class = BrakeConfig

    def __init__(self, config=None):
        self.config = config or BrakeConfig()

    def reset(self, config, rng):
        pass

    def act(self, inp):
        return -self.config.gain * np.asarray(inp.acceleration)
'''


def test_records_of_builtin_outside_and_learned_policies(tmp_path):
    """A built-in: its name, the hash of its files, its parameters and declaration; a file planner:
    its absolute path; a learned policy: no planner fields."""
    crowd = planner_record("mpc_crowd", ["margin=0.5"])
    assert crowd["planner_source"] == "mpc_crowd" and crowd["planner_privileged"] == ["positions", "radii"]
    assert crowd["planner_params"]["margin"] == 0.5 and crowd["planner_params"]["speeds"] == [0.6, 1.2, 1.8, 2.4]
    assert crowd["planner_sha256"] == resolve_planner("mpc_crowd").sha256() and len(crowd["planner_sha256"]) == 64
    path = tmp_path / "brake.py"
    path.write_text(PLANNER, encoding="utf-8")
    mine = planner_record(f"{path}:Brake")
    assert mine["planner_source"] == f"{path.resolve()}:Brake" and mine["planner_params"] == {"gain": 1.0}
    assert planner_record("stage6_policy") == dict.fromkeys(mine)


def test_a_changed_builtin_changes_its_hash(tmp_path, monkeypatch):
    """The hash covers the planner's module and its bases' (mpc_crowd: mpc_crowd.py and mpc_goal.py)."""
    found = resolve_planner("mpc_crowd")
    assert [p.name for p in found.files] == ["mpc_crowd.py", "mpc_goal.py"]
    copy = tmp_path / "mpc_goal.py"
    copy.write_bytes(found.files[1].read_bytes() + b"\n# changed\n")
    changed = type(found)(found.spec, found.name, found.source, found.factory, found.config_class,
                          (found.files[0], copy))
    assert changed.sha256() != found.sha256()


def test_a_changed_planner_is_another_evaluation(tmp_path):
    """After one episode of file planner Brake: other parameters, or an edited file, are refused
    (naming the field) and the file keeps its line; the same planner resumes."""
    path = tmp_path / "brake.py"
    path.write_text(PLANNER, encoding="utf-8")
    spec = f"{path}:Brake"
    out = tmp_path / "out"
    evaluate(EvalSpec("stage5", spec, 1, 0, OVERRIDES, 1), out, progress=False)
    before = (out / "stage5.jsonl").read_bytes()
    with pytest.raises(EvalError, match="planner_params"):
        evaluate(EvalSpec("stage5", spec, 1, 0, OVERRIDES, 1, planner=("gain=2",)), out, progress=False)
    path.write_text(PLANNER + "\n# a new version\n", encoding="utf-8")
    with pytest.raises(EvalError, match="planner_sha256"):
        evaluate(EvalSpec("stage5", spec, 1, 0, OVERRIDES, 1), out, progress=False)
    assert (out / "stage5.jsonl").read_bytes() == before
    path.write_text(PLANNER, encoding="utf-8")
    row = evaluate(EvalSpec("stage5", spec, 1, 0, OVERRIDES, 1), out, progress=False)
    assert row["episodes"] == 1 and row["planner_privileged"] == ""


def test_a_privileged_planner_is_marked_in_the_summary(tmp_path):
    """mpc_crowd's records carry planner_privileged; its summary row shows "(privileged)" after the method."""
    row = evaluate(EvalSpec("stage5", "mpc_crowd", 1, 0, OVERRIDES, 1), tmp_path, progress=False)
    assert read_jsonl(tmp_path / "stage5.jsonl")[0]["planner_privileged"] == ["positions", "radii"]
    assert row["planner_privileged"] == "positions,radii"
    assert "| mpc_crowd (privileged) |" in format_markdown([row])
    assert "(privileged)" not in format_markdown([{**row, "planner_privileged": ""}])


def test_tables_take_planners_and_mark_privileged_ones(tmp_path):
    """tables planners=mpc_crowd,FILE:Brake adds both as methods; only mpc_crowd is marked "(privileged)"."""
    path = tmp_path / "brake.py"
    path.write_text(PLANNER, encoding="utf-8")
    method = planner_method(f"{path}:Brake")
    assert method.name == "brake.py:Brake" and method.slug == "planner_brake.py_Brake"
    rows = table_rows(4, Path(tmp_path / "evals"), 5, run_missing=False, methods=["TEB", "mpc_crowd", "brake.py:Brake"],
                      planners=["mpc_crowd", f"{path}:Brake"])
    assert [(r["method"], r["privileged"]) for r in rows[:3]] == [
        ("TEB", False), ("mpc_crowd", True), ("brake.py:Brake", False)]
    text = format_table(rows) + format_social(rows)
    assert text.count("mpc_crowd (privileged)") == 6 and "brake.py:Brake (privileged)" not in text
