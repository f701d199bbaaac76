"""``mjnav sweep``: a grid of training runs, each followed by its held-out evaluation, and one table.

    mjnav sweep task=stage2 grid=task.design=design1,design2 seeds=0,1,2 train.iterations=50 episodes=100

The grid: each ``grid=KEY=V1,V2,...`` is one axis (``KEY`` a ``task.*``/``train.*`` override key or
the short form ``<section>.<field>``; repeat ``grid=`` for more axes; a value may not contain a
comma), and ``seeds=`` is the last axis (``train.seed``). Every other ``task.*``/``train.*`` key is
given to every run. A cell is one combination: ``mjnav train`` in ``<out>/<cell>/`` (its run folder
inside, ``train.log`` beside it), then ``mjnav evaluate policy=<run folder> episodes=N`` into
``<out>/<cell>/eval/`` (the run's own task overrides, so the evaluation is of what was trained),
then ``<out>/<cell>/result.json``. Started again (resume after a kill, or widen the grid in the same
``out``), the sweep skips a cell whose ``result.json`` has the same arguments, evaluates without
training again a run that an earlier call trained (``trained.json``: killed while evaluating, or asked
for more episodes), resumes a training that was stopped (``mjnav train resume=`` from its newest
``model_<it>.pt``; ``resumed`` in its result), leaves out a cell that another live process is
running (a second sweep on the same ``out``: the cell folder's ``.lock``; or a ``resume=`` by hand:
the run folder's) and refuses, before running anything, a folder whose run was trained with other
arguments. A failed cell writes ``failed.json`` with its log, the rest go on, and the sweep exits
with 1 (so it does when a cell was left out). ``sweep.md`` and ``sweep.json`` are the table of the
grid of the last call. With either backend, SIGTERM to the sweep is passed on to the running
trainings or evaluations (which save and end), then the sweep exits with 143; started again, it
goes on.

Cells run one after another in child processes on this machine (``backend=local``), or as plain Ray
tasks (``backend=ray``, ``address=`` for a running cluster; ``out`` must then be on a file system
every node sees), each task reserving ``cpus_per_run`` CPUs.

The table (``<out>/sweep.md`` and ``<out>/sweep.json``): one row per grid point, with the mean over
seeds and its 95 % Student-t interval (:func:`mjnav.eval.intervals.mean_interval`) of success,
collision and timeout rates, time to goal and path length (:data:`HEADLINE`).
"""

from __future__ import annotations

import contextlib
import csv
import dataclasses
import itertools
import json
import math
import re
import signal
import subprocess
import sys
import threading
from collections.abc import Callable, Iterator, Sequence
from pathlib import Path
from typing import Any

import yaml

from mjnav.args import ArgsError, Grammar, Parsed, config_key
from mjnav.eval.intervals import mean_interval
from mjnav.jobs import LOCK_FILE, FolderInUse, holder, holding, joined_ray, usable_cores, write_atomic
from mjnav.schema import ConfigError

__all__ = ["HEADLINE", "Cell", "SweepOptions", "arguments", "cells", "check_recorded", "grammar", "run", "run_cell",
           "table"]

#: The summary columns the table shows: (key, label, percent?).
HEADLINE: tuple[tuple[str, str, bool], ...] = (
    ("success_rate", "Success (%)", True),
    ("collision_rate", "Collision (%)", True),
    ("timeout_rate", "Timeout (%)", True),
    ("time_s", "Time (s)", False),
    ("distance_m", "Distance (m)", False),
)
#: Where cells run: ``backend=NAME`` → ``runner(cells, options)`` yielding each cell's result as it ends.
BACKENDS: dict[str, Callable[[Sequence[Cell], SweepOptions], Iterator[dict[str, Any]]]] = {}


