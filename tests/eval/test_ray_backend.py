"""``backend=ray``: the held-out episodes as Ray tasks (local Ray, loopback only) give the local
backend's records, episode for episode; a worker process builds its environment once."""

from __future__ import annotations

from pathlib import Path

import pytest

from mjnav.eval import runner
from mjnav.eval.runner import EvalSpec, evaluate_tasks

from tests.eval._same import records, summary

ray = pytest.importorskip("ray")

OVERRIDES = ("timing.episode_steps=20",)
EPISODES = 5


@pytest.fixture(scope="module")
def local_ray():
    """A local Ray with 2 CPUs, no dashboard (the evaluation joins it instead of starting its own)."""
    ray.init(num_cpus=2, include_dashboard=False, log_to_driver=False)
    yield
    ray.shutdown()


def test_ray_gives_the_local_records_episode_for_episode(local_ray, tmp_path: Path) -> None:
    spec = EvalSpec("stage5", "mpc_goal", EPISODES, 0, OVERRIDES, 1)
    evaluate_tasks([spec], tmp_path / "local", progress=False)
    evaluate_tasks([EvalSpec(**{**spec.__dict__, "workers": 2, "backend": "ray"})], tmp_path / "ray",
                   progress=False)
    assert records(tmp_path / "ray" / "stage5.jsonl") == records(tmp_path / "local" / "stage5.jsonl")
    assert summary(tmp_path / "ray" / "summary.csv") == summary(tmp_path / "local" / "summary.csv")
    # a shard on Ray is that shard of the local run
    evaluate_tasks([EvalSpec(**{**spec.__dict__, "workers": 2, "backend": "ray", "shard": (1, 2)})],
                   tmp_path / "ray", progress=False)
    local = {r["index"]: r for r in records(tmp_path / "local" / "stage5.jsonl")}
    shard = records(tmp_path / "ray" / "stage5.shard-1-of-2.jsonl", drop=("shard",))
    assert [r["index"] for r in shard] == [1, 3] and shard == [local[1], local[3]]


def test_a_bad_policy_fails_before_any_task(local_ray, tmp_path: Path) -> None:
    with pytest.raises((runner.EvalError, FileNotFoundError), match="no_such_policy"):
        evaluate_tasks([EvalSpec("stage5", "no_such_policy", 2, 0, OVERRIDES, 2, backend="ray")], tmp_path,
                       progress=False)


def test_a_worker_builds_its_environment_once(monkeypatch: pytest.MonkeyPatch) -> None:
    """Chunks of one evaluation, and of another with other episodes, reuse the worker's environment."""
    built: list[EvalSpec] = []
    monkeypatch.setattr(runner, "_setup_worker", lambda spec: built.append(spec))
    monkeypatch.setattr(runner, "_work", lambda index: {"index": index, "seed": runner._WORKER["spec"].seed_offset})
    monkeypatch.setattr(runner, "_WORKER", {})
    spec = EvalSpec("stage5", "mpc_goal", 8, 0, OVERRIDES, 2, backend="ray")
    assert runner._run_chunk(spec, [0, 1]) == [{"index": 0, "seed": 0}, {"index": 1, "seed": 0}]
    runner._run_chunk(spec, [2, 3])
    assert runner._run_chunk(EvalSpec(**{**spec.__dict__, "seed_offset": 9}), [0]) == [{"index": 0, "seed": 9}]
    assert len(built) == 1
    runner._run_chunk(EvalSpec(**{**spec.__dict__, "overrides": ("timing.episode_steps=30",)}), [0])
    assert len(built) == 2


def test_chunks_cover_the_episodes_in_order() -> None:
    assert runner._chunks(list(range(10)), 2) == [[0, 1], [2, 3], [4, 5], [6, 7], [8, 9]]
    assert runner._chunks([3, 5], 4) == [[3], [5]]
    assert sum(runner._chunks(list(range(1000)), 3), []) == list(range(1000))
    assert {len(c) for c in runner._chunks(list(range(1000)), 2, most=8)} == {8}  # a kill loses little
