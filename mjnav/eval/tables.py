"""The paper's tables from held-out evaluations, with the paper's numbers side by side.

``python scripts/paper_tables.py table=2`` reads one evaluation JSONL per (method, stage,
collision rule) from ``out`` (default ``evals/paper``), runs the missing evaluations
(:func:`mjnav.eval.runner.evaluate`, ``episodes`` held-out scenarios each, the policy's own
training config plus ``collision=scan`` or ``collision=contact``), and prints one row per method and
stage: our success under the paper's collision rule (shrunk scan ≤ 0) and under MuJoCo contacts,
each with a 95 % Wilson interval, the paper's success, and time / distance / speed over the
successful episodes under the paper's rule. A method whose policy file does not exist is listed
as "not trained", never estimated. ``action=mean`` (default, spec §8) acts on the policy's mean
through the shipped ``*_policy.pt`` / ``*.pt``; ``action=sample`` samples its Gaussian through the
shipped ``*_checkpoint.pt``.

Files: ``<out>/table<K>/<method>/<stage>_<rule>.jsonl`` (the evaluation runner's JSONL). A file
whose episode count, seed offset or policy differs from the request is evaluated again.
"""

from __future__ import annotations

import json
import math
from collections.abc import Sequence
from pathlib import Path
from typing import Any

__all__ = ["PAPER", "TABLES", "format_table", "load_rows", "table_rows", "wilson"]

RULES = ("scan", "contact")

#: Paper's success % (time s, distance m, speed m/s) per table, method and stage (spec §11).
PAPER: dict[int, dict[str, dict[str, tuple[float, ...]]]] = {
    2: {
        "Design 1": {"stage2": (76, 4.0, 11.28, 2.87), "stage3": (79.9, 4.0, 11.37, 2.9), "stage4": (80.9, 3.9, 11.25, 2.95)},
        "Design 2": {"stage2": (76, 4.0, 11.11, 2.8), "stage3": (79,), "stage4": (75.1,)},
        "Design 3": {"stage2": (90.3, 9.0, 15.26, 1.72), "stage3": (87.8, 8.8, 15.42, 1.77), "stage4": (84.5,)},
        "Design 4": {"stage2": (83, 5.0, 11.66, 2.23), "stage3": (83.5, 4.9, 11.59, 2.24), "stage4": (83.7,)},
        "Ours": {"stage2": (89.2, 5.5, 12.19, 2.18), "stage3": (89.1, 5.9, 13.04, 2.17), "stage4": (85.5, 5.8, 12.51, 2.1)},
    },
}

#: Method → policy spec per stage (``{stage}`` is filled in), per table.
TABLES: dict[int, dict[str, str]] = {
    2: {
        "Design 1": "docs/policies/stage4_design1.pt",
        "Design 2": "docs/policies/stage4_design2.pt",
        "Design 3": "docs/policies/stage4_design3.pt",
        "Design 4": "docs/policies/stage4_design4.pt",
        "Ours": "docs/policies/{stage}_policy.pt",
    },
}

STAGES = {2: ("stage2", "stage3", "stage4")}

def wilson(successes: int, n: int, z: float = 1.959964) -> tuple[float, float]:
    """95 % Wilson score interval of a rate (fractions); (nan, nan) for n = 0."""
    if n <= 0:
        return math.nan, math.nan
    p = successes / n
    centre = (p + z * z / (2 * n)) / (1 + z * z / n)
    half = z * math.sqrt(p * (1 - p) / n + z * z / (4 * n * n)) / (1 + z * z / n)
    return max(0.0, centre - half), min(1.0, centre + half)


def load_rows(path: Path) -> list[dict[str, Any]]:
    """The episode records of one evaluation JSONL ([] when the file does not exist)."""
    if not path.is_file():
        return []
    with open(path, encoding="utf-8") as f:
        return [json.loads(line) for line in f if line.strip()]


def _stats(rows: Sequence[dict[str, Any]]) -> dict[str, Any]:
    n = len(rows)
    wins = [r for r in rows if r["outcome"] == "success"]
    out: dict[str, Any] = {"episodes": n, "success": len(wins), "collision": sum(r["outcome"] == "collision" for r in rows)}
    for key, name in (("time_s", "time"), ("distance_m", "distance"), ("mean_speed", "speed")):
        out[name] = sum(r["metrics"][key] for r in wins) / len(wins) if wins else math.nan
    return out