@dataclasses.dataclass(frozen=True)
class SweepOptions:
    """The ``sweep`` verb's own keys (``mjnav sweep --help``).

    Attributes:
        task: Stage or task YAML every run trains and is evaluated on.
        grid: One axis ``KEY=V1,V2,...`` (a ``task.*``/``train.*`` override key); repeat for more axes.
        seeds: Comma-separated ``train.seed`` values: the runs whose mean and interval a row shows.
        episodes: Held-out evaluation episodes per run.
        start: ``mjnav train start=`` of every run (``scratch``, ``auto``, ``shipped``, ``curriculum``).
        out: Sweep folder: one folder per cell, ``sweep.md`` and ``sweep.json`` (default ``sweeps/<task>``).
        workers: Evaluation worker processes per run (default: the CPU cores this process may use).
        backend: ``local`` (cells one after another here) or ``ray`` (cells as Ray tasks).
        address: Ray cluster to join with ``backend=ray`` (``auto``, ``HOST:6379``); default: a local Ray.
        cpus_per_run: CPUs a Ray task of one cell reserves (``backend=ray``); its training and evaluation use that many.
    """

    task: str = "stage2"
    grid: str | None = None
    seeds: str = "0,1,2"
    episodes: int = 100
    start: str = "scratch"
    out: str | None = None
    workers: int | None = None
    backend: str = "local"
    address: str | None = None
    cpus_per_run: int = 1


@dataclasses.dataclass(frozen=True)
class Cell:
    """One training run of the grid and its evaluation.

    Attributes:
        point: The grid point: ``(KEY, value)`` per axis, in the order the axes were given.
        seed: ``train.seed``.
        folder: ``<out>/<cell name>``.
        train: ``mjnav train`` arguments (without ``out=``).
        evaluate: ``mjnav evaluate`` arguments other than ``policy=`` and ``out=``.
    """

    point: tuple[tuple[str, str], ...]
    seed: int
    folder: Path
    train: tuple[str, ...]
    evaluate: tuple[str, ...]


def grammar() -> Grammar:
    """:class:`SweepOptions`, ``task.*`` and ``train.*`` overrides given to every run."""
    # deferred: mjnav.config ~0.3 s (numba, scipy, osqp), not needed by `mjnav --help`
    from mjnav.config import TASK_SECTIONS

    return Grammar(SweepOptions, ("task", "train"), {}, TASK_SECTIONS)


def _axes(argv: Sequence[str], fixed: Sequence[str]) -> list[tuple[str, list[str]]]:
    """``[(KEY, [values])]`` of every ``grid=KEY=V1,V2`` token (the grammar keeps only the last one),
    each key in its long form (``task.crowd.count``).

    Raises:
        ArgsError: A malformed axis, a key given twice (in either form) or also among the overrides
            ``fixed`` given to every run, or a value listed twice (one run would count twice).
    """
    g = grammar()
    axes = []
    for token in argv:
        key, _, axis = token.partition("=")
        if key.strip() != "grid":
            continue
        name, sep, values = axis.partition("=")
        listed = [v.strip() for v in values.split(",") if v.strip()]
        if not sep or not name.strip() or not listed:
            raise ArgsError(f"grid: expected KEY=V1,V2,... (grid=task.design=design1,design2), got {axis!r}")
        if len(set(listed)) < len(listed):
            raise ArgsError(f"grid: {name.strip()} lists a value twice ({values.strip()})")
        axes.append((config_key(name.strip(), g), listed))
    if len({k for k, _ in axes}) < len(axes):
        raise ArgsError("grid: an override key is given twice (crowd.count and task.crowd.count are one key)")
    both = {k for k, _ in axes} & {o.split("=", 1)[0] for o in fixed}
    if both:
        raise ArgsError(f"grid: {', '.join(sorted(both))} is also given to every run; give it once")
    return axes


def _name(point: Sequence[tuple[str, str]], seed: int) -> str:
    """A cell's folder name: ``design-design1_seed-0`` (each key's last part, unsafe characters as -)."""
    parts = [f"{key.rpartition('.')[2]}-{value}" for key, value in point] + [f"seed-{seed}"]
    return re.sub(r"[^A-Za-z0-9.+_-]", "-", "_".join(parts))


