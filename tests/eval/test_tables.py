"""Paper tables: intervals, lookups of shipped files and the markdown layout (no evaluation runs)."""

from __future__ import annotations

import json
from pathlib import Path

import pytest

from mjnav.eval import tables


def test_wilson_interval_brackets_the_rate() -> None:
    """The 95 % Wilson interval contains the rate, stays in [0, 1] and narrows with n."""
    lo, hi = tables.wilson(900, 1000)
    assert lo < 0.9 < hi and hi - lo == pytest.approx(0.037, abs=0.002)
    assert tables.wilson(0, 10)[0] == 0.0 and tables.wilson(10, 10)[1] == pytest.approx(1.0)
    assert tables.wilson(45, 50)[1] - tables.wilson(45, 50)[0] > hi - lo


def test_missing_policies_are_listed_as_not_trained(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    """A method without its policy file gets "not trained", never a number."""
    monkeypatch.setitem(tables.TABLES, 2, {"Ours": str(tmp_path / "{stage}_policy.pt")})
    rows = tables.table_rows(2, tmp_path, episodes=5, run_missing=False)
    assert [r["status"] for r in rows] == ["not trained"] * 3
    assert "not trained" in tables.format_table(rows)


def test_existing_evaluations_are_read_not_rerun(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    """Matching JSONL files are summarised under both rules with the paper's number beside them."""
    policy = tmp_path / "stage2_policy.pt"
    policy.write_bytes(b"x")
    monkeypatch.setitem(tables.TABLES, 2, {"Ours": str(tmp_path / "{stage}_policy.pt")})
    monkeypatch.setitem(tables.STAGES, 2, ("stage2",))
    for rule, wins in (("scan", 3), ("contact", 4)):
        path = tmp_path / "out" / "table2" / "ours" / f"stage2_{rule}.jsonl"
        path.parent.mkdir(parents=True, exist_ok=True)
        lines = [{"policy_source": str(policy), "index": i, "seed": 2**32 + i, "action_mode": "mean",
                  "outcome": "success" if i < wins else "collision",
                  "metrics": {"time_s": 5.0, "distance_m": 12.0, "mean_speed": 2.0}} for i in range(5)]
        path.write_text("".join(json.dumps(x) + "\n" for x in lines))
    rows = tables.table_rows(2, tmp_path / "out", episodes=5, run_missing=False)
    assert rows[0]["scan"]["success"] == 3 and rows[0]["contact"]["success"] == 4
    text = tables.format_table(rows)
    assert "| stage2 | Ours | 89.2 (5.5 s, 12.19 m, 2.18 m/s) | 60.0 [" in text and "| 80.0 [" in text
    stale = tables.table_rows(2, tmp_path / "out", episodes=6, run_missing=False)
    assert stale[0]["scan"] is None  # other episode count: not reused
