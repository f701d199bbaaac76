"""The paper's tables from held-out evaluations, with the paper's numbers side by side.

``mjnav tables table=K`` (``scripts/paper_tables.py``) (K = 2: Designs 1-4 and Ours on stages 2-4; 3: the
reward ablation r_t1-r_t4 on stages 5-7, with Total Abs Acc; 4: Ours against TEB on stages 5-7)
reads one evaluation JSONL per (method, stage, collision rule) from ``out`` (default
``evals/paper``), runs the missing evaluations (:func:`mjnav.eval.runner.evaluate`, ``episodes``
held-out scenarios each, the policy's own training config plus ``collision=scan`` or
``collision=contact``), and prints one row per method and stage: our success under the paper's
collision rule (shrunk scan ≤ 0) and under MuJoCo contacts, each with a 95 % Wilson interval, the
paper's success, and time / distance / speed over the successful episodes under the paper's rule.
A method whose policy is not shipped (or whose file does not exist) is listed as "not trained",
never estimated. ``action=mean`` (default, spec §8) acts on the policy's mean through the shipped
actor (``policies/manifest.yaml``, :mod:`mjnav.shipped`); ``action=sample`` / ``expected`` use its
Gaussian through the shipped weights-only checkpoint (``NAME.weights``; "not trained" where none
is shipped) or, for a path, the ``*_checkpoint.pt`` beside it.

Files: ``<out>/<method slug>/<stage>_<rule>[_<action>].jsonl`` (the evaluation runner's JSONL;
a policy shared by two tables is evaluated once). A file with more episodes than requested answers
with its first ones. A file with fewer, or whose seed offset, policy or action mode differs from the
request, or whose policy file (a baseline: its parameters, :func:`mjnav.eval.runner.policy_sha256`)
has changed since, is evaluated again; records of another evaluation are kept, renamed
``<stage>_<rule>.<commit>-<sha>.jsonl``, never deleted. The contact rule is run first: its
episodes carry their outcome under the paper's rule wherever they determine it
(:func:`mjnav.eval.runner.settle_from_contact`), so the paper's-rule run only plays the rest.
"""
from __future__ import annotations

import bisect
import dataclasses
import math
import re
import sys
from collections.abc import Sequence
from pathlib import Path
from typing import Any

from mjnav.eval.intervals import wilson
from mjnav.eval.social import aggregate_social
from mjnav import shipped
from mjnav.eval.runner import _SPEC_KEYS, EvalSpec, evaluate, held_out_seed, policy_sha256, settle_from_contact
from mjnav.eval.runner import read_jsonl as load_rows

__all__ = ["TABLES", "Method", "Table", "format_social", "format_strata", "format_table", "load_rows",
           "TRACKS_SUFFIX", "planner_method", "success_by_distance",
           "table_rows", "wilson"]

RULES = ("scan", "contact")


@dataclasses.dataclass(frozen=True)
class Method:
    """One row family of a paper table.

    Attributes:
        name: As the paper names it (``Ours``, ``Design 1``, ``r_t2``, ``TEB``).
        policy: Policy spec, ``{stage}`` filled in per stage: a shipped policy's name
            (``stage6_policy``), a file (missing = "not trained") or a baseline name (``teb``).
        slug: Folder of its evaluations under ``out``; methods that evaluate the same policy share
            it (``Ours`` of Table IV is ``r_t1`` of Table III).
        paper: Stage -> the paper's (success %, time s, distance m, speed m/s[, Total Abs Acc]).
        planner: A baseline's parameter overrides (``("tracks=true",)``), as ``planner.*`` of
            ``mjnav evaluate``.
    """

    name: str
    policy: str
    slug: str
    paper: dict[str, tuple[float, ...]]
    planner: tuple[str, ...] = ()


@dataclasses.dataclass(frozen=True)
class Table:
    """A paper table: stages (rows grouped by stage), methods, and whether Total Abs Acc is shown."""

    stages: tuple[str, ...]
    methods: tuple[Method, ...]
    abs_acc: bool = False


_OURS_CROWD = {"stage5": (87.1, 2.9, 4.59, 1.57, 26475.46), "stage6": (78.1, 2.9, 4.12, 1.42, 19507.60),
               "stage7": (68.5, 3.1, 4.22, 1.36, 6348.57)}

#: Suffix of a ``planners=`` entry that runs the planner with its LiDAR tracks (``teb+tracks``:
#: ``planner.tracks=true``), and of its row label (``teb + tracks``).
TRACKS_SUFFIX = "+tracks"