def cells(parsed: Parsed, argv: Sequence[str]) -> list[Cell]:
    """Every cell of the grid, each checked by ``mjnav train``'s grammar before anything runs.

    Raises:
        ConfigError: A malformed ``grid=`` or ``seeds=``, or a run the train grammar refuses
            (unknown key, bad value), named.
    """
    # deferred: mjnav.train.session imports torch and the environments, not needed by `mjnav sweep --help`
    from mjnav.train.session import parse_args, plan_run

    opts: SweepOptions = parsed.options
    try:
        seeds = [int(s) for s in opts.seeds.split(",") if s.strip()]
    except ValueError:
        raise ArgsError(f"seeds: expected comma-separated integers, got {opts.seeds!r}") from None
    if not seeds or opts.episodes < 1 or opts.cpus_per_run < 1:
        raise ArgsError("seeds: at least one; episodes and cpus_per_run: >= 1")
    if len(set(seeds)) < len(seeds):
        raise ArgsError(f"seeds: a seed is listed twice ({opts.seeds}): one run would count twice")
    if opts.workers is not None and opts.workers < 0:
        raise ArgsError(f"workers: must be >= 0, got {opts.workers}")
    fixed = [*(f"task.{o}" for o in parsed.task), *(f"train.{o}" for o in parsed.train)]
    axes, out = _axes(argv, fixed), Path(opts.out or Path("sweeps") / Path(opts.task).stem)
    workers = usable_cores() if opts.workers is None else opts.workers
    if opts.backend == "ray":  # a cell uses the CPUs its task reserves, no more (see _reserved)
        fixed += _reserved(parsed.train, opts.cpus_per_run)
        workers = opts.cpus_per_run if opts.workers is None else opts.workers
    found = []
    for values in itertools.product(*(v for _, v in axes)):
        point = tuple(zip((k for k, _ in axes), values))
        for seed in seeds:
            train = (f"task={opts.task}", f"start={opts.start}", *fixed, *(f"{k}={v}" for k, v in point),
                     f"seed={seed}")
            plan_run(parse_args(train))  # resolves the task and PPO configs: a bad key or value fails here
            evaluate = (f"task={opts.task}", f"episodes={opts.episodes}", f"workers={workers}")
            found.append(Cell(point, seed, out / _name(point, seed), train, evaluate))
    return found


def _reserved(train: Sequence[str], cpus: int) -> list[str]:
    """``train.workers``/``train.update_threads`` of a Ray cell that the command left to their defaults.

    Their defaults take every core of the node; with several cells on one node the PPO update's
    OpenMP threads then spin against the other cells' processes. Measured on the 2-core box under
    load (about 7 runnable processes): 28-45 s per stage-1 update of 2,048 transitions with the
    default against 0.9-1.0 s with ``train.update_threads=1``.
    """
    given = {o.split("=", 1)[0] for o in train}
    return [f"train.{key}={cpus}" for key in ("workers", "update_threads") if key not in given]


# ---------------------------------------------------------------------------- one cell

def _mjnav(args: Sequence[str], log: Path) -> int:
    """``python -m mjnav ARGS`` in a child process (this interpreter), output appended to ``log``.

    SIGTERM to this process (``kill``, a batch system's time limit) is passed on to the child, so a
    training saves its checkpoint and ends with the sweep instead of running on alone; so is Ctrl-C.
    """
    with open(log, "a", encoding="utf-8") as f:
        f.write(f"$ {sys.executable} -m mjnav {' '.join(args)}\n")
        f.flush()
        child = subprocess.Popen([sys.executable, "-m", "mjnav", *args], stdout=f, stderr=subprocess.STDOUT)
        try:
            with _passing_sigterm_to(child) as stopped:
                code = _wait(child)
        except BaseException:  # Ctrl-C, a cancelled Ray task: the child saves and ends first
            child.terminate()
            child.wait()
            raise
        if stopped:
            raise SystemExit(128 + signal.SIGTERM)
        return code


def _wait(child: subprocess.Popen) -> int:
    """``child.wait()`` in short slices: an interrupt that is no signal (``ray.cancel``'s
    KeyboardInterrupt in a Ray task) is raised between them, not after the child has ended."""
    while True:
        with contextlib.suppress(subprocess.TimeoutExpired):
            return child.wait(timeout=0.2)


