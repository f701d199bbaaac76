"""Facts about the job this process runs in: the CPUs it may use and folder names that never collide.

A process of a job array (SLURM, Ray, a shell loop) may start in the same second as its siblings,
on the same shared file system, with fewer CPUs than the machine has. Worker counts therefore come
from the CPU affinity mask (:func:`usable_cores`), folders named by time carry a suffix unique
to the process (:func:`unique_stamp`), a process that writes a folder holds a lock on it that
others can test (:func:`holding`, :func:`holder`), and files that others read are written whole
(:func:`write_atomic`).

This module is a bottom layer: it imports nothing from mjnav.
"""

from __future__ import annotations

import contextlib
import os
import secrets
import socket
import tempfile
import time
from collections.abc import Iterator
from pathlib import Path
from typing import Any

try:
    import fcntl
except ImportError:  # Windows: no flock, so folders are not locked (holding() holds nothing)
    fcntl = None  # type: ignore[assignment]

__all__ = ["ARRAY_TASK_ENV", "LOCK_FILE", "FolderInUse", "check_reachable", "holder", "holding", "joined_ray",
           "unique_stamp", "usable_cores", "write_atomic"]

#: Environment variable holding a job array's task id (SLURM); shown in the stamp when set.
ARRAY_TASK_ENV = "SLURM_ARRAY_TASK_ID"
#: The lock file a process writing a folder holds (:func:`holding`); it says ``<pid> on <host>``.
LOCK_FILE = ".lock"
#: The stamps this process has handed out (two calls in one second differ too).
_ISSUED: set[str] = set()


def usable_cores() -> int:
    """CPU cores this process may run on: its affinity mask where the OS has one, else ``os.cpu_count()``."""
    if hasattr(os, "sched_getaffinity"):
        try:
            return max(1, len(os.sched_getaffinity(0)))
        except OSError:
            pass
    return os.cpu_count() or 1


def unique_stamp(now: float | None = None) -> str:
    """``YYYYmmdd-HHMMSS[-a<array task>]-<pid>-<4 hex>``: a time stamp no other process gets.

    The local time (``now``, seconds since the epoch; default: now), the job array's task id when
    :data:`ARRAY_TASK_ENV` is set, this process's id and 16 random bits (never one this process
    already handed out), so two runs started in the same second (one job array on many nodes, or two
    processes on one) never share a folder.
    """
    parts = [time.strftime("%Y%m%d-%H%M%S", time.localtime(now))]
    array_task = os.environ.get(ARRAY_TASK_ENV, "").strip()
    if array_task.isalnum():
        parts.append(f"a{array_task}")
    parts.append(str(os.getpid()))
    while (stamp := "-".join([*parts, secrets.token_hex(2)])) in _ISSUED:  # this process's earlier stamps
        pass
    _ISSUED.add(stamp)
    return stamp


def check_reachable(address: str, timeout_s: float = 10.0) -> None:
    """Raise ``ConnectionError`` at once when nothing answers at a Ray ``HOST:PORT`` address.

    ``ray.init`` keeps retrying a wrong address for many minutes, printing warnings; this opens one
    TCP connection first. ``auto``, ``local`` and ``ray://`` addresses are left to Ray.

    Raises:
        ConnectionError: No connection within ``timeout_s`` seconds; the message names the address.
    """
    host, sep, port = address.rpartition(":")
    if not sep or not port.isdigit() or "://" in address:
        return
    try:
        socket.create_connection((host.strip("[]"), int(port)), timeout=timeout_s).close()
    except OSError as err:
        raise ConnectionError(f"address: no Ray cluster answers at {address} ({err}); start one with "
                              "`ray start --head` there, or leave out address= for a local Ray") from None