#: The paper's tables II-IV (spec §11): methods, their shipped policies, the paper's numbers.
TABLES: dict[int, Table] = {
    2: Table(("stage2", "stage3", "stage4"), (
        Method("Design 1", "stage4_design1", "design1",
               {"stage2": (76, 4.0, 11.28, 2.87), "stage3": (79.9, 4.0, 11.37, 2.9),
                "stage4": (80.9, 3.9, 11.25, 2.95)}),
        Method("Design 2", "stage4_design2", "design2",
               {"stage2": (76, 4.0, 11.11, 2.8), "stage3": (79,), "stage4": (75.1,)}),
        Method("Design 3", "stage4_design3", "design3",
               {"stage2": (90.3, 9.0, 15.26, 1.72), "stage3": (87.8, 8.8, 15.42, 1.77), "stage4": (84.5,)}),
        Method("Design 4", "stage4_design4", "design4",
               {"stage2": (83, 5.0, 11.66, 2.23), "stage3": (83.5, 4.9, 11.59, 2.24), "stage4": (83.7,)}),
        Method("Ours", "{stage}_policy", "ours",
               {"stage2": (89.2, 5.5, 12.19, 2.18), "stage3": (89.1, 5.9, 13.04, 2.17),
                "stage4": (85.5, 5.8, 12.51, 2.1)}),
        Method("Ours + tracks", "{stage}_tracks_policy", "ours_tracks", {}),  # not in the paper (issue 39)
    )),
    3: Table(("stage5", "stage6", "stage7"), (
        Method("r_t1", "{stage}_policy", "ours", _OURS_CROWD),
        # the ablation's own r_t1: trained by the same protocol and budget as r_t2-r_t4
        Method("r_t1 (ablation run)", "stage7_r_t1", "r_t1", _OURS_CROWD),
        Method("r_t2", "stage7_r_t2", "r_t2",
               {"stage5": (87.8, 2.9, 4.65, 1.57, 27600.56), "stage6": (77.3, 2.8, 4.10, 1.43, 20397.66),
                "stage7": (69.9, 3.0, 4.15, 1.37, 7218.53)}),
        Method("r_t3", "stage7_r_t3", "r_t3",
               {"stage5": (84.8, 3.4, 4.38, 1.40, 27781.34), "stage6": (73.1, 3.4, 3.85, 1.25, 21988.81),
                "stage7": (67.1, 3.6, 3.98, 1.19, 6080.69)}),
        Method("r_t4", "stage7_r_t4", "r_t4",
               {"stage5": (86.7, 2.9, 4.65, 1.58, 26460.66), "stage6": (74.6, 3.0, 4.35, 1.46, 19950.77),
                "stage7": (65.3, 2.9, 3.88, 1.36, 5668.30)}),
    ), abs_acc=True),
    4: Table(("stage5", "stage6", "stage7"), (
        Method("TEB", "teb", "teb",
               {"stage5": (77.1, 4.4, 4.64, 1.11), "stage6": (65.2, 4.0, 4.21, 1.10),
                "stage7": (57.8, 3.8, 3.87, 1.07)}),
        Method("Ours", "{stage}_policy", "ours", {k: v[:4] for k, v in _OURS_CROWD.items()}),
        Method("Ours + tracks", "{stage}_tracks_policy", "ours_tracks", {}),  # not in the paper (issue 39)
    )),
}


def success_by_distance(rows: Sequence[dict[str, Any]], edges: Sequence[float] = (0.0, 2.0, 4.0, 6.0, 8.0)
                        ) -> list[dict[str, Any]]:
    """Success rate by straight start-goal distance: how a method's result depends on the trip.

    Args:
        rows: Evaluation records (the runner's JSONL), each with ``start``, ``goal`` (m) and ``outcome``.
        edges: Increasing bin edges, m; bin i holds distances in [edges[i], edges[i+1]), the last
            one [edges[-1], inf); shorter trips are not counted.

    Returns:
        One dict per bin: ``lo``, ``hi`` (m), ``episodes``, ``success`` (count), ``rate`` and its
        95 % Wilson interval ``ci`` (fractions; nan for an empty bin).

    Raises:
        ValueError: Edges not increasing or negative, or a record without start, goal or outcome.
    """
    edges = [float(e) for e in edges]
    if not edges or edges[0] < 0 or any(b <= a for a, b in zip(edges, edges[1:])):
        raise ValueError(f"edges must be non-negative and increasing, got {edges}")
    bounds = [*edges, math.inf]
    counts = [[0, 0] for _ in edges]
    for k, row in enumerate(rows):
        if not {"start", "goal", "outcome"} <= row.keys():
            raise ValueError(f"record {k} has no start, goal or outcome (not an evaluation JSONL?)")
        d = math.dist(row["start"], row["goal"])
        i = bisect.bisect_right(edges, d) - 1
        if i >= 0:
            counts[i][0] += 1
            counts[i][1] += row["outcome"] == "success"
    return [{"lo": lo, "hi": hi, "episodes": n, "success": s, "rate": s / n if n else math.nan,
             "ci": wilson(s, n)} for (lo, hi), (n, s) in zip(zip(bounds, bounds[1:]), counts)]