@contextlib.contextmanager
def _passing_sigterm_to(child: subprocess.Popen) -> Iterator[list[bool]]:
    """While inside, SIGTERM is sent on to ``child`` and noted in the list yielded (empty until then)."""
    with _on_sigterm(child.terminate) as stopped:
        yield stopped


@contextlib.contextmanager
def _on_sigterm(action: Callable[[], None]) -> Iterator[list[bool]]:
    """While inside, the first SIGTERM calls ``action``; each is noted in the list yielded (empty
    until then). Outside the main thread (no signals there): nothing."""
    stopped: list[bool] = []
    if threading.current_thread() is not threading.main_thread():  # signals reach only the main thread
        yield stopped
        return

    def on_sigterm(signum: int, frame: Any) -> None:
        del signum, frame
        stopped.append(True)
        if len(stopped) == 1:
            action()

    previous = signal.signal(signal.SIGTERM, on_sigterm)
    try:
        yield stopped
    finally:
        signal.signal(signal.SIGTERM, previous)


def _run_folder(folder: Path) -> Path | None:
    """The newest run folder (one with ``policy.pt``) under a cell's folder."""
    runs = sorted((p for p in folder.iterdir() if (p / "policy.pt").is_file()), key=lambda p: p.stat().st_mtime)
    return runs[-1] if runs else None


def _interrupted(folder: Path) -> Path | None:
    """The newest run folder under a cell's folder that a stopped training left: a ``model_<it>.pt``
    checkpoint and no ``policy.pt`` (SIGTERM, Ctrl-C, a batch system's time limit, a kill after a
    periodic checkpoint)."""
    # deferred: mjnav.train imports torch, not needed by `mjnav sweep --help`
    from mjnav.train.runner import checkpoints

    if not folder.is_dir():
        return None
    runs = [p for p in folder.iterdir()
            if (p / "config.yaml").is_file() and not (p / "policy.pt").is_file() and checkpoints(p)]
    return max(runs, key=lambda p: p.stat().st_mtime) if runs else None


def _training(folder: Path) -> tuple[Path, str] | None:
    """A run folder under a cell's folder that a live process is training into, and its pid (one
    whose lock cannot be read counts as live: it cannot be told apart)."""
    if not folder.is_dir():
        return None
    for run_dir in folder.iterdir():
        try:
            pid = holder(run_dir) if run_dir.is_dir() else None
        except OSError as err:
            pid = f"unknown: {err}"
        if pid is not None:
            return run_dir, pid
    return None


def _launched_with(run_dir: Path) -> list[str]:
    """The ``mjnav train`` arguments a run folder was started with (its ``config.yaml``), ``out=`` left out.

    Raises:
        ConfigError: The file cannot be read or holds no ``run.argv``.
    """
    path = run_dir / "config.yaml"
    try:
        argv = yaml.safe_load(path.read_text(encoding="utf-8"))["run"]["argv"]
        if not isinstance(argv, list):
            raise TypeError(f"run.argv is {type(argv).__name__}")
    except (OSError, yaml.YAMLError, KeyError, TypeError) as err:
        raise ConfigError(f"{path}: not a readable run record ({type(err).__name__}: {err}); the stopped run "
                          "cannot be checked or resumed: move that run folder away") from None
    return [str(a) for a in argv if not str(a).startswith("out=")]


def _summary(path: Path) -> dict[str, Any]:
    """The first row of an evaluation's ``summary.csv``, numbers as floats."""
    with open(path, encoding="utf-8") as f:
        row = next(csv.DictReader(f))
    out: dict[str, Any] = {}
    for key, value in row.items():
        try:
            out[key] = float(value) if value != "" else math.nan
        except ValueError:
            out[key] = value
    return out


def arguments(cell: Cell) -> dict[str, list[str]]:
    """What a cell's results depend on: its ``train`` and ``evaluate`` arguments (``workers=`` left
    out: any worker count gives the same episodes)."""
    return {"train": list(cell.train), "evaluate": [a for a in cell.evaluate if not a.startswith("workers=")]}


