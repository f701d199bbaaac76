"""Job facts (:mod:`mjnav.jobs`): worker counts follow the CPU affinity mask, and folders named by
time never collide between processes of a job array, and a folder's writer holds a lock others see."""

from __future__ import annotations

import os
import re
import socket
import subprocess
import sys
from pathlib import Path

import pytest

from mjnav import jobs


@pytest.fixture
def three_cores(monkeypatch: pytest.MonkeyPatch) -> None:
    """This process may run on 3 CPUs of a larger machine."""
    monkeypatch.setattr(os, "sched_getaffinity", lambda pid: {0, 2, 5}, raising=False)
    monkeypatch.setattr(os, "cpu_count", lambda: 64)


def test_usable_cores_is_the_affinity_mask(three_cores) -> None:
    assert jobs.usable_cores() == 3


def test_usable_cores_falls_back_to_cpu_count(monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.delattr(os, "sched_getaffinity", raising=False)
    monkeypatch.setattr(os, "cpu_count", lambda: 7)
    assert jobs.usable_cores() == 7


def test_evaluate_and_tables_default_workers_to_the_affinity(three_cores, monkeypatch, tmp_path) -> None:
    from mjnav.eval.runner import parse_args

    specs, _, _ = parse_args(["policy=mpc_goal", "task=stage1", "episodes=1"])
    assert specs[0].workers == 3
    from mjnav.envs.workers import _default_workers

    assert _default_workers(16) == 3 and _default_workers(2) == 2

    seen = {}
    from mjnav.verbs import tables

    monkeypatch.setattr(tables, "table_rows", lambda *a, **k: seen.setdefault("workers", a[4]) and [])
    monkeypatch.setattr(tables, "format_table", lambda *a, **k: "")
    from mjnav.args import parse

    tables.run(parse([f"out={tmp_path}"], tables.grammar()), [])
    assert seen["workers"] == 3


def test_stamps_are_unique_and_readable(monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.delenv(jobs.ARRAY_TASK_ENV, raising=False)
    stamps = {jobs.unique_stamp(now=0.0) for _ in range(200)}
    assert len(stamps) == 200  # the same second, one process: the random part differs
    assert all(re.fullmatch(rf"\d{{8}}-\d{{6}}-{os.getpid()}-[0-9a-f]{{4}}", s) for s in stamps)
    monkeypatch.setenv(jobs.ARRAY_TASK_ENV, "17")
    assert f"-a17-{os.getpid()}-" in jobs.unique_stamp()


def test_two_runs_started_in_one_second_get_two_folders(monkeypatch: pytest.MonkeyPatch, tmp_path) -> None:
    from mjnav.train import session

    monkeypatch.setattr(jobs.time, "time", lambda: 1.8e9)
    args = session.parse_args(["task=stage1", f"out={tmp_path}"])
    first, second = session.plan_run(args).run_dir, session.plan_run(args).run_dir
    assert first != second and first.parent == second.parent == tmp_path
    assert first.name.startswith("stage1-") and re.search(r"-\d{8}-\d{6}-", first.name)


def test_a_ray_address_where_nothing_answers_is_refused_at_once() -> None:
    """``ray.init`` retries a wrong address for minutes; one TCP connection tells at once."""
    with socket.socket() as listening:
        listening.bind(("127.0.0.1", 0))
        listening.listen()
        port = listening.getsockname()[1]
        jobs.check_reachable(f"127.0.0.1:{port}")  # something answers
    with pytest.raises(ConnectionError, match=f"no Ray cluster answers at 127.0.0.1:{port}"):
        jobs.check_reachable(f"127.0.0.1:{port}")  # closed now
    for left_to_ray in ("auto", "local", "ray://head:10001"):
        jobs.check_reachable(left_to_ray)


def test_joined_ray_refuses_an_address_where_nothing_answers_before_ray_init() -> None:
    class NoRay:
        def is_initialized(self) -> bool:
            return False

        def init(self, **kwargs: object) -> None:
            raise AssertionError("ray.init must not be reached")

    with socket.socket() as closed:
        closed.bind(("127.0.0.1", 0))
        port = closed.getsockname()[1]
    with pytest.raises(ConnectionError, match="no Ray cluster answers"):
        with jobs.joined_ray(NoRay(), f"127.0.0.1:{port}", 1):
            pass


@pytest.mark.skipif(sys.platform == "win32", reason="flock")
def test_a_folder_lock_is_seen_by_others_and_dropped_when_its_holder_is_killed(tmp_path: Path) -> None:
    """A live holder is named by its pid; a second holder is refused; SIGKILL frees the folder."""
    holder_code = (f"from mjnav.jobs import holding\nwith holding({str(tmp_path)!r}):\n"
                   " print('held', flush=True)\n input()")
    child = subprocess.Popen([sys.executable, "-c", holder_code], stdin=subprocess.PIPE, stdout=subprocess.PIPE,
                             text=True, cwd=Path(__file__).parents[1])
    try:
        assert child.stdout.readline() == "held\n"
        assert jobs.holder(tmp_path) == f"{child.pid} on {socket.gethostname()}"
        with pytest.raises(jobs.FolderInUse, match=f"pid {child.pid} on "), jobs.holding(tmp_path, patience_s=0.1):
            pass
    finally:
        child.kill()
        child.wait()
    assert jobs.holder(tmp_path) is None  # SIGKILL: the system dropped it
    with jobs.holding(tmp_path):
        assert jobs.holder(tmp_path) == f"{os.getpid()} on {socket.gethostname()}"


@pytest.mark.skipif(sys.platform == "win32", reason="flock")
def test_a_look_at_the_lock_does_not_refuse_a_writer_and_errors_inside_pass(tmp_path: Path, monkeypatch) -> None:
    """:func:`holder` takes the lock shared for an instant; a writer starting then waits it out.
    An error inside ``holding`` is not taken for a busy folder."""
    import fcntl

    flock, refused = fcntl.flock, [1]

    def busy_once(f, how):  # the first try meets a look in progress
        if refused and how & fcntl.LOCK_EX:
            refused.pop()
            raise BlockingIOError(11, "Resource temporarily unavailable")
        return flock(f, how)

    monkeypatch.setattr(fcntl, "flock", busy_once)
    with pytest.raises(BlockingIOError, match="from inside"), jobs.holding(tmp_path):
        assert refused == []
        raise BlockingIOError("from inside")  # e.g. a fork that hit a process limit
    assert jobs.holder(tmp_path) is None