def table_rows(table: int, out: Path, episodes: int, seed_offset: int = 0, workers: int = 2,
               run_missing: bool = True, action: str = "mean") -> list[dict[str, Any]]:
    """One row per (stage, method): our numbers under both rules and the paper's.

    Evaluations missing from ``out`` (or made with other episodes, seeds, policy or action mode)
    are run when ``run_missing`` is set; otherwise that rule's entry is None (shown as "–").
    """
    from mjnav.eval.runner import EvalSpec, evaluate
    from mjnav.eval.policies import training_overrides

    rows = []
    for stage in STAGES[table]:
        for method, pattern in TABLES[table].items():
            policy = _policy_file(pattern.format(stage=stage), action)
            row: dict[str, Any] = {"stage": stage, "method": method, "policy": policy,
                                   "paper": PAPER[table][method].get(stage, ())}
            if not Path(policy).is_file():
                rows.append({**row, "status": "not trained"})
                continue
            for rule in RULES:
                mode = "" if action == "mean" else f"_{action}"
                path = out / f"table{table}" / method.replace(" ", "").lower() / f"{stage}_{rule}{mode}.jsonl"
                found = load_rows(path)
                if not _matches(found, episodes, seed_offset, policy, action):
                    if not run_missing:
                        row[rule] = None
                        continue
                    spec = EvalSpec(stage, policy, episodes, seed_offset, (f"collision={rule}",), workers,
                                    training_overrides(policy), action)
                    evaluate(spec, path.parent, progress=True)
                    path.parent.joinpath(f"{stage}.jsonl").replace(path)
                    found = load_rows(path)
                row[rule] = _stats(found)
                row["mode"] = found[0].get("action_mode", "mean")
            rows.append({**row, "status": "ok"})
    return rows


def _policy_file(policy: str, action: str) -> str:
    """The shipped file to load: the exported actor for the mean, the checkpoint for sampling."""
    if action == "mean":
        return policy
    path = Path(policy)
    return str(path.with_name(f"{path.stem.removesuffix('_policy')}_checkpoint.pt"))


def _matches(found: Sequence[dict[str, Any]], episodes: int, seed_offset: int, policy: str, action: str) -> bool:
    if len(found) != episodes:
        return False
    first = found[0]
    return (first.get("policy_source") == policy and first.get("action_mode", "mean") == action
            and first.get("seed") == 2**32 + seed_offset + first.get("index", 0))


def _pct(stats: dict[str, Any] | None) -> str:
    if not stats:
        return "–"
    lo, hi = wilson(stats["success"], stats["episodes"])
    return f"{100 * stats['success'] / stats['episodes']:.1f} [{100 * lo:.1f}, {100 * hi:.1f}]"


def _paper(values: tuple[float, ...]) -> str:
    if not values:
        return "–"
    return f"{values[0]:g}" + (f" ({values[1]:g} s, {values[2]:g} m, {values[3]:g} m/s)" if len(values) == 4 else "")


def format_table(rows: Sequence[dict[str, Any]]) -> str:
    """Markdown: stage, method, paper, ours under both rules (success with CI, collisions), time/distance/speed
    over the successes under the paper's rule, action mode, episodes."""
    head = ("| stage | method | paper success % (time, distance, speed) | success %, paper's rule [95 % CI] "
            "| collision %, paper's rule | success %, contact rule [95 % CI] | collision %, contact rule "
            "| time s | distance m | speed m/s | action | episodes |")
    lines = [head, "|" + "---|" * 12]
    for row in rows:
        if row["status"] != "ok":
            lines.append(f"| {row['stage']} | {row['method']} | {_paper(row['paper'])} | {row['status']} "
                         f"(`{row['policy']}`) | | | | | | | | |")
            continue
        scan = row.get("scan") or {}
        metric = [f"{scan[k]:.2f}" if scan and not math.isnan(scan[k]) else "–" for k in ("time", "distance", "speed")]
        lines.append(f"| {row['stage']} | {row['method']} | {_paper(row['paper'])} | {_pct(scan)} "
                     f"| {_collisions(scan)} | {_pct(row.get('contact'))} | {_collisions(row.get('contact'))} "
                     f"| {' | '.join(metric)} | {row.get('mode', 'mean')} | {scan.get('episodes', '–')} |")
    return "\n".join(lines) + "\n"


def _collisions(stats: dict[str, Any] | None) -> str:
    return f"{100 * stats['collision'] / stats['episodes']:.1f}" if stats else "–"