def format_strata(series: dict[str, list[dict[str, Any]]]) -> str:
    """Markdown: one row per distance bin, one column per method (success % [95 % CI] (episodes))."""
    names = list(series)
    if not names:
        return ""
    lines = ["| start-goal distance | " + " | ".join(names) + " |", "|---" * (len(names) + 1) + "|"]
    for i, first in enumerate(series[names[0]]):
        label = f"{first['lo']:g}-{first['hi']:g} m" if math.isfinite(first["hi"]) else f">= {first['lo']:g} m"
        cells = []
        for name in names:
            b = series[name][i]
            cells.append("–" if not b["episodes"] else
                         f"{100 * b['rate']:.1f} [{100 * b['ci'][0]:.1f}, {100 * b['ci'][1]:.1f}] ({b['episodes']})")
        lines.append(f"| {label} | " + " | ".join(cells) + " |")
    return "\n".join(lines)


def _stats(rows: Sequence[dict[str, Any]]) -> dict[str, Any]:
    n = len(rows)
    wins = [r for r in rows if r["outcome"] == "success"]
    collisions = sum(r["outcome"] == "collision" for r in rows)
    out: dict[str, Any] = {"episodes": n, "success": len(wins), "collision": collisions}
    for key, name in (("time_s", "time"), ("distance_m", "distance"), ("mean_speed", "speed")):
        out[name] = sum(r["metrics"][key] for r in wins) / len(wins) if wins else math.nan
    out["abs_acc"] = sum(r["metrics"].get("abs_acc_sum", math.nan) for r in wins)  # the paper's sum over successes
    out["social"] = aggregate_social(rows)
    return out


def evaluation_path(out: Path, method: Method, stage: str, rule: str, action: str) -> Path:
    """``<out>/<slug>/<stage>_<rule>[_<action>].jsonl`` (no suffix for the mean action)."""
    return out / method.slug / f"{stage}_{rule}{'' if action == 'mean' else '_' + action}.jsonl"


def table_rows(table: int, out: Path, episodes: int, seed_offset: int = 0, workers: int = 2,
               run_missing: bool = True, action: str = "mean",
               methods: Sequence[str] | None = None, planners: Sequence[str] = ()) -> list[dict[str, Any]]:
    """One row per (stage, method): our numbers under both rules and the paper's.

    ``methods``: only these methods (their names as in the table, e.g. ``("Ours",)``), for
    re-running one method after retraining it; all when None. ``planners``: planner specs added as
    methods (a registered name, ``package.module:Class`` or ``file.py:Class``; :func:`planner_method`);
    a planner that reads ground truth has ``privileged`` set and is marked "(privileged)".

    Evaluations missing from ``out`` (or made with other episodes, seeds, policy or action mode)
    are run when ``run_missing`` is set; otherwise that rule's entry holds what an unfinished run of it
    has so far (episodes 0 .. n-1, shown as "n of N") or None (shown as "–").
    Baselines (``teb``) have no action mode and always act as themselves.

    Raises:
        ValueError: A name in ``methods`` is not one of the table's.
    """
    # deferred: mjnav.policy ~0.2 s (planners: MPC, numba, scipy, osqp), not needed by `mjnav tables --help`
    from mjnav.eval.policies import planner_record
    from mjnav.policy import BASELINES, training_overrides

    chosen = _chosen_methods((*TABLES[table].methods, *(planner_method(p) for p in planners)), methods)
    rows = []
    for stage in TABLES[table].stages:
        for method in chosen:
            baseline = method.policy in BASELINES
            mode = "mean" if baseline else action
            policy = method.policy if baseline else _policy_file(method.policy.format(stage=stage), mode)
            row: dict[str, Any] = {"stage": stage, "method": method.name, "policy": policy,
                                   "paper": method.paper.get(stage, ()), "mode": "–" if baseline else mode,
                                   "privileged": bool(baseline and planner_record(policy)["planner_privileged"])}
            overrides = method.planner
            if not baseline and (policy is None or shipped.find(policy) is None and not Path(policy).is_file()):
                rows.append({**row, "status": "not trained"})
                continue
            for rule in ("contact", "scan"):  # the contact run settles most episodes of the paper's rule
                path = evaluation_path(out, method, stage, rule, mode)
                found = _first(load_rows(path), episodes)
                if not _matches(found, episodes, seed_offset, policy, mode, overrides):
                    if not run_missing:  # an unfinished run (resumable) shows as what it has so far
                        partial = _prefix(load_rows(path.parent / f"{stage}.jsonl"), rule, seed_offset, policy, mode,
                                          episodes, overrides)
                        # its Total Abs Acc, a sum, is not comparable
                        row[rule] = {**_stats(partial), "abs_acc": math.nan, "of": episodes} if partial else None
                        continue
                    spec = EvalSpec(stage, policy, episodes, seed_offset, (f"collision={rule}",), workers,
                                    training_overrides(policy), mode, overrides)
                    if rule == "scan":
                        contact = evaluation_path(out, method, stage, "contact", mode)
                        settle_from_contact(spec, contact, path.parent)
                    evaluate(spec, path.parent, progress=True)
                    _replace_keeping(path.parent / f"{stage}.jsonl", path)
                    found = _first(load_rows(path), episodes)
                row[rule] = _stats(found)
            rows.append({**row, "status": "ok"})
    return rows


