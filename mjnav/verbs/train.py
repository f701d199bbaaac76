"""``mjnav train``: a PPO training session (:mod:`mjnav.train.session`)."""

from __future__ import annotations

import sys

from mjnav.args import Grammar, Parsed
from mjnav.schema import ConfigError

__all__ = ["grammar", "run"]


def grammar() -> Grammar:
    """:func:`mjnav.train.session.grammar` (its options are :class:`mjnav.train.session.TrainOptions`)."""
    from mjnav.train.session import grammar as session_grammar

    return session_grammar()


def run(parsed: Parsed, argv: list[str]) -> int:
    """Train; the run folder records ``argv`` as given."""
    from mjnav.train.session import run as run_session

    try:
        run_session(argv)
    except ConfigError as err:
        print(f"error: {err}", file=sys.stderr)
        return 2
    return 0
