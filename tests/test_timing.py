"""mjnav.timing: interleaved rounds."""

import numpy as np

from mjnav.timing import time_rounds


def test_rounds_alternate_the_order_and_time_every_block() -> None:
    calls = []

    def make(name: str, steps: int):
        def block() -> int:
            calls.append(name)
            return steps

        return block

    rates = time_rounds({"a": make("a", 10), "b": make("b", 20)}, rounds=3)
    assert calls == ["a", "b", "b", "a", "a", "b"]
    assert set(rates) == {"a", "b"} and all(len(v) == 3 and (v > 0).all() for v in rates.values())
    assert np.median(rates["b"]) > 0
