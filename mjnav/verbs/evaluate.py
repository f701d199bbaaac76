"""``mjnav evaluate``: held-out evaluation (:mod:`mjnav.eval.runner`)."""

from __future__ import annotations

from mjnav.args import Grammar, Parsed
from mjnav.eval.runner import grammar as runner_grammar
from mjnav.eval.runner import main

__all__ = ["grammar", "run"]


def grammar() -> Grammar:
    """:func:`mjnav.eval.runner.grammar` (its options are :class:`mjnav.eval.runner.EvaluateOptions`)."""
    return runner_grammar()


def run(parsed: Parsed, argv: list[str]) -> int:
    """Evaluate, write the files, print the table (:func:`mjnav.eval.runner.main`)."""
    return main(argv)