def _replace_keeping(new: Path, path: Path) -> None:
    """Move the evaluation ``new`` to ``path``; records already at ``path`` from another evaluation (other
    policy version, commit, seeds or overrides) are first moved aside to ``<stem>.<commit>-<sha>.jsonl``."""
    old, now = load_rows(path)[:1], load_rows(new)[:1]
    if old and now and any(old[0].get(k) != now[0].get(k) for k in (*_SPEC_KEYS, "seed")):
        aside = f"{str(old[0].get('commit'))[:8]}-{old[0].get('policy_sha256')}"
        path.replace(path.with_name(f"{path.stem}.{aside}.jsonl"))
        print(f"kept the earlier evaluation {path} as {path.stem}.{aside}.jsonl", file=sys.stderr)
    new.replace(path)


def _first(found: Sequence[dict[str, Any]], episodes: int) -> list[dict[str, Any]]:
    """The records of episodes 0 .. ``episodes`` − 1, by index (a longer evaluation answers a shorter request)."""
    by_index: dict[Any, dict[str, Any]] = {}
    for record in found:
        by_index.setdefault(record.get("index"), record)
    return [by_index[i] for i in range(episodes) if i in by_index]


def planner_method(spec: str) -> Method:
    """A planner as a table method: its display name, evaluations under ``<out>/planner_<name>/``, no
    paper numbers. ``SPEC+tracks`` (:data:`TRACKS_SUFFIX`) is the planner with ``planner.tracks=true``
    (its LiDAR tracks), labelled ``<name> + tracks``, under ``<out>/planner_<name>_tracks/``.

    Raises:
        mjnav.planners.PlannerError, mjnav.registry.RegistryError: A spec that does not load.
        ConfigError: ``+tracks`` for a planner without a ``tracks`` parameter.
    """
    # deferred: mjnav.planners ~0.2 s (MPC, numba, scipy, osqp), not needed by `mjnav tables --help`
    from mjnav.planners import resolve_planner

    tracked = spec.endswith(TRACKS_SUFFIX)
    base = spec[: -len(TRACKS_SUFFIX)] if tracked else spec
    found = resolve_planner(base)
    slug = "planner_" + re.sub(r"[^\w.-]", "_", found.name)
    if not tracked:
        return Method(found.name, base, slug, {})
    found.config(["tracks=true"])  # a planner without the parameter fails here, naming it
    return Method(f"{found.name} + tracks", base, slug + "_tracks", {}, ("tracks=true",))


def _method_label(row: dict[str, Any]) -> str:
    """The method as the tables print it: a planner reading ground truth is marked "(privileged)"."""
    return f"{row['method']} (privileged)" if row.get("privileged") else row["method"]


