"""Comparing two evaluations of the same episodes: everything but the wall-clock measurements
(MPC solve times, and the summary columns made of them) must be equal."""

from __future__ import annotations

import csv
from pathlib import Path
from typing import Any

from mjnav.eval.runner import read_jsonl

#: Summary columns measured on the clock (they differ between any two runs).
CLOCK_COLUMNS = ("solve_ms_median", "solve_ms_p99")


def timing_free(record: dict[str, Any]) -> dict[str, Any]:
    """``record`` without its solve times (only their count kept), recursively through ``paper_rule``."""
    out = {}
    for key, value in record.items():
        if key == "solve_times_ms":
            out[key] = len(value)
        elif isinstance(value, dict):
            out[key] = timing_free(value)
        else:
            out[key] = value
    return out


def records(path: Path, drop: tuple[str, ...] = ()) -> list[dict[str, Any]]:
    """The timing-free records of a JSONL file, without the fields ``drop``."""
    return [timing_free({k: v for k, v in r.items() if k not in drop}) for r in read_jsonl(path)]


def summary(path: Path) -> list[dict[str, str]]:
    """The rows of a ``summary.csv`` without :data:`CLOCK_COLUMNS`."""
    with open(path, encoding="utf-8") as f:
        return [{k: v for k, v in row.items() if k not in CLOCK_COLUMNS} for row in csv.DictReader(f)]