def _head(cell: Cell) -> dict[str, Any]:
    """The keys every result of ``cell`` starts with: ``cell``, ``point``, ``seed`` and :func:`arguments`."""
    return {"cell": cell.folder.name, "point": dict(cell.point), "seed": cell.seed, **arguments(cell)}


def _recorded(cell: Cell) -> dict[str, Any]:
    """What an earlier call left in the cell: its ``result.json``, else its ``trained.json``, else the
    arguments of a stopped training to resume (``interrupted``: its run folder), else {}."""
    for name in ("result.json", "trained.json"):
        path = cell.folder / name
        if path.is_file():
            return {**json.loads(path.read_text(encoding="utf-8")), "file": name}
    if (live := _training(cell.folder)) is not None:
        return {"busy": f"{live[0]} is being trained by another process (pid {live[1]})"}
    stopped = _interrupted(cell.folder)
    if stopped is None:
        return {}
    return {"train": _launched_with(stopped), "file": f"{stopped.name}/config.yaml", "interrupted": stopped}


def check_recorded(todo: Sequence[Cell]) -> None:
    """Refuse to run when a cell's folder holds a run trained with other arguments.

    A cell is found again by its folder name (grid point and seed), which does not show the
    overrides given to every run; reusing its run would report it under the new arguments.

    Raises:
        ConfigError: Naming the first such cells and the arguments that differ.
    """
    stale = []
    for cell in todo:
        recorded = _recorded(cell)
        if "train" in recorded and recorded["train"] != list(cell.train):
            before, now = set(recorded["train"]), set(cell.train)
            stale.append(f"{cell.folder} (its {recorded['file']}: {', '.join(sorted(before - now)) or '-'}; "
                         f"now: {', '.join(sorted(now - before)) or '-'})")
    if stale:
        raise ConfigError(f"{len(stale)} cell(s) hold a run trained with other arguments, e.g. {stale[0]}; "
                          "give another out= or move those folders away")


def run_cell(cell: Cell) -> dict[str, Any]:
    """Train and evaluate one cell; returns its result.

    A cell whose ``result.json`` has its arguments (:func:`arguments`) is done and skipped. A run
    trained by an earlier call (``trained.json``, or a ``result.json`` of other evaluation
    arguments, such as more episodes) is evaluated, not trained again; the evaluation picks up the
    episodes already in ``eval/``. A training an earlier call left stopped (a checkpoint, no
    ``policy.pt``) goes on from its newest checkpoint. Call :func:`check_recorded` first.

    The result: ``cell`` (folder name), ``point`` (``{KEY: value}``), ``seed``, ``train`` and
    ``evaluate`` (:func:`arguments`), ``run`` (run folder), ``summary`` (the evaluation's summary
    row), ``resumed`` (the checkpoint a stopped training went on from, when it did), or ``failed``
    (which step) and ``log``, or ``busy`` (another process is training or evaluating the cell;
    nothing done); ``skipped`` (True) when it was read from an earlier ``result.json``,
    ``unchecked`` (True) when that file predates the recorded arguments. NaN is written to
    ``result.json`` as null.

    The cell's folder is locked (:func:`mjnav.jobs.holding`) while this runs, so a second sweep on
    the same ``out`` leaves the cell out (``busy``) instead of training or evaluating it again.
    """
    head = _head(cell)
    cell.folder.mkdir(parents=True, exist_ok=True)
    with contextlib.ExitStack() as held:
        try:
            held.enter_context(holding(cell.folder))
        except FolderInUse as err:  # only the taking of the lock
            return {**head, "busy": f"another process (pid {err.pid}) is running this cell"}
        except OSError as err:  # a .lock that is a folder, not ours to write, no locks on this file system
            return _failed(cell, head, f"locking the cell ({err})", cell.folder / LOCK_FILE)
        return _run_held(cell, head)


