"""Paper tables: intervals, lookups of shipped files and the markdown layout (no evaluation runs)."""

from __future__ import annotations

import dataclasses
import json
from pathlib import Path

import pytest

from mjnav.eval import tables
from mjnav.eval.runner import policy_sha256
from mjnav.planners import resolve_planner

TEB_SHA = resolve_planner("teb").sha256()  # what a teb evaluation records as planner_sha256


def test_wilson_interval_brackets_the_rate() -> None:
    """The 95 % Wilson interval contains the rate, stays in [0, 1] and narrows with n."""
    lo, hi = tables.wilson(900, 1000)
    assert lo < 0.9 < hi and hi - lo == pytest.approx(0.037, abs=0.002)
    assert tables.wilson(0, 10)[0] == 0.0 and tables.wilson(10, 10)[1] == pytest.approx(1.0)
    assert tables.wilson(45, 50)[1] - tables.wilson(45, 50)[0] > hi - lo


def test_missing_policies_are_listed_as_not_trained(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    """A method without its policy file gets "not trained", never a number."""
    ours = tables.Method("Ours", str(tmp_path / "{stage}_policy.pt"), "ours", {})
    monkeypatch.setitem(tables.TABLES, 2, tables.Table(("stage2", "stage3", "stage4"), (ours,)))
    rows = tables.table_rows(2, tmp_path, episodes=5, run_missing=False)
    assert [r["status"] for r in rows] == ["not trained"] * 3
    assert "not trained" in tables.format_table(rows)


def test_methods_keeps_only_the_named_ones(tmp_path: Path) -> None:
    """methods=("Ours",) gives Ours' rows only; an unknown name is a ValueError naming the known ones."""
    rows = tables.table_rows(4, tmp_path, episodes=5, run_missing=False, methods=("Ours",))
    assert {r["method"] for r in rows} == {"Ours"} and len(rows) == 3
    with pytest.raises(ValueError, match="known"):
        tables.table_rows(4, tmp_path, episodes=5, run_missing=False, methods=("PPO",))


def test_every_method_name_survives_the_comma_separated_option() -> None:
    """paper_tables.py splits methods= at commas, so no method name may contain one."""
    names = [m.name for table in tables.TABLES.values() for m in table.methods]
    assert [n for n in names if "," in n or n != n.strip()] == []


def test_existing_evaluations_are_read_not_rerun(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    """Matching JSONL files are summarised under both rules with the paper's number beside them."""
    policy = tmp_path / "stage2_policy.pt"
    policy.write_bytes(b"x")
    ours = next(m for m in tables.TABLES[2].methods if m.name == "Ours")
    ours = dataclasses.replace(ours, policy=str(tmp_path / "{stage}_policy.pt"))
    monkeypatch.setitem(tables.TABLES, 2, tables.Table(("stage2",), (ours,)))
    for rule, wins in (("scan", 3), ("contact", 4)):
        path = tmp_path / "out" / "ours" / f"stage2_{rule}.jsonl"
        path.parent.mkdir(parents=True, exist_ok=True)
        lines = [{"policy_source": str(policy), "policy_sha256": policy_sha256(str(policy)), "index": i,
                  "seed": 2**32 + i, "action_mode": "mean", "outcome": "success" if i < wins else "collision",
                  "metrics": {"time_s": 5.0, "distance_m": 12.0, "mean_speed": 2.0}} for i in range(5)]
        path.write_text("".join(json.dumps(x) + "\n" for x in lines))
    rows = tables.table_rows(2, tmp_path / "out", episodes=5, run_missing=False)
    assert rows[0]["scan"]["success"] == 3 and rows[0]["contact"]["success"] == 4
    text = tables.format_table(rows)
    assert "| stage2 | Ours | 89.2 (5.5 s, 12.19 m, 2.18 m/s) | 60.0 [" in text and "| 80.0 [" in text
    stale = tables.table_rows(2, tmp_path / "out", episodes=6, run_missing=False)
    assert stale[0]["scan"] is None  # other episode count: not reused
    policy.write_bytes(b"retrained")
    assert tables.table_rows(2, tmp_path / "out", episodes=5, run_missing=False)[0]["scan"] is None  # new file


def test_crowd_tables_share_ours_and_show_total_abs_acc(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    """Table III's r_t1 and Table IV's Ours read the same evaluations; TEB is a baseline, never "not trained"."""
    policy = tmp_path / "stage5_policy.pt"
    policy.write_bytes(b"x")
    for number in (3, 4):
        table = tables.TABLES[number]
        methods = tuple(dataclasses.replace(m, policy=str(tmp_path / ("{stage}_policy.pt" if m.slug == "ours" else
                                                                       f"{m.slug}.pt")))
                        if m.policy != "teb" else m for m in table.methods)
        monkeypatch.setitem(tables.TABLES, number, dataclasses.replace(table, stages=("stage5",), methods=methods))
    for rule in tables.RULES:
        path = tmp_path / "out" / "ours" / f"stage5_{rule}.jsonl"
        path.parent.mkdir(parents=True, exist_ok=True)
        lines = [{"policy_source": str(policy), "policy_sha256": policy_sha256(str(policy)), "index": i,
                  "seed": 2**32 + i, "action_mode": "mean", "outcome": "success",
                  "metrics": {"time_s": 3.0, "distance_m": 4.5, "mean_speed": 1.5, "abs_acc_sum": 10.0}} for i in range(4)]
        path.write_text("".join(json.dumps(x) + "\n" for x in lines))
    three = tables.table_rows(3, tmp_path / "out", episodes=4, run_missing=False)
    four = tables.table_rows(4, tmp_path / "out", episodes=4, run_missing=False)
    assert three[0]["scan"] == four[1]["scan"] and three[0]["scan"]["abs_acc"] == pytest.approx(40.0)
    assert [r["status"] for r in three[1:]] == ["not trained"] * 4  # the ablation runs, not shipped here
    assert four[0]["method"] == "TEB" and four[0]["status"] == "ok" and four[0]["scan"] is None  # not run
    text = tables.format_table(three, abs_acc=True)
    assert "Total Abs Acc" in text and "| 40.0 |" in text and "87.1 (2.9 s, 4.59 m, 1.57 m/s, 26475.5)" in text
    assert all(line.count("|") == text.splitlines()[0].count("|") for line in text.splitlines())


def test_an_unfinished_evaluation_shows_its_episodes_so_far(tmp_path: Path) -> None:
    """With run=false the runner's unfinished JSONL is shown as "n of N" up to its first gap; a file
    of the other rule is not."""
    folder = tmp_path / "teb"
    folder.mkdir()
    lines = [{"policy_source": "teb", "policy_sha256": policy_sha256("teb"), "planner_sha256": TEB_SHA,
              "index": i, "seed": 2**32 + i, "collision": "scan", "action_mode": "mean",
              "outcome": "success" if i % 2 else "collision",
              "metrics": {"time_s": 4.0, "distance_m": 4.0, "mean_speed": 1.0, "abs_acc_sum": 5.0}} for i in range(6)]
    (folder / "stage6.jsonl").write_text("".join(json.dumps(x) + "\n" for x in lines))
    rows = tables.table_rows(4, tmp_path, episodes=1000, run_missing=False)
    teb = next(r for r in rows if r["stage"] == "stage6" and r["method"] == "TEB")
    assert teb["scan"]["episodes"] == 6 and teb["scan"]["success"] == 3 and teb["contact"] is None
    line = next(x for x in tables.format_table(rows).splitlines() if "| stage6 | TEB |" in x)
    assert "| 6 of 1000 |" in line and "50.0 [" in line
    (folder / "stage6.jsonl").write_text("".join(json.dumps(x) + "\n" for x in lines[3:] + lines[:2]))
    rows = tables.table_rows(4, tmp_path, episodes=1000, run_missing=False)
    assert next(r for r in rows if r["stage"] == "stage6" and r["method"] == "TEB")["scan"]["episodes"] == 2  # up to the gap
    (folder / "stage6.jsonl").write_text("".join(json.dumps({**x, "collision": "contact"}) + "\n" for x in lines))
    rows = tables.table_rows(4, tmp_path, episodes=1000, run_missing=False)
    assert next(r for r in rows if r["stage"] == "stage6" and r["method"] == "TEB")["scan"] is None  # other rule


def test_a_changed_baseline_default_makes_its_evaluations_stale(tmp_path: Path,
                                                               monkeypatch: pytest.MonkeyPatch) -> None:
    """A baseline's records carry a hash of its resolved parameters: the same parameters match, a
    changed default (or an override) does not, so a re-tuned TEB is never reported with old episodes."""
    from mjnav.planners import PLANNERS, TebConfig

    assert policy_sha256("teb") == policy_sha256("teb") != policy_sha256("teb", ["d_inflation=0.9"])
    assert policy_sha256("dwa") != policy_sha256("teb") and policy_sha256("random_jerk") is None
    table = tables.TABLES[4]
    monkeypatch.setitem(tables.TABLES, 4, dataclasses.replace(table, stages=("stage6",), methods=table.methods[:1]))
    for rule in tables.RULES:
        path = tmp_path / "teb" / f"stage6_{rule}.jsonl"
        path.parent.mkdir(parents=True, exist_ok=True)
        lines = [{"policy_source": "teb", "policy_sha256": policy_sha256("teb"), "planner_sha256": TEB_SHA,
                  "index": i, "seed": 2**32 + i, "collision": rule, "action_mode": "mean", "outcome": "success",
                  "metrics": {"time_s": 4.0, "distance_m": 4.0, "mean_speed": 1.0}} for i in range(3)]
        path.write_text("".join(json.dumps(x) + "\n" for x in lines))
    assert tables.table_rows(4, tmp_path, episodes=3, run_missing=False)[0]["scan"]["success"] == 3
    retuned = dataclasses.make_dataclass("TebConfig", [("d_inflation", float, 1.8)], bases=(TebConfig,),
                                       frozen=TebConfig.__dataclass_params__.frozen)
    teb = PLANNERS.get("teb")
    PLANNERS.register("teb", teb.factory, config=retuned, replace=True)
    try:
        assert tables.table_rows(4, tmp_path, episodes=3, run_missing=False)[0]["scan"] is None
    finally:
        PLANNERS.register("teb", teb.factory, config=teb.config_class, source=teb.source, replace=True)


def _trip(d: float, outcome: str) -> dict:
    return {"start": [0.0, 0.0], "goal": [d, 0.0], "outcome": outcome}


def test_success_by_distance_bins_trips_and_counts_their_outcomes() -> None:
    """Trips fall into [lo, hi) bins, the last one open; each bin has its rate and Wilson interval."""
    rows = [_trip(1.0, "success"), _trip(2.0, "collision"), _trip(3.9, "success"), _trip(9.5, "timeout"),
            _trip(0.5, "success")]
    bins = tables.success_by_distance(rows, edges=(1.0, 2.0, 4.0))
    assert [(b["lo"], b["hi"], b["episodes"], b["success"]) for b in bins] == [
        (1.0, 2.0, 1, 1), (2.0, 4.0, 2, 1), (4.0, float("inf"), 1, 0)]  # the 0.5 m trip is below 1 m
    assert bins[1]["rate"] == 0.5 and bins[1]["ci"] == tables.wilson(1, 2)
    empty = tables.success_by_distance([], edges=(0.0, 5.0))
    assert all(b["episodes"] == 0 and b["rate"] != b["rate"] for b in empty)  # nan for an empty bin
    table = tables.format_strata({"A": bins, "B": bins})
    assert "| 2-4 m | 50.0 [" in table and ">= 4 m" in table and table.count("\n") == 4


@pytest.mark.parametrize("edges", [(), (2.0, 1.0), (-1.0, 2.0), (1.0, 1.0)])
def test_success_by_distance_refuses_bad_edges(edges: tuple) -> None:
    """Edges that are empty, negative or not increasing are a ValueError naming them."""
    with pytest.raises(ValueError, match="edges"):
        tables.success_by_distance([_trip(1.0, "success")], edges=edges)


def test_success_by_distance_refuses_records_without_a_trip() -> None:
    """A record without start, goal or outcome (not the runner's JSONL) is a ValueError, not a KeyError."""
    with pytest.raises(ValueError, match="record 1"):
        tables.success_by_distance([_trip(1.0, "success"), {"outcome": "success"}])


def test_methods_picks_an_added_planner_alone(tmp_path: Path) -> None:
    """``methods=`` names added planners too, so one planner's evaluations can be run by themselves."""
    rows = tables.table_rows(4, tmp_path, 5, run_missing=False, methods=["mpc_goal + tracks"],
                             planners=["mpc_goal", "mpc_goal+tracks"])
    assert [(r["stage"], r["method"]) for r in rows] == [(s, "mpc_goal + tracks") for s in ("stage5", "stage6", "stage7")]
    with pytest.raises(ValueError, match="mpc_crowd"):
        tables.table_rows(4, tmp_path, 5, run_missing=False, methods=["mpc_crowd"], planners=["mpc_goal"])
