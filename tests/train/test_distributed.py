"""Data-parallel PPO under torchrun on CPU (gloo over loopback): ranks stay in lockstep, rank 0 writes.

The torchrun tests launch this file as the training script: run as ``__main__`` it trains through
``mjnav.train.session.run`` with every PPO update followed by a line in ``$MJNAV_TEST_DIGESTS/rank<R>.txt``
(iteration, a digest of the actor and critic state, a digest of the rollout's observations);
with ``$MJNAV_TEST_STOP_AT=K`` the last rank asks to stop (as SIGTERM would) just before update K.
"""

from __future__ import annotations

import hashlib
import os
import socket
import subprocess
import sys
from pathlib import Path
from typing import Any

import pytest
import torch
import yaml

from mjnav.schema import ConfigError
from mjnav.train import distributed
from mjnav.train.runner import checkpoints

ROOT = Path(__file__).resolve().parents[2]
TINY = [
    "task=stage1", "start=scratch", "train.num_envs=2", "train.workers=0", "train.steps_per_env=4",
    "train.epochs=1", "train.minibatches=1", "train.policy.actor_hidden_dims=[16, 16, 16]",
    "train.policy.critic_hidden_dims=[16, 16, 16]",
]


def _digest(tensors: list[torch.Tensor]) -> str:
    """SHA-256 of the tensors' bytes, in order."""
    h = hashlib.sha256()
    for t in tensors:
        h.update(t.detach().cpu().contiguous().numpy().tobytes())
    return h.hexdigest()[:16]


def _record_updates() -> None:
    """Make ``session.run`` append one digest line per PPO update to ``$MJNAV_TEST_DIGESTS/rank<R>.txt``."""
    from mjnav.train import session
    from mjnav.train.runner import request_stop

    build = session.build_runner
    out = Path(os.environ["MJNAV_TEST_DIGESTS"]) / f"rank{os.environ.get('RANK', '0')}.txt"
    last_rank = os.environ.get("RANK") == str(int(os.environ.get("WORLD_SIZE", "1")) - 1)
    stop_at = int(os.environ.get("MJNAV_TEST_STOP_AT", "-1"))

    def build_and_record(*args: Any, **kwargs: Any) -> Any:
        runner = build(*args, **kwargs)
        update, done = runner.alg.update, []

        def update_and_record(*a: Any, **k: Any) -> Any:
            iteration = runner.current_learning_iteration + len(done)  # the next iteration before the first update
            if last_rank and iteration == stop_at:
                request_stop()
            observed = _digest([runner.alg.storage.observations["policy"]])
            result = update(*a, **k)
            done.append(iteration)
            state = [v for m in (runner.alg.actor, runner.alg.critic) for _, v in sorted(m.state_dict().items())]
            with out.open("a") as f:
                f.write(f"{iteration} {_digest(state)} {observed}\n")
            return result

        runner.alg.update = update_and_record
        return runner

    session.build_runner = build_and_record


def _kill_a_worker_on_the_last_rank() -> None:
    """With ``$MJNAV_TEST_KILL_AT=K`` the last rank SIGKILLs its first env worker process at its step K."""
    from mjnav.train import session
    from mjnav.train.runner import make_vec_env
    from mjnav.verbs import train as train_verb
    from tests.train._dying import kill_a_worker_at

    kill_at = int(os.environ.get("MJNAV_TEST_KILL_AT", "-1"))
    if kill_at < 0 or os.environ.get("RANK") != str(int(os.environ.get("WORLD_SIZE", "1")) - 1):
        return

    def dying(*args: Any, **kwargs: Any) -> Any:
        return kill_a_worker_at(make_vec_env(*args, **kwargs), kill_at)

    train_verb.run_session = lambda argv: session.run(argv, make_env=dying)


