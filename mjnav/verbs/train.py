"""``mjnav train``: a PPO training session (:mod:`mjnav.train.session`)."""

from __future__ import annotations

import sys

from mjnav.args import Grammar, Parsed
from mjnav.envs.vec_env import EnvError
from mjnav.schema import ConfigError
from mjnav.train.session import grammar as session_grammar
from mjnav.train.session import run as run_session

__all__ = ["grammar", "run"]


def grammar() -> Grammar:
    """:func:`mjnav.train.session.grammar` (its options are :class:`mjnav.train.session.TrainOptions`)."""
    return session_grammar()


def run(parsed: Parsed, argv: list[str]) -> int:
    """Train; the run folder records ``argv`` as given. 2 on a configuration error, 1 when an
    environment failed (after saving the weights of the last completed iteration)."""
    try:
        run_session(argv)
    except ConfigError as err:
        print(f"error: {err}", file=sys.stderr)
        return 2
    except EnvError as err:  # a worker died or an environment raised: its traceback is in the message
        print(f"error: {err}", file=sys.stderr)
        return 1
    return 0