def _chosen_methods(methods: Sequence[Method], names: Sequence[str] | None) -> tuple[Method, ...]:
    """The ``methods`` (the table's, then the added planners) named in ``names`` (all for None), in order."""
    if names is None:
        return tuple(methods)
    known = [m.name for m in methods]
    unknown = [n for n in names if n not in known]
    if unknown:
        raise ValueError(f"methods: {unknown} not in this table (known: {known})")
    return tuple(m for m in methods if m.name in names)


def _policy_file(policy: str, action: str) -> str | None:
    """What to load: the actor for the mean; for sampling a shipped policy's ``NAME.weights`` (None
    where it ships none) or the ``*_checkpoint.pt`` beside a file."""
    if action == "mean":
        return policy
    if policy in shipped.names():
        return f"{policy}{shipped.WEIGHTS_SUFFIX}" if shipped.get(policy).weights else None
    path = Path(policy)
    return str(path.with_name(f"{path.stem.removesuffix('_policy')}_checkpoint.pt"))


def _matches(found: Sequence[dict[str, Any]], episodes: int, seed_offset: int, policy: str, action: str,
             planner: Sequence[str] = ()) -> bool:
    """The records are ``episodes`` episodes of this policy file (path and content), planner
    parameters (``planner``: overrides), action mode and seeds."""
    # deferred: mjnav.eval.policies ~0.2 s (planners: MPC, numba, scipy, osqp), not needed by `mjnav tables --help`
    from mjnav.eval.policies import planner_record

    if len(found) != episodes:
        return False
    first = found[0]
    return (first.get("policy_source") == policy and first.get("policy_sha256") == policy_sha256(policy, planner)
            and first.get("planner_sha256") == planner_record(policy, planner)["planner_sha256"]
            and first.get("action_mode", "mean") == action
            and first.get("seed") == held_out_seed(first.get("index", 0), seed_offset))


def _prefix(found: Sequence[dict[str, Any]], rule: str, seed_offset: int, policy: str, action: str,
            episodes: int, planner: Sequence[str] = ()) -> list[dict[str, Any]]:
    """Episodes 0 .. n-1 of an unfinished evaluation under ``rule``, up to its first gap ([] if none).

    Workers finish chunks out of order, so a stopped run can hold later episodes past a gap; they
    are left out (keeping them would favour the episodes that finish fast).
    """
    by_index = {r.get("index"): r for r in found if r.get("collision") == rule}
    rows: list[dict[str, Any]] = []
    while len(rows) < episodes and len(rows) in by_index:
        rows.append(by_index[len(rows)])
    return rows if rows and _matches(rows, len(rows), seed_offset, policy, action, planner) else []


def _pct(stats: dict[str, Any] | None) -> str:
    if not stats:
        return "–"
    lo, hi = wilson(stats["success"], stats["episodes"])
    return f"{100 * stats['success'] / stats['episodes']:.1f} [{100 * lo:.1f}, {100 * hi:.1f}]"


def _paper(values: tuple[float, ...]) -> str:
    if not values:
        return "–"
    text = f"{values[0]:g}"
    if len(values) >= 4:
        acc = f", {values[4]:g}" if len(values) > 4 else ""
        text += f" ({values[1]:g} s, {values[2]:g} m, {values[3]:g} m/s{acc})"
    return text


def format_table(rows: Sequence[dict[str, Any]], abs_acc: bool = False, social: bool = False) -> str:
    """Markdown: stage, method, paper, ours under both rules (success with CI, collisions), time/distance/speed
    (and, with ``abs_acc``, the paper's Total Abs Acc) over the successes under the paper's rule, action mode,
    episodes; with ``social``, then a second table of the social metrics (:func:`format_social`)."""
    if social:
        return _format_paper(rows, abs_acc) + "\n" + format_social(rows)
    return _format_paper(rows, abs_acc)


