"""Short versions of scripts/fuzz.py and scripts/soak.py (the full runs are in docs/reliability.md)."""

from __future__ import annotations

from tests._scripts import load_script

fuzz = load_script("fuzz")
soak = load_script("soak")


def test_fuzz_region_and_mpc() -> None:
    """2,000 random scans and 1,000 random MPC problems: no invariant violation, no exception,
    and the generators reach every region outcome (found, recovered, failed) and the fallbacks."""
    report = fuzz.run(scans=2000, problems=1000, seed=1)
    for part in ("region", "mpc"):
        assert report[part]["violations"] == {} and report[part]["exception_count"] == 0, report[part]
    assert {"ok", "recovered", "touching"} <= set(report["region"]["status"])
    assert report["mpc"]["outcomes"]["solved"] > 500


def test_soak_short() -> None:
    """3,000 steps over all stages with random actions and a planner: no escaped error, bounded memory."""
    report = soak.run(steps=3000, seed=2, every=500)
    assert report["steps"] == 3000 and report["episodes"] >= 7
    assert report["growth"] < 0.10, report
    assert sum(report["outcomes"].values()) == report["episodes"]
