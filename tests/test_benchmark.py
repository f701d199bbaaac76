"""mjnav.bench.throughput (``mjnav bench throughput``): interleaved rounds and the per-part breakdown."""

import numpy as np
import pytest

from mjnav.config import load_task
from mjnav.bench import throughput
from mjnav.jobs import usable_cores
from mjnav.schema import ConfigError


def _script():
    return throughput


def test_adapter_rows_cover_the_worker_counts_then_processes() -> None:
    bench = _script()
    assert [(w, main) for _, w, main in bench.adapter_rows([1, 2, 4])] == [(1, True), (2, True), (4, True), (4, False)]
    assert [(w, main) for _, w, main in bench.adapter_rows([1])] == [(1, True), (2, False)]


def test_worker_lists() -> None:
    """``workers=1,2,4,8,15``: counts in order, duplicates dropped, ``cores`` the usable cores; bad lists refused."""
    parse = _script().parse_workers
    assert parse("1,2,4,8,15", 64) == [1, 2, 4, 8, 15]
    assert parse("1, 2,2", 64) == [1, 2]
    assert parse("cores", 64) == [min(64, usable_cores())]
    for bad in ("0", "1,x", "65", "", "-1"):
        with pytest.raises(ConfigError, match="workers"):
            parse(bad, 64)


def _two_timed_blocks(bench) -> dict[str, float]:
    """Two blocks after the uncounted warm-up; ``bench.parts()``, with its environment closed."""
    try:
        assert bench.total_steps == 0  # the warm-up block is not counted
        bench.block()
        bench.block()
        return bench.parts()
    finally:
        bench.env.close()


def test_single_env_parts_add_up_to_the_measured_time() -> None:
    single = _script().SingleEnv(load_task("stage1"), steps=20, seed=0)
    parts = _two_timed_blocks(single)
    assert single.total_steps == 40
    assert {"physics", "lidar", "region", "mpc", "observation", "reward"} <= set(parts)
    assert all(parts[k] > 0 for k in ("physics", "lidar", "region", "mpc"))
    assert np.isclose(sum(parts.values()), 1e6 * single.total_time / 40)


def test_adapter_split_adds_up_to_the_measured_time() -> None:
    """The adapter's own block, wait, bookkeeping and outside parts add up to the timed blocks."""
    vec = _script().VecBench(load_task("stage1"), num_envs=2, workers=0, steps=5, seed=0, step_in_main=True)
    split = _two_timed_blocks(vec)
    assert vec.total_steps == 10
    assert split["own block"] > 0.0 and split["adapter bookkeeping"] > 0.0
    assert split["wait for worker processes"] < 0.1 * split["own block"]  # no worker processes here
    assert np.isclose(sum(split.values()), vec.sums["total"] / 10)


def test_envs_in_turn_step_every_environment() -> None:
    """The no-adapter reference steps each of its environments once per block step, in turn or in
    stages, to the same states."""
    script = _script()
    in_turn = script.EnvsInTurn(load_task("stage1"), num_envs=3, steps=2, seed=0)
    in_stages = script.EnvsInTurn(load_task("stage1"), num_envs=3, steps=2, seed=0, staged=True)
    try:
        assert in_turn.block() == in_stages.block() == 6
        assert len(in_turn.envs) == 3
        for a, b in zip(in_turn.envs, in_stages.envs, strict=True):
            np.testing.assert_array_equal(a.physics.data.qpos, b.physics.data.qpos)
            np.testing.assert_array_equal(a.task.observation, b.task.observation)
    finally:
        in_turn.close()
        in_stages.close()