def _run_held(cell: Cell, head: dict[str, Any]) -> dict[str, Any]:
    """:func:`run_cell` once the cell is locked."""
    given, recorded = arguments(cell), _recorded(cell)
    if "busy" in recorded:  # a resume by hand is training its run: not counted here
        return {**head, "busy": recorded["busy"]}
    if recorded.get("file") == "result.json" and recorded.get("evaluate", given["evaluate"]) == given["evaluate"]:
        if "summary" in recorded:  # null back to NaN, as _summary reads an empty cell
            recorded["summary"] = {k: math.nan if v is None else v for k, v in recorded["summary"].items()}
        unchecked = {"unchecked": True} if "train" not in recorded else {}
        del recorded["file"]
        return {**recorded, "point": head["point"], "skipped": True, **unchecked}
    (cell.folder / "failed.json").unlink(missing_ok=True)
    run_dir = cell.folder / Path(recorded["run"]).name if "run" in recorded else None  # the sweep may have moved
    if run_dir is None or not (run_dir / "policy.pt").is_file():
        run_dir, resumed = _train(cell, recorded.get("interrupted"))
        if run_dir is None:
            return _failed(cell, head, "train", cell.folder / "train.log")
        head.update(resumed)
        went_on = bool(resumed)
        trained = {"train": given["train"], "run": str(run_dir), **resumed}
        write_atomic(cell.folder / "trained.json", json.dumps(trained, indent=1) + "\n")
    else:
        head.update({k: recorded[k] for k in ("resumed",) if k in recorded})
        went_on = False
    log = cell.folder / "eval.log"
    if _mjnav(["evaluate", f"policy={run_dir}", *cell.evaluate, f"out={cell.folder / 'eval'}"], log) != 0:
        return _failed(cell, head, "evaluate", log)
    result = {**head, "run": str(run_dir), "summary": _summary(cell.folder / "eval" / "summary.csv")}
    write_atomic(cell.folder / "result.json", json.dumps(_no_nan(result), indent=1) + "\n")
    return {**result, "went_on": True} if went_on else result


def _train(cell: Cell, stopped: Path | None) -> tuple[Path | None, dict[str, str]]:
    """Train the cell, or resume the training an earlier call left ``stopped``, from its newest checkpoint.

    Returns:
        The finished run folder (None when the training failed) and ``{"resumed": "model_<it>.pt"}``
        when it went on from a checkpoint ({} otherwise).
    """
    # deferred: mjnav.train imports torch, not needed by `mjnav sweep --help`
    from mjnav.train.runner import checkpoints

    log = cell.folder / "train.log"
    if stopped is None:
        code, resumed = _mjnav(["train", *cell.train, f"out={cell.folder}"], log), {}
    else:
        resumed = {"resumed": checkpoints(stopped)[-1].name}
        code = _mjnav(["train", f"resume={stopped}"], log)
    if code != 0:
        return None, resumed
    run_dir = stopped if stopped is not None else _run_folder(cell.folder)
    return (run_dir if run_dir is not None and (run_dir / "policy.pt").is_file() else None), resumed


def _failed(cell: Cell, head: dict[str, Any], step: str, log: Path) -> dict[str, Any]:
    result = {**head, "failed": step, "log": str(log)}
    write_atomic(cell.folder / "failed.json", json.dumps(result, indent=1) + "\n")
    return result


def _local(todo: Sequence[Cell], _: SweepOptions) -> Iterator[dict[str, Any]]:
    """Cells one after another on this machine."""
    for cell in todo:
        yield run_cell(cell)


def _ray(todo: Sequence[Cell], opts: SweepOptions) -> Iterator[dict[str, Any]]:
    """Cells as plain Ray tasks of ``cpus_per_run`` CPUs, yielded as they end."""
    try:
        import ray  # deferred: an optional extra (pip install mjnav[ray]), only for backend=ray
    except ImportError:
        raise ConfigError("backend=ray needs Ray: pip install 'mjnav[ray]'") from None
    try:
        with joined_ray(ray, opts.address, max(opts.cpus_per_run, usable_cores())):
            yield from _ray_cells(ray, todo, opts.cpus_per_run)
    except ConnectionError as err:  # nothing at address=, or address=auto and no cluster running
        raise ConfigError(f"backend=ray: {err}") from None


