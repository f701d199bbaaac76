"""scripts/benchmark.py: interleaved rounds and the per-part breakdown."""

import importlib.util
from pathlib import Path

import numpy as np

from mjnav.config import load_task

ROOT = Path(__file__).resolve().parents[1]


def _script():
    spec = importlib.util.spec_from_file_location("benchmark", ROOT / "scripts" / "benchmark.py")
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


def test_rounds_alternate_the_order_and_time_every_block() -> None:
    calls = []

    def make(name: str, steps: int):
        def block() -> int:
            calls.append(name)
            return steps

        return block

    rates = _script().time_rounds({"a": make("a", 10), "b": make("b", 20)}, rounds=3)
    assert calls == ["a", "b", "b", "a", "a", "b"]
    assert set(rates) == {"a", "b"} and all(len(v) == 3 and (v > 0).all() for v in rates.values())
    assert np.median(rates["b"]) > 0


def test_adapter_rows_cover_one_two_and_all_cores() -> None:
    bench = _script()
    assert [(w, main) for _, w, main in bench.adapter_rows(4)] == [(1, True), (2, True), (4, True), (4, False)]
    assert [(w, main) for _, w, main in bench.adapter_rows(1)] == [(1, True), (2, True), (2, False)]


def test_single_env_parts_add_up_to_the_measured_time() -> None:
    single = _script().SingleEnv(load_task("stage1"), steps=20, seed=0)
    try:
        assert single.total_steps == 0  # the warm-up block is not counted
        single.block()
        single.block()
        parts = single.parts()
    finally:
        single.env.close()
    assert single.total_steps == 40
    assert {"physics", "lidar", "region", "mpc", "observation", "reward"} <= set(parts)
    assert all(parts[k] > 0 for k in ("physics", "lidar", "region", "mpc"))
    assert np.isclose(sum(parts.values()), 1e6 * single.total_time / 40)
