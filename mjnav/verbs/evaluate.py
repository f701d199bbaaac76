"""``mjnav evaluate``: held-out evaluation (:mod:`mjnav.eval.runner`), or the merge of its shards
(``merge=``, :mod:`mjnav.eval.shards`)."""

from __future__ import annotations

import sys
from pathlib import Path

from mjnav.args import Grammar, Parsed
from mjnav.eval.metrics import format_markdown
from mjnav.eval.runner import EvalError
from mjnav.eval.runner import grammar as runner_grammar
from mjnav.eval.runner import main
from mjnav.eval.shards import merge as merge_shards

__all__ = ["grammar", "run"]

#: The keys ``merge=`` may be given with.
MERGE_KEYS = frozenset({"merge", "out", "episodes"})


def grammar() -> Grammar:
    """:func:`mjnav.eval.runner.grammar` (its options are :class:`mjnav.eval.runner.EvaluateOptions`)."""
    return runner_grammar()


def run(parsed: Parsed, argv: list[str]) -> int:
    """Evaluate, write the files, print the table (:func:`mjnav.eval.runner.main`); with ``merge=``,
    merge shards instead (:func:`merge`)."""
    if parsed.options.merge is None:
        return main(argv)
    return merge(parsed)


def merge(parsed: Parsed) -> int:
    """``merge=A,B,... [out=DIR] [episodes=N]``: merge shard files into ``out`` (default: the first
    source's folder), episodes 0 .. N − 1 of each task (default: the count the shards were run with)."""
    extra = sorted(set(parsed.given) - MERGE_KEYS) + [f"{p}.*" for p in ("task", "planner") if getattr(parsed, p)]
    sources = [s.strip() for s in parsed.options.merge.split(",") if s.strip()]
    try:
        if extra:
            raise EvalError(f"merge: takes only merge=, out= and episodes=, got {', '.join(extra)}")
        if not sources:
            raise EvalError("merge: expected comma-separated shard folders or JSONL files")
        first = Path(sources[0])
        out = Path(parsed.options.out) if parsed.options.out else (first if first.is_dir() else first.parent)
        rows = merge_shards(sources, out, parsed.options.episodes if "episodes" in parsed.given else None)
    except EvalError as err:
        print(f"error: {err}", file=sys.stderr)
        return 2
    print(format_markdown(rows), end="")
    for row in rows:
        if row["left_out"]:
            print(f"{row['task']}: {row['left_out']} records past episode {int(row['episodes']) - 1} are left out "
                  f"(the shard files keep them)")
    print(f"wrote {out}/summary.csv, {out}/summary.md and one merged JSONL per task")
    return 0