def _ray_cells(ray: Any, todo: Sequence[Cell], cpus: int) -> Iterator[dict[str, Any]]:
    """The cells as Ray tasks, yielded as they end; a crashed task is a failed cell (run_cell
    returns its own failures).

    SIGTERM cancels the tasks (``ray.cancel``: a running cell passes it on to its training, which
    saves a checkpoint; a waiting one never starts) and waits for them to end, then exits with 143;
    a second SIGTERM stops the waiting (exit 143 at once). Ray's own handler (installed by
    ``ray.init``) would exit at once and lose the trainings' progress since their last periodic
    checkpoint.
    """
    task = ray.remote(num_cpus=cpus, max_retries=0)(_cell_task)
    pending = {task.remote(cell): cell for cell in todo}
    with _on_sigterm(lambda: None) as stopped:
        while pending:
            if stopped:
                _cancel(ray, pending, stopped)
                raise SystemExit(128 + signal.SIGTERM)
            done, _ = ray.wait(list(pending), num_returns=1, timeout=0.5)
            if done:
                yield _ray_result(ray, done[0], pending.pop(done[0]))


def _cell_task(cell: Cell) -> dict[str, Any]:
    """:func:`run_cell` as a Ray task, interruptible by ``ray.cancel``.

    The cancel raises KeyboardInterrupt through Python's SIGINT machinery, which does nothing while
    SIGINT is ignored, as it is in a process started in the background by a shell script
    (``mjnav sweep ... &``) and in the Ray workers that inherit it. The task restores Python's
    default handler for its run.
    """
    if threading.current_thread() is not threading.main_thread():
        return run_cell(cell)
    previous = signal.signal(signal.SIGINT, signal.default_int_handler)
    try:
        return run_cell(cell)
    finally:
        signal.signal(signal.SIGINT, previous)


def _cancel(ray: Any, pending: dict[Any, Cell], stopped: list[bool]) -> None:
    """Cancel the Ray tasks ``pending`` and wait until each has ended (a running cell's training
    saved); return early, after a second SIGTERM (``stopped`` grown)."""
    print(f"sweep: SIGTERM: stopping {len(pending)} cell(s); a running cell's training saves a checkpoint "
          "(SIGTERM again: exit at once)", file=sys.stderr, flush=True)
    for ref in pending:
        ray.cancel(ref)
    refs = list(pending)
    while refs and len(stopped) == 1:
        _, refs = ray.wait(refs, num_returns=len(refs), timeout=0.5)


def _ray_result(ray: Any, done: Any, cell: Cell) -> dict[str, Any]:
    """The result of the ended Ray task ``done`` of ``cell``."""
    try:
        return ray.get(done)
    except ray.exceptions.RayError as err:  # a crashed worker process or a lost node
        return _failed(cell, _head(cell), f"Ray ({type(err).__name__})", cell.folder / "train.log")


BACKENDS.update(local=_local, ray=_ray)


# ---------------------------------------------------------------------------- the table

def table(results: Sequence[dict[str, Any]], keys: Sequence[str]) -> list[dict[str, Any]]:
    """One row per grid point: its values, the seeds that finished, failed and were left out
    (``busy``), and mean/lo/hi of :data:`HEADLINE`."""
    groups: dict[tuple[str, ...], list[dict[str, Any]]] = {}
    for result in results:
        groups.setdefault(tuple(result["point"][k] for k in keys), []).append(result)
    rows = []
    for values, members in groups.items():
        ok = [m for m in members if "summary" in m]
        row: dict[str, Any] = {**dict(zip(keys, values)), "seeds": sorted(m["seed"] for m in ok),
                               "failed": sorted(m["seed"] for m in members if "failed" in m),
                               "busy": sorted(m["seed"] for m in members if "busy" in m)}
        for key, _, percent in HEADLINE:  # rates lie in [0, 1], times and lengths in [0, inf)
            values = [m["summary"].get(key, math.nan) for m in ok]
            mean, lo, hi = mean_interval(values, bounds=(0.0, 1.0 if percent else math.inf))
            row.update({key: mean, f"{key}_lo": lo, f"{key}_hi": hi})
        rows.append(row)
    return rows


