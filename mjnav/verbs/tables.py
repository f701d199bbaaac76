"""``mjnav tables``: regenerate a table of the paper from held-out evaluations (:mod:`mjnav.eval.tables`).

Reads ``<out>/<method>/<stage>_<rule>.jsonl``, runs the evaluations that are missing (``run=false``:
reports them as missing, or an unfinished one as "n of N" episodes so far) and prints the table in
markdown. Tables use each policy's training config, so no task overrides are taken.
"""

from __future__ import annotations

import dataclasses
import sys
from pathlib import Path

from mjnav.args import Grammar, Parsed
from mjnav.eval.runner import EvalError
from mjnav.eval.tables import TABLES, format_table, table_rows
from mjnav.jobs import usable_cores
from mjnav.schema import ConfigError

__all__ = ["TablesOptions", "grammar", "run"]


@dataclasses.dataclass(frozen=True)
class TablesOptions:
    """The ``tables`` verb's own keys.

    Attributes:
        table: The paper's table number (2, 3 or 4).
        episodes: Held-out scenarios per method and stage.
        out: Folder of the evaluation records (``<out>/<method>/<stage>_<rule>.jsonl``).
        workers: Worker processes of the evaluations that are run (default: one per CPU core this process may use).
        seed_offset: Offset of the held-out episode seeds.
        run: Run the missing evaluations (false: report them as missing).
        action: ``mean``, ``expected`` or ``sample`` (how a learned policy acts).
        methods: Comma-separated methods to keep (names as the table prints them); empty: all.
        social: Add a table of the social-navigation metrics (:mod:`mjnav.eval.social`).
        planners: Comma-separated planners added as methods: registered names, ``package.module:Class``
            or ``path/to/file.py:Class``; those reading ground truth are marked "(privileged)";
            ``NAME+tracks`` adds NAME with ``planner.tracks=true`` (its LiDAR tracks), row "NAME + tracks".
    """

    table: int = 2
    episodes: int = 1000
    out: str = "evals/paper"
    workers: int | None = None
    seed_offset: int = 0
    run: bool = True
    action: str = "mean"
    methods: str = ""
    social: bool = False
    planners: str = ""


def grammar() -> Grammar:
    """:class:`TablesOptions`; no config overrides."""
    return Grammar(TablesOptions, ())


def run(parsed: Parsed, argv: list[str]) -> int:
    """Build the table and print it; returns the exit code."""
    # deferred: mjnav.eval.policies ~0.2 s (planners: MPC, numba, scipy, osqp), not needed by `mjnav tables --help`
    from mjnav.eval.policies import ACTION_MODES

    opts: TablesOptions = parsed.options
    try:
        if opts.action not in ACTION_MODES:
            raise ConfigError(f"action: expected one of {ACTION_MODES}, got {opts.action!r}")
        if opts.table not in TABLES:
            raise ConfigError(f"table: {opts.table} is not available (known: {sorted(TABLES)})")
        names = [n.strip() for n in opts.methods.split(",") if n.strip()] or None
        workers = usable_cores() if opts.workers is None else opts.workers
        planners = [p.strip() for p in opts.planners.split(",") if p.strip()]
        rows = table_rows(opts.table, Path(opts.out), opts.episodes, opts.seed_offset, workers, opts.run,
                          opts.action, names, planners)
    # EvalError: a file of another evaluation; KeyError: an unknown planner name
    except (ConfigError, ValueError, KeyError, FileNotFoundError, EvalError) as err:
        print(f"error: {err}", file=sys.stderr)
        return 2
    print(format_table(rows, TABLES[opts.table].abs_acc, opts.social), end="")
    return 0
