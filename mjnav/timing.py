"""Interleaved timing of code blocks, for the speed benchmarks (``mjnav bench``, ``scripts/compare_speed.py``).

This machine's speed drifts by up to 2x within minutes, so blocks that are to be compared run
in alternation: every round runs each block once, and the order reverses from one round to the
next, so drift and warm-cache effects fall on every block alike.
"""

from __future__ import annotations

import time
from collections.abc import Callable

import numpy as np

__all__ = ["Block", "time_rounds"]

Block = Callable[[], int]
"""Runs once and returns how many steps it took (env steps, mj_steps, ...)."""


def time_rounds(blocks: dict[str, Block], rounds: int) -> dict[str, np.ndarray]:
    """Steps/s of every block in each of ``rounds`` rounds, in alternating order.

    Returns:
        ``{name: (rounds,) array of steps/s}``.
    """
    names = list(blocks)
    rates: dict[str, list[float]] = {name: [] for name in names}
    for r in range(rounds):
        for name in names if r % 2 == 0 else names[::-1]:
            start = time.perf_counter()
            steps = blocks[name]()
            rates[name].append(steps / (time.perf_counter() - start))
    return {name: np.array(values) for name, values in rates.items()}