def _cell_text(row: dict[str, Any], key: str, percent: bool) -> str:
    scale = 100.0 if percent else 1.0
    mean, lo, hi = (row[k] * scale for k in (key, f"{key}_lo", f"{key}_hi"))
    if math.isnan(mean):
        return "–"
    digits = 1 if percent else 2
    return f"{mean:.{digits}f}" if math.isnan(lo) else f"{mean:.{digits}f} [{lo:.{digits}f}, {hi:.{digits}f}]"


def format_table(rows: Sequence[dict[str, Any]], keys: Sequence[str]) -> str:
    """A markdown table of :func:`table` rows: mean [95 % interval] over seeds."""
    header = [*keys, "seeds", *(label for _, label, _ in HEADLINE)]
    lines = ["| " + " | ".join(header) + " |", "|" + "|".join("---" for _ in header) + "|"]
    for row in rows:
        seeds = ",".join(map(str, row["seeds"])) + (f" ({len(row['failed'])} failed)" if row["failed"] else "")
        seeds = (seeds + (f" ({len(row['busy'])} left out: running elsewhere)" if row.get("busy") else "")).strip()
        cells_ = [*(str(row[k]) for k in keys), seeds, *(_cell_text(row, k, p) for k, _, p in HEADLINE)]
        lines.append("| " + " | ".join(cells_) + " |")
    return "\n".join(lines) + "\n"


def _no_nan(value: Any) -> Any:
    """``value`` with NaN floats as None (strict JSON)."""
    if isinstance(value, float) and math.isnan(value):
        return None
    if isinstance(value, dict):
        return {k: _no_nan(v) for k, v in value.items()}
    if isinstance(value, list | tuple):
        return [_no_nan(v) for v in value]
    return value


# ---------------------------------------------------------------------------- the verb

def run(parsed: Parsed, argv: list[str]) -> int:
    """Run the grid's missing cells, write and print the table; 0 when every cell finished, else 1."""
    opts: SweepOptions = parsed.options
    try:
        if opts.backend not in BACKENDS:
            raise ConfigError(f"backend: expected one of {', '.join(BACKENDS)}, got {opts.backend!r}")
        if opts.address is not None and opts.backend != "ray":
            raise ConfigError("address: a Ray cluster address; needs backend=ray")
        todo = cells(parsed, argv)
        check_recorded(todo)
        keys = [k for k, _ in todo[0].point]
        out = todo[0].folder.parent
        results = []
        with contextlib.closing(BACKENDS[opts.backend](todo, opts)) as stream:
            for result in stream:
                state = "done before (its result.json)" if result.pop("skipped", False) else "done"
                if result.pop("went_on", False):
                    state += f" (its stopped training went on from {result['resumed']})"
                if "busy" in result:
                    state = f"left out: {result['busy']}"
                if result.pop("unchecked", False):
                    state += ", recorded without its arguments: not checked"
                state = f"failed in {result['failed']} (see {result['log']})" if "failed" in result else state
                print(f"sweep: {result['cell']}: {state}", file=sys.stderr, flush=True)
                results.append(result)
    except ConfigError as err:
        print(f"error: {err}", file=sys.stderr)
        return 2
    order = {cell.folder.name: k for k, cell in enumerate(todo)}  # the grid's order, not the finishing order
    results.sort(key=lambda r: order[r["cell"]])
    rows = table(results, keys)
    text = format_table(rows, keys)
    write_atomic(out / "sweep.md", text)
    record = {"task": opts.task, "axes": keys, "episodes": opts.episodes, "rows": rows, "runs": results}
    write_atomic(out / "sweep.json", json.dumps(_no_nan(record), indent=1) + "\n")
    print(text, end="")
    print(f"wrote {out}/sweep.md and {out}/sweep.json")
    return 1 if any("failed" in r or "busy" in r for r in results) else 0