@contextlib.contextmanager
def joined_ray(ray: Any, address: str | None, num_cpus: int) -> Iterator[None]:
    """``ray`` (the imported module) initialised for the ``with`` block, shut down after it only if
    the block started it.

    A Ray this process already started is joined as it is (a benchmark times the work alone);
    otherwise ``address``'s cluster, or a local Ray of ``num_cpus`` CPUs without the dashboard.

    Raises:
        ConnectionError: No cluster at ``address`` (:func:`check_reachable`, or Ray's own error for
            ``auto`` with none running).
    """
    started = not ray.is_initialized()
    if started:
        if address is not None:
            check_reachable(address)
            ray.init(address=address, log_to_driver=False)
        else:
            ray.init(num_cpus=max(1, num_cpus), include_dashboard=False, log_to_driver=False)
    try:
        yield
    finally:
        if started:
            ray.shutdown()


class FolderInUse(RuntimeError):
    """Another live process holds a folder's lock (:func:`holding`).

    Attributes:
        folder: The folder.
        pid: The holder's ``<pid> on <host>`` as its lock file says ("?" when it says nothing yet).
    """

    def __init__(self, folder: str | os.PathLike[str], pid: str) -> None:
        """Name the folder and its holder (``pid`` as :func:`holder` gives it)."""
        super().__init__(f"{folder} is in use by another process (pid {pid})")
        self.folder, self.pid = Path(folder), pid


@contextlib.contextmanager
def holding(folder: str | os.PathLike[str], patience_s: float = 1.0) -> Iterator[None]:
    """Hold ``folder``'s lock (an ``flock`` on ``folder/.lock``, which says ``<pid> on <host>``) while inside.

    The operating system drops the lock when the process ends, however it ends (SIGKILL too), so a
    held lock means a live writer. A lock held only for a look (:func:`holder`, microseconds) is
    waited out for up to ``patience_s`` seconds. Without ``fcntl`` (Windows) nothing is locked.

    Raises:
        FolderInUse: Another process holds it (raised on entry only; errors inside pass as they are).
    """
    if fcntl is None:
        yield
        return
    with open(Path(folder) / LOCK_FILE, "a+", encoding="utf-8") as f:
        deadline = time.monotonic() + patience_s
        while True:
            try:
                fcntl.flock(f, fcntl.LOCK_EX | fcntl.LOCK_NB)
                break
            except BlockingIOError:
                if time.monotonic() >= deadline:
                    f.seek(0)
                    raise FolderInUse(folder, f.read().strip() or "?") from None
                time.sleep(0.02)
        try:
            f.truncate(0)
            f.write(f"{os.getpid()} on {socket.gethostname()}\n")  # a cluster's nodes share the folder
            f.flush()
            yield
        finally:
            fcntl.flock(f, fcntl.LOCK_UN)


def holder(folder: str | os.PathLike[str]) -> str | None:
    """``<pid> on <host>`` (as the lock file holds it; "?" before it is written) of the live process
    holding ``folder``'s lock, else None.

    Raises:
        OSError: The lock file cannot be opened for reading (another user's, mode 600).
    """
    path = Path(folder) / LOCK_FILE
    if fcntl is None or not path.is_file():
        return None
    with open(path, encoding="utf-8") as f:
        try:
            fcntl.flock(f, fcntl.LOCK_SH | fcntl.LOCK_NB)
        except BlockingIOError:
            return f.read().strip() or "?"
        fcntl.flock(f, fcntl.LOCK_UN)
    return None


def write_atomic(path: str | os.PathLike[str], text: str) -> None:
    """Write ``text`` to ``path`` whole: a temporary file beside it, fsync, one ``os.replace`` (then
    fsync the folder). A kill at any moment leaves the old file or the new one, never half of one,
    and a reader never sees a partial file."""
    path = Path(path)
    fd, tmp = tempfile.mkstemp(prefix=f".{path.name}.", suffix=".tmp", dir=path.parent)
    try:
        with os.fdopen(fd, "w", encoding="utf-8") as f:
            f.write(text)
            f.flush()
            os.fsync(f.fileno())
        os.replace(tmp, path)
    except BaseException:
        Path(tmp).unlink(missing_ok=True)
        raise
    try:
        folder = os.open(path.parent, os.O_RDONLY)
    except OSError:  # a platform without directory handles
        return
    try:
        os.fsync(folder)
    finally:
        os.close(folder)
