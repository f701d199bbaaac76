"""Regenerate a table of the paper from held-out evaluations (see :mod:`mjnav.eval.tables`).

    python scripts/paper_tables.py table=2|3|4 [episodes=1000] [out=evals/paper] [workers=2]
                                   [seed_offset=0] [run=true] [action=mean|expected|sample]
                                   [methods=Ours,TEB] [social=false]

Reads ``<out>/<method>/<stage>_<rule>.jsonl``, runs the evaluations that are missing
(``run=false``: report them as missing, or an unfinished one as "n of N" episodes so far) and prints the table in markdown.
``methods`` keeps only the named methods (names as the table prints them), e.g. to re-run Ours
after retraining it without touching the baselines' records. ``social=true`` adds a table of the
social-navigation metrics (see :mod:`mjnav.eval.social`).
"""

from __future__ import annotations

import os
import sys
from pathlib import Path

from mjnav.schema import ConfigError, split_args


def main(argv: list[str]) -> int:
    """Parse ``key=value`` arguments, build the table, print it; returns the exit code."""
    from mjnav.eval.policies import ACTION_MODES
    from mjnav.eval.runner import EvalError
    from mjnav.eval.tables import TABLES, format_table, table_rows

    defaults = {"table": 2, "episodes": 1000, "out": "evals/paper", "workers": os.cpu_count() or 1,
                "seed_offset": 0, "run": True, "action": "mean", "methods": "", "social": False}
    try:
        opts, extra = split_args(argv, defaults)
        if extra:
            raise ConfigError(f"unexpected task overrides {extra}: tables use each policy's training config")
        table = int(opts["table"])
        if opts["action"] not in ACTION_MODES:
            raise ConfigError(f"action: expected one of {ACTION_MODES}, got {opts['action']!r}")
        if table not in TABLES:
            raise ConfigError(f"table: {table} is not available (known: {sorted(TABLES)})")
        names = [n.strip() for n in str(opts["methods"]).split(",") if n.strip()] or None
        rows = table_rows(table, Path(str(opts["out"])), int(opts["episodes"]), int(opts["seed_offset"]),
                          int(opts["workers"]), bool(opts["run"]), str(opts["action"]), names)
    except (ConfigError, ValueError, FileNotFoundError, EvalError) as err:  # EvalError: a file of another evaluation
        print(f"error: {err}", file=sys.stderr)
        return 2
    print(format_table(rows, TABLES[table].abs_acc, bool(opts["social"])), end="")
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