def _torchrun(args: list[str], digests: Path, ranks: int = 2, stop_at: int = -1, nodes: int = 1,
              kill_at: int = -1, check: bool = True) -> subprocess.CompletedProcess[str]:
    """Train this file's ``__main__`` under torchrun with ``ranks`` CPU processes (the last rank asks
    to stop before update ``stop_at``, or kills a worker at step ``kill_at``): ``torchrun --standalone``,
    or with ``nodes`` > 1 that many torchrun agents of ``ranks`` processes each, meeting by c10d
    rendezvous on loopback as the nodes of a cluster do; returns the first agent's process (with
    ``check``, every agent must succeed)."""
    env = {**os.environ, "PYTHONPATH": str(ROOT), "MJNAV_TEST_DIGESTS": str(digests), "OMP_NUM_THREADS": "1",
           "MJNAV_TEST_STOP_AT": str(stop_at), "MJNAV_TEST_KILL_AT": str(kill_at)}
    launch = ["--standalone"]
    if nodes > 1:
        with socket.socket() as s:
            s.bind(("127.0.0.1", 0))
            port = s.getsockname()[1]
        launch = [f"--nnodes={nodes}", "--rdzv_backend=c10d", f"--rdzv_endpoint=127.0.0.1:{port}",
                  f"--rdzv_id=test-{port}"]
    command = [sys.executable, "-m", "torch.distributed.run", *launch, f"--nproc_per_node={ranks}", __file__, *args]
    logs = [(digests / f"node{k}.out", digests / f"node{k}.err") for k in range(nodes)]  # no pipe fills up
    agents = []
    try:
        for out, err in logs:
            with out.open("w") as o, err.open("w") as e:
                agents.append(subprocess.Popen(command, env=env, stdout=o, stderr=e, text=True, cwd=ROOT))
        for agent in agents:
            agent.wait(timeout=300)
    finally:
        for agent in agents:
            agent.kill()
    outputs = [(out.read_text(), err.read_text()) for out, err in logs]
    for agent, (out, err) in zip(agents, outputs):
        assert agent.returncode == 0 or not check, out[-3000:] + err[-3000:]
    return subprocess.CompletedProcess(command, agents[0].returncode, *outputs[0])


def _lines(digests: Path, rank: int) -> list[list[str]]:
    return [line.split() for line in (digests / f"rank{rank}.txt").read_text().splitlines()]


def _shape(run_dir: Path) -> set[str]:
    """The run folder's files, TensorBoard event files under one name."""
    return {"events" if p.name.startswith("events.out.tfevents") else str(p.relative_to(run_dir))
            for p in run_dir.rglob("*") if p.is_file()}


@pytest.fixture(scope="module")
def ddp_run(tmp_path_factory: pytest.TempPathFactory) -> tuple[Path, Path]:
    """Two ranks train stage 1 for 2 iterations; (run folder, digest folder)."""
    root = tmp_path_factory.mktemp("ddp")
    out, digests = root / "runs", root / "digests"
    digests.mkdir()
    done = _torchrun([*TINY, "train.iterations=2", f"out={out}"], digests)
    assert "stage1 for 32 env steps" in done.stdout  # 2 iterations x 2 ranks x 2 envs x 4 steps
    (run_dir,) = out.iterdir()
    return run_dir, digests


def test_ranks_hold_identical_parameters_after_every_update(ddp_run):
    """Both ranks log every update with the same parameter digest, from different rollouts."""
    _, digests = ddp_run
    rank0, rank1 = _lines(digests, 0), _lines(digests, 1)
    assert [r[0] for r in rank0] == ["0", "1"]
    assert [r[:2] for r in rank0] == [r[:2] for r in rank1]
    assert rank0[0][1] != rank0[1][1]  # the update moved the parameters
    assert all(a[2] != b[2] for a, b in zip(rank0, rank1))  # each rank collected its own data


def test_rank0_alone_writes_a_single_process_shaped_run_folder(ddp_run, tmp_path):
    """One run folder, with the files of a one-process run of the same arguments."""
    from mjnav.train import session

    run_dir, _ = ddp_run
    single = session.run([*TINY, "train.iterations=2", f"out={tmp_path}"])
    assert _shape(run_dir) == _shape(single)
    assert {"config.yaml", "model_1.pt", "policy.pt", "checkpoint_weights.pt", "events"} <= _shape(run_dir)
    ranks = [yaml.safe_load((folder / "config.yaml").read_text())["run"]["ranks"] for folder in (run_dir, single)]
    assert ranks == [[2], [1]]  # the launch's processes are recorded


def test_resume_loads_the_checkpoint_on_every_rank_and_a_stop_on_one_rank_stops_all(ddp_run, tmp_path):
    """A torchrun resume continues at iteration 2 with the ranks in lockstep; the last rank's stop
    request before update 3 ends both ranks after iteration 3, and rank 0 saves ``model_3.pt``."""
    run_dir, _ = ddp_run
    done = _torchrun([f"resume={run_dir}", "train.iterations=20"], tmp_path, stop_at=3)
    rank0, rank1 = _lines(tmp_path, 0), _lines(tmp_path, 1)
    assert [r[0] for r in rank0] == ["2", "3"] and [r[:2] for r in rank0] == [r[:2] for r in rank1]
    assert (run_dir / "model_3.pt").is_file() and "torch.distributed.run" in done.stdout.split("continue with:")[1]
    assert yaml.safe_load((run_dir / "config.yaml").read_text())["run"]["ranks"] == [2, 2]