#: Social columns of :func:`format_social`: (summary key, label, format): ``rate`` = a rate with its Wilson
#: interval; ``near/far:<format>`` = ``<key>_near`` / ``<key>_far`` in one cell; else a number format.
_SOCIAL_TABLE = (
    ("mean_min_ped_distance_m", "min gap to a pedestrian m", "{:.3f}"),
    ("intrusion_share", "intrusion % steps [95 % CI]", "rate"),
    ("personal_share", "personal space % steps [95 % CI]", "rate"),
    ("social_share", "social zone % steps [95 % CI]", "rate"),
    ("near_misses_per_episode", "near misses / ep.", "{:.2f}"),
    ("mean_min_ttc_s", "min TTC s", "{:.2f}"),
    ("path_efficiency", "path efficiency", "{:.3f}"),
    ("spl", "SPL", "{:.3f}"),
    ("stopped_time_s", "stopped s", "{:.2f}"),
    ("ped_speed", "ped. speed near / far m/s", "near/far:{:.3f}"),
    ("ped_accel", "ped. accel. near / far m/s²", "near/far:{:.2f}"),
    ("ped_turn", "ped. turn rate near / far rad/s", "near/far:{:.3f}"),
    ("collision_pedestrian_rate", "collisions with pedestrians % [95 % CI]", "rate"),
    ("collision_obstacle_rate", "with obstacles % [95 % CI]", "rate"),
    ("collision_wall_rate", "with walls % [95 % CI]", "rate"),
)


def format_social(rows: Sequence[dict[str, Any]]) -> str:
    """Markdown: the social metrics (:mod:`mjnav.eval.social`) of each row under the paper's rule (– where
    the records predate them); thresholds as in :data:`mjnav.eval.social.THRESHOLDS`."""
    lines = ["| stage | method | " + " | ".join(label for _, label, _ in _SOCIAL_TABLE) + " |",
             "|" + "---|" * (2 + len(_SOCIAL_TABLE))]
    for row in rows:
        summary = ((row.get("scan") or {}).get("social") or {}) if row["status"] == "ok" else {}
        cells = [_social_cell(summary, key, fmt) for key, _, fmt in _SOCIAL_TABLE]
        lines.append(f"| {row['stage']} | {_method_label(row)} | " + " | ".join(cells) + " |")
    return "\n".join(lines) + "\n"


def _social_cell(summary: dict[str, float], key: str, fmt: str) -> str:
    if fmt.startswith("near/far:"):  # near and far from the robot (within / beyond the social zone)
        return " / ".join(_social_cell(summary, f"{key}_{side}", fmt.removeprefix("near/far:"))
                          for side in ("near", "far"))
    value = summary.get(key, math.nan)
    if value is None or math.isnan(value):
        return "–"
    if fmt == "rate":
        return f"{100 * value:.1f} [{100 * summary[key + '_lo']:.1f}, {100 * summary[key + '_hi']:.1f}]"
    return fmt.format(value)


def _format_paper(rows: Sequence[dict[str, Any]], abs_acc: bool) -> str:
    """The paper's columns of :func:`format_table`."""
    extra = ["time s", "distance m", "speed m/s"] + (["Total Abs Acc"] if abs_acc else [])
    paper = "paper success % (time, distance, speed" + (", Total Abs Acc)" if abs_acc else ")")
    head = (f"| stage | method | {paper} | success %, paper's rule [95 % CI] | collision %, paper's rule "
            f"| success %, contact rule [95 % CI] | collision %, contact rule | {' | '.join(extra)} "
            "| action | episodes |")
    cols = 9 + len(extra)
    lines = [head, "|" + "---|" * cols]
    keys = ("time", "distance", "speed", "abs_acc")[: len(extra)]
    for row in rows:
        if row["status"] != "ok":
            lines.append(f"| {row['stage']} | {_method_label(row)} | {_paper(row['paper'])} | {row['status']} "
                         f"(`{row['policy']}`) |" + " |" * (cols - 4))
            continue
        scan = row.get("scan") or {}
        metric = [_number(scan.get(k), 1 if k == "abs_acc" else 2) for k in keys]
        lines.append(f"| {row['stage']} | {_method_label(row)} | {_paper(row['paper'])} | {_pct(scan)} "
                     f"| {_collisions(scan)} | {_pct(row.get('contact'))} | {_collisions(row.get('contact'))} "
                     f"| {' | '.join(metric)} | {row.get('mode', 'mean')} | {_episodes(row)} |")
    return "\n".join(lines) + "\n"


def _episodes(row: dict[str, Any]) -> str:
    """Episodes per rule; an unfinished evaluation as "n of N"."""
    counts = []
    for rule in RULES:
        stats = row.get(rule)
        if stats:
            counts.append(f"{stats['episodes']} of {stats['of']}" if "of" in stats else str(stats["episodes"]))
    return " / ".join(dict.fromkeys(counts)) or "–"


def _number(value: float | None, digits: int) -> str:
    return "–" if value is None or math.isnan(value) else f"{value:.{digits}f}"


def _collisions(stats: dict[str, Any] | None) -> str:
    return f"{100 * stats['collision'] / stats['episodes']:.1f}" if stats else "–"