def test_a_worker_dead_on_another_rank_is_saved_by_that_rank(tmp_path):
    """Rank 1's env worker dies in iteration 3: rank 1 saves the weights of iteration 2 (the ranks
    hold the same ones) into the shared run folder and the launch fails; rank 0 knew nothing of it."""
    out = tmp_path / "runs"
    done = _torchrun([*TINY, "train.workers=2", "train.iterations=6", "train.save_interval=50", f"out={out}"],
                     tmp_path, kill_at=3 * 4 + 2, check=False)
    assert done.returncode != 0
    (run_dir,) = out.iterdir()
    assert [p.name for p in checkpoints(run_dir)] == ["model_0.pt", "model_2.pt"]
    assert torch.load(run_dir / "model_2.pt", weights_only=False)["iter"] == 2
    assert f"saved {run_dir / 'model_2.pt'}" in done.stderr and "died (exit code -9)" in done.stderr


def test_two_nodes_meet_by_rendezvous_and_train_as_one(tmp_path):
    """The README's multi-node launch on loopback: two torchrun agents of one process each (c10d
    rendezvous) hold identical parameters after every update and write one run folder."""
    out, digests = tmp_path / "runs", tmp_path / "digests"
    digests.mkdir()
    _torchrun([*TINY, "train.iterations=2", f"out={out}"], digests, ranks=1, nodes=2)
    rank0, rank1 = _lines(digests, 0), _lines(digests, 1)
    assert [r[0] for r in rank0] == ["0", "1"] and [r[:2] for r in rank0] == [r[:2] for r in rank1]
    assert all(a[2] != b[2] for a, b in zip(rank0, rank1))
    (run_dir,) = out.iterdir()
    assert yaml.safe_load((run_dir / "config.yaml").read_text())["run"]["ranks"] == [2]


def test_rank_seeds_devices_and_backends():
    """Rank r seeds seed + r·num_envs; cuda becomes cuda:LOCAL_RANK; gloo on CPU, nccl on CUDA."""
    ranks = distributed.ranks_from_env({"WORLD_SIZE": "4", "RANK": "3", "LOCAL_RANK": "1", "LOCAL_WORLD_SIZE": "2"})
    assert ranks == distributed.Ranks(rank=3, local_rank=1, world_size=4, local_world_size=2)
    assert distributed.rank_seed(7, 16, ranks) == 7 + 3 * 16
    assert distributed.rank_seed(7, 16, distributed.Ranks()) == 7
    assert distributed.rank_device("cuda", ranks) == "cuda:1" and distributed.rank_device("cpu", ranks) == "cpu"
    assert distributed.rank_device("cuda:0", distributed.Ranks()) == "cuda:0"
    assert (distributed.backend("cuda:1"), distributed.backend("cpu")) == ("nccl", "gloo")
    with pytest.raises(ConfigError, match="mps"):
        distributed.rank_device("mps", ranks)


def test_one_process_is_not_distributed():
    """Without torchrun: one rank, rank 0 writes, values shared as they are."""
    assert distributed.ranks_from_env({}) == distributed.Ranks()
    assert distributed.current().main and not distributed.current().distributed
    assert distributed.share("x") == "x" and distributed.any_rank(True, "cpu")


if __name__ == "__main__":
    from mjnav.cli import main

    _record_updates()
    _kill_a_worker_on_the_last_rank()
    sys.exit(main(["train", *sys.argv[1:]]))


def test_a_stop_asked_after_the_ranks_agreed_waits_for_their_next_update(monkeypatch):
    """A signal between the all-reduce of the stop flags and the log must not stop one rank alone
    (the others would wait for it in their next all-reduce): it is shared at the next update."""
    from types import SimpleNamespace

    from mjnav.train.runner import TrainingInterrupted, _agree_on_stops, handle_interrupts, request_stop

    monkeypatch.setattr(distributed, "any_rank", lambda flag, device: flag)  # this rank's flag decides
    runner = SimpleNamespace(alg=SimpleNamespace(update=lambda: None), device="cpu",
                             logger=SimpleNamespace(log=lambda *a, it, **k: None))
    with handle_interrupts():
        _agree_on_stops(runner, distributed.Ranks(rank=1, local_rank=1, world_size=2, local_world_size=2))
        runner.alg.update()
        request_stop()  # after the all-reduce
        runner.logger.log(it=0)  # goes on, as the other rank does
        runner.alg.update()
        with pytest.raises(TrainingInterrupted):
            runner.logger.log(it=1)
