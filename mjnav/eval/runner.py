"""Held-out evaluation: the same scenario set for every policy, run in parallel.

Scenario ``i`` of a task has the episode seed ``HELD_OUT_BASE + seed_offset + i`` with
``HELD_OUT_BASE = 2**32``. Training environments draw their episode seeds with
``RandomState.randint(0, 2**31 − 1)`` (:meth:`mjnav.tasks.nav.CrowdNavTask.initialize_episode`),
so held-out seeds never occur in training, and every policy evaluated with the same
``seed_offset`` sees exactly the same layouts and crowd motion (paired comparisons; planners get
their own random stream, ``default_rng([seed, 1])``, so they cannot shift the scenario).

Each worker process builds its environment and loads the policy once, then runs episodes by
index. Results: one JSON line per episode (``<task>.jsonl``), ``summary.csv`` and
``summary.md`` (one row per task) in the output folder; each record also carries the episode's
social-navigation metrics and collision kind (:mod:`mjnav.eval.social`).

A JSONL only grows. Episodes are appended as they finish, so an evaluation that is interrupted
and started again with the same arguments runs only the missing episodes (never duplicates); at
the end the file is rewritten sorted by index, every record kept, atomically (temporary file,
fsync, ``os.replace``). A smaller ``episodes=`` summarises the first episodes and keeps the rest.
A file holding another evaluation's episodes (other commit, overrides, policy version, seeds) is
never deleted or rewritten: the evaluation stops with an :class:`EvalError` naming the difference.

Scaling out: ``shard=i/n`` runs only the episodes whose index is ``i`` modulo ``n`` (same seeds as
the whole evaluation) into ``<task>.shard-i-of-n.jsonl`` and ``summary.shard-i-of-n.csv``/``.md``,
so jobs of an array can share one folder; :mod:`mjnav.eval.shards` merges the files into the whole
evaluation's. ``backend=ray`` runs the episodes as Ray tasks (:data:`BACKENDS`) instead of local
processes, with the same records, episode for episode.
"""

from __future__ import annotations

import csv
import dataclasses
import hashlib
import itertools
import json
import math
import multiprocessing as mp
import multiprocessing.connection
import os
import subprocess
import sys
import threading
from collections.abc import Callable, Iterator, Sequence
from concurrent.futures import FIRST_COMPLETED, ProcessPoolExecutor, wait
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np

from mjnav.eval.metrics import (
    EpisodeMetrics,
    aggregate,
    episode_metrics,
    format_markdown,
    summary_row,
    write_csv,
)
from mjnav.eval.social import aggregate_social, social_metrics
from mjnav.args import Grammar, parse
from mjnav.jobs import joined_ray, usable_cores, write_atomic
from mjnav import shipped
from mjnav.schema import ConfigError, to_dict

__all__ = [
    "BACKENDS",
    "EvaluateOptions",
    "grammar",
    "HELD_OUT_BASE",
    "EpisodeTrace",
    "EvalError",
    "EvalSpec",
    "episode_setup",
    "evaluate",
    "evaluate_tasks",
    "git_commit",
    "held_out_seed",
    "jsonl_name",
    "parse_shard",
    "policy_sha256",
    "read_jsonl",
    "run_episode",
    "seed_paper_rule",
    "settle_from_contact",
    "summarise",
    "task_sha256",
    "write_summaries",
]

if TYPE_CHECKING:
    from mjnav.config import TaskConfig
    from mjnav.envs.gym_env import NavGymEnv
    from mjnav.eval.policies import Agent
    from mjnav.sim import NavSim

#: First held-out episode seed (training seeds are < 2**31).
HELD_OUT_BASE = 2**32
#: Offset of the scenarios the baselines are tuned on (``scripts/evaluate.py seed_offset=1000000000
#: planner.KEY=VALUE``): a billion scenarios past the evaluation sets (offset 0) and the
#: development sets of the results page (offsets 5,000,000 and 6,000,000), so no parameter is
#: ever chosen on a scenario a results table reports.
TUNING_SEED_OFFSET = 1_000_000_000
#: Seed of the untimed warm-up steps of each worker (neither a training nor a held-out seed).
WARM_UP_SEED = HELD_OUT_BASE - 1


class EvalError(RuntimeError):
    """An evaluation worker could not build its environment or load its policy (message says why)."""


def held_out_seed(index: int, seed_offset: int = 0) -> int:
    """Episode seed of held-out scenario ``index``."""
    return HELD_OUT_BASE + int(seed_offset) + int(index)


@dataclasses.dataclass(frozen=True)
class EvalSpec:
    """What to evaluate.

    Attributes:
        task: Stage name or YAML path.
        policy: ``PATH_OR_NAME`` (see :func:`mjnav.eval.policies.load_policy`).
        episodes: Number of held-out scenarios.
        seed_offset: Offset into the held-out seed range.
        overrides: Dotted task overrides given for this evaluation (``["crowd.count=25"]``).
        workers: Processes (0 or 1 = in this process).
        policy_overrides: The task overrides the policy was trained with
            (:func:`mjnav.policy.training_overrides`); ``overrides`` win over them.
        action: ``mean``, ``expected`` or ``sample`` (:func:`mjnav.eval.policies.load_policy`).
        planner: Parameter overrides of a baseline planner (``["w_clearance=0.8"]``, from
            ``planner.w_clearance=0.8`` on the command line).
        shard: ``(i, n)``: evaluate only the episodes whose index is ``i`` modulo ``n`` (``(0, 1)``: all).
        backend: Where the episodes run: a key of :data:`BACKENDS` (``local`` processes or ``ray`` tasks).
        address: The Ray cluster to join (``ray.init(address=...)``); None starts a local Ray with
            ``workers`` CPUs.
    """

    task: str
    policy: str
    episodes: int = 1000
    seed_offset: int = 0
    overrides: tuple[str, ...] = ()
    workers: int = 1
    policy_overrides: tuple[str, ...] = ()
    action: str = "mean"
    planner: tuple[str, ...] = ()
    shard: tuple[int, int] = (0, 1)
    backend: str = "local"
    address: str | None = None

    @property
    def task_overrides(self) -> list[str]:
        """The overrides the environment is built with: the policy's, then this evaluation's."""
        return [*self.policy_overrides, *self.overrides]

    @property
    def indices(self) -> list[int]:
        """The episode indices this evaluation (its shard) plays, ascending."""
        first, count = self.shard
        return list(range(first, self.episodes, count))

    @property
    def setup(self) -> tuple[Any, ...]:
        """What a worker's environment and agent are built from (not which episodes it plays)."""
        return self.task, tuple(self.task_overrides), self.policy, self.action, self.planner

    def in_shard(self, index: int) -> bool:
        """Whether episode ``index`` belongs to this evaluation's shard."""
        return index % self.shard[1] == self.shard[0]


def parse_shard(text: str) -> tuple[int, int]:
    """``"i/n"`` → ``(i, n)`` with 0 <= i < n.

    Raises:
        ValueError: Not of that form (the message shows it).
    """
    first, sep, count = text.partition("/")
    try:
        shard = (int(first), int(count)) if sep else None
    except ValueError:
        shard = None
    if shard is None or not 0 <= shard[0] < shard[1]:
        raise ValueError(f"shard: expected i/n with 0 <= i < n (shard=0/4), got {text!r}")
    return shard


def shard_suffix(shard: tuple[int, int]) -> str:
    """``.shard-i-of-n`` in the names of a shard's files; empty for the whole evaluation."""
    return "" if shard[1] == 1 else f".shard-{shard[0]}-of-{shard[1]}"


def jsonl_name(task: str, shard: tuple[int, int] = (0, 1)) -> str:
    """The JSONL file name of ``task`` (of one shard: ``stage5.shard-0-of-4.jsonl``)."""
    return f"{task}{shard_suffix(shard)}.jsonl"


@dataclasses.dataclass
class EpisodeTrace:
    """Per-step record of one episode (world frame, SI units).

    Attributes:
        positions: (T+1, 2) robot positions.
        velocities: (T+1, 2) robot velocities.
        pedestrians: (T+1, P, 3) pedestrian circles ``[x, y, r]``.
        plans: Per control step, what the action layer decided (``position`` planned from,
            ``polygon``, ``q_s``, ``q_l``, ``predicted``); empty for baselines.
        control_period: Time between two samples, seconds.
    """

    positions: np.ndarray
    velocities: np.ndarray
    pedestrians: np.ndarray
    plans: list[dict[str, np.ndarray]] = dataclasses.field(default_factory=list)
    control_period: float = math.nan


def git_commit(path: str | Path | None = None) -> str:
    """HEAD commit of the repository holding ``path`` (``unknown`` outside git)."""
    where = Path(path) if path else Path(__file__).resolve().parent
    try:
        out = subprocess.run(["git", "rev-parse", "HEAD"], cwd=where, capture_output=True, text=True,
                             timeout=10, check=False)
    except (OSError, subprocess.SubprocessError):
        return "unknown"
    return out.stdout.strip() if out.returncode == 0 else "unknown"


def _segment_gap(p: np.ndarray, segments: np.ndarray) -> float:
    """Distance from p to the nearest segment ``[x0, y0, x1, y1]``, metres."""
    if len(segments) == 0:
        return np.inf
    a, b = segments[:, :2], segments[:, 2:]
    ab = b - a
    t = np.clip(np.sum((p - a) * ab, axis=1) / np.maximum(np.sum(ab * ab, axis=1), 1e-12), 0.0, 1.0)
    closest = a + t[:, None] * ab
    return float(np.min(np.hypot(*(p - closest).T)))


def _clearances(p: np.ndarray, sim: NavSim, radius: float) -> tuple[float, float]:
    obst = _segment_gap(p, sim.segments) - radius
    circles = sim.pedestrian_circles()
    if len(circles) == 0:
        return obst, np.nan
    return obst, float(np.min(np.hypot(*(circles[:, :2] - p).T) - circles[:, 2])) - radius


class _Recorder:
    """Collects the per-step quantities of one episode."""

    def __init__(self, env: NavGymEnv, agent: Agent) -> None:
        """Snapshot the cumulative counters; call before the episode's reset (``env`` unwrapped)."""
        self.env, self.agent, self.task = env, agent, env.task
        self.radius = env.task.config.robot.radius
        self.positions, self.velocities, self.peds, self.obst, self.ped = [], [], [], [], []
        self.solve: list[float] = []
        self.plans: list[dict[str, np.ndarray]] = []
        self.counters = dict(self.task.core.counters)
        self.planner_stats = self._planner_stats()
        # Under the contact rule, where the paper's rule would have ended the episode (see paper_rule)
        self.watch_scan = env.task.config.collision == "contact"
        self.scan_cut: dict[str, Any] | None = None
        self.scan_kind: str | None = None  # what the shortest beam hit when the shrunk scan first reached 0

    def _planner_stats(self) -> dict[str, int]:
        return dict(getattr(getattr(self.agent.planner, "planner", None), "stats", {}) or {})

    def _snapshot(self) -> dict[str, Any]:
        """How far the episode has got: samples, solve times, core counters and planner statistics."""
        return {"samples": len(self.positions), "solve": len(self.solve),
                "counters": dict(self.task.core.counters), "planner_stats": self._planner_stats()}

    def sample(self) -> None:
        p, v, _ = self.task.sim.robot_state(self.env.physics)
        self.positions.append(p)
        self.velocities.append(v)
        self.peds.append(self.task.sim.pedestrian_circles())  # a new array each call
        obst, ped = _clearances(p, self.task.sim, self.radius)
        self.obst.append(obst)
        self.ped.append(ped)
        record = self.task.core.record
        if record is not None and self.agent.planner is None:
            self.solve.append(1e3 * record.solve_time_s)
            self.plans.append({"position": record.position.copy(), "polygon": record.polygon,
                               "q_s": record.q_s.copy(), "q_l": record.q_l.copy(), "predicted": record.predicted})
        if self.scan_kind is None and self.task.core.min_scan <= 0.0 and len(self.positions) > 1:
            self.scan_kind = self.task.scan_hit_kind(self.env.physics) or "unknown"
        if self.watch_scan and self.scan_cut is None and self.task.core.min_scan <= 0.0:
            self.scan_cut = self._snapshot()

    def finish(self, outcome: str) -> tuple[EpisodeMetrics, dict[str, int], EpisodeTrace]:
        """Metrics, planner statistics and trace of the whole episode."""
        now = self._snapshot()
        metrics, stats = self._metrics(outcome, now["samples"], now["solve"], now["counters"], now["planner_stats"])
        trace = EpisodeTrace(np.array(self.positions), np.array(self.velocities), _stack_peds(self.peds), self.plans,
                             self.task.config.timing.control_period)
        return metrics, stats, trace

    def collision_kind(self, outcome: str, rule: str) -> str | None:
        """What a collision under ``rule`` hit (``pedestrian``, ``obstacle``, ``wall``; None without one).

        The contact rule: the kind of the robot's deepest MuJoCo contact (:meth:`NavSim.robot_in_collision`);
        the paper's rule: what the shortest beam hit (:meth:`CrowdNavTask.scan_hit_kind`), ``unknown``
        when that beam, cast without noise, hits nothing (only the range noise made it short).
        """
        if outcome != "collision":
            return None
        return self.task.contact_kind if rule == "contact" else self.scan_kind

    def social(self, outcome: str, samples: int | None = None) -> dict[str, Any]:
        """Social metrics (:func:`mjnav.eval.social.social_metrics`) of the first ``samples`` instants."""
        layout = self.task.layout
        return social_metrics(np.array(self.positions[:samples]), np.array(self.velocities[:samples]),
                              _stack_peds(self.peds[:samples]), self.task.config.timing.control_period,
                              self.radius, layout.start, layout.goal, outcome,
                              self.task.config.reward.goal_tolerance).to_dict()

    def paper_rule(self, outcome: str) -> dict[str, Any] | None:
        """This contact-rule episode's outcome and metrics under the paper's rule (``collision=scan``).

        Both rules see the same scenario, observations and actions up to the first step whose shrunk
        scan is <= 0; the paper's rule ends the episode there as a collision. If no step got there,
        the outcome is the contact rule's, except a contact collision: the paper's rule would have
        gone on, so that episode is undetermined (None) and has to be run under that rule.
        """
        if not self.watch_scan or (self.scan_cut is None and outcome == "collision"):
            return None
        cut = self.scan_cut or self._snapshot()
        metrics, stats = self._metrics("collision" if self.scan_cut else outcome, cut["samples"], cut["solve"],
                                       cut["counters"], cut["planner_stats"])
        return {"outcome": metrics.outcome, "metrics": metrics.to_dict(), "planner_stats": stats,
                "collision_kind": self.collision_kind(metrics.outcome, "scan"),
                "social": self.social(metrics.outcome, cut["samples"])}

    def _metrics(self, outcome: str, samples: int, solves: int, counters: dict[str, int],
                 planner_stats: dict[str, int]) -> tuple[EpisodeMetrics, dict[str, int]]:
        """Metrics of the episode's first ``samples`` control instants (``solves`` MPC solve times)."""
        stats = {k: int(v - self.planner_stats.get(k, 0)) for k, v in planner_stats.items()}
        if self.task.config.shield.enabled:  # the action layer's crowd shield (mjnav.control.crowd)
            stats["shield_overrides"] = counters["shield_overrides"] - self.counters["shield_overrides"]
        fallbacks = counters["fallbacks"] - self.counters["fallbacks"] + stats.get("fallbacks", 0)
        solve = self.solve[:solves] if self.agent.planner is None else self.agent.plan_times_ms()[: samples - 1]
        metrics = episode_metrics(
            np.array(self.positions[:samples]), np.array(self.velocities[:samples]),
            self.task.config.timing.control_period, outcome,
            obstacle_clearances=self.obst[:samples], pedestrian_clearances=self.ped[:samples], solve_times_ms=solve,
            fallbacks=fallbacks, region_failures=counters["region_failures"] - self.counters["region_failures"],
            scans=samples,
        )
        return metrics, stats


def _stack_peds(peds: list[np.ndarray]) -> np.ndarray:
    count = max((len(p) for p in peds), default=0)
    out = np.full((len(peds), count, 3), np.nan)
    for k, p in enumerate(peds):
        out[k, : len(p)] = p
    return out


def episode_setup(args: dict[str, str], overrides: Sequence[str],
                  planner: Sequence[str] = ()) -> tuple[NavGymEnv, Agent, int]:
    """Environment, agent and episode seed of one scripted episode (``scripts/render.py``, ``plot.py``).

    Args:
        args: ``task`` (default stage6), ``policy`` (default mpc_goal), and ``episode_seed`` (a raw
            episode seed) or ``seed`` (held-out scenario index, default 0).
        overrides: Task config overrides.
        planner: ``planner.<field>=value`` parameter overrides (``["margin=0.5"]``).

    Raises:
        ValueError, FileNotFoundError: A bad task, override, policy or seed.
    """
    # deferred: mjnav.envs ~0.5 s after mjnav.config (MuJoCo, dm_control), not needed by `mjnav evaluate --help`
    from mjnav.envs.gym_env import NavGymEnv
    # deferred: ~0.2 s (planners: MPC, numba, scipy, osqp), not needed by `mjnav evaluate --help`/`tables --help`
    from mjnav.eval.policies import load_policy
    from mjnav.policy import training_overrides

    policy = args.get("policy", "mpc_goal")
    env = NavGymEnv(args.get("task", "stage6"), overrides=[*training_overrides(policy), *overrides] or None, seed=0)
    agent = load_policy(policy, planner=planner)
    seed = int(args["episode_seed"]) if "episode_seed" in args else held_out_seed(int(args.get("seed", 0)))
    return env, agent, seed


def run_episode(
    env: NavGymEnv, agent: Agent, seed: int
) -> tuple[EpisodeMetrics, dict[str, Any], EpisodeTrace]:
    """Run one episode of scenario ``seed`` to its end.

    Args:
        env: A :class:`mjnav.envs.gym_env.NavGymEnv`, possibly wrapped (``gymnasium.make`` gives a
            wrapped one; steps go through the wrappers).
        agent: A loaded :class:`mjnav.eval.policies.Agent`.
        seed: Episode seed.

    Returns:
        (metrics, extras with ``planner_stats``, ``start``, ``goal``, ``collision_kind``, ``social``
        (:mod:`mjnav.eval.social`) and, under the contact rule, ``paper_rule``
        (:meth:`_Recorder.paper_rule`), trace).
    """
    base = env.unwrapped  # wrappers (TimeLimit, RecordEpisodeStatistics, ...) do not forward task/physics
    agent.begin(base.task, seed)
    rec = _Recorder(base, agent)
    obs, _ = env.reset(options={"episode_seed": seed})
    rec.sample()
    info = {"outcome": "running"}
    done = False
    while not done:
        obs, _, terminated, truncated, info = env.step(agent.act(obs))
        rec.sample()
        done = terminated or truncated
    metrics, stats, trace = rec.finish(info["outcome"])
    layout = base.task.layout
    extras = {"planner_stats": stats, "start": layout.start.tolist(), "goal": layout.goal.tolist(),
              "collision_kind": rec.collision_kind(metrics.outcome, base.task.config.collision),
              "social": rec.social(metrics.outcome)}
    if rec.watch_scan:
        extras["paper_rule"] = rec.paper_rule(info["outcome"])
    return metrics, extras, trace


# ---------------------------------------------------------------------------- workers

_WORKER: dict[str, Any] = {}


def _init_worker(spec: EvalSpec) -> None:
    """Build this worker's environment and policy; a failure is kept and raised by each episode
    (:func:`_work`), so the parent reports it as one :class:`EvalError` with the cause."""
    _WORKER.clear()
    try:
        _setup_worker(spec)
    except Exception as err:  # noqa: BLE001 - reported to the parent by _work
        _WORKER["error"] = f"{type(err).__name__}: {err}"


def _setup_worker(spec: EvalSpec) -> None:
    # deferred: mjnav.envs ~0.5 s after mjnav.config (MuJoCo, dm_control), not needed by `mjnav evaluate --help`
    from mjnav.envs.gym_env import NavGymEnv
    # deferred: ~0.2 s (planners: MPC, numba, scipy, osqp), not needed by `mjnav evaluate --help`/`tables --help`
    from mjnav.eval.policies import load_policy

    try:
        import torch  # deferred: torch ~1-3 s (-X importtime), not needed to evaluate baselines

        torch.set_num_threads(1)
    except ImportError:
        pass
    env = _WORKER["env"] = NavGymEnv(spec.task, overrides=spec.task_overrides or None, seed=0)
    agent = _WORKER["agent"] = load_policy(spec.policy, mode=spec.action, planner=spec.planner)
    _WORKER["spec"] = spec
    _warm_up(env, agent)


def _warm_up(env: NavGymEnv, agent: Agent, steps: int = 3) -> None:
    """A few steps of a seed outside the held-out set, so JIT compilation is not timed."""
    agent.begin(env.task, WARM_UP_SEED)
    obs, _ = env.reset(options={"episode_seed": WARM_UP_SEED})
    for _ in range(steps):
        obs, _, terminated, truncated, _ = env.step(agent.act(obs))
        if terminated or truncated:
            break


def _work(index: int) -> dict[str, Any]:
    if "error" in _WORKER:
        raise EvalError(f"evaluation worker setup failed: {_WORKER['error']}")
    env, agent, spec = _WORKER["env"], _WORKER["agent"], _WORKER["spec"]
    seed = held_out_seed(index, spec.seed_offset)
    metrics, extras, _ = run_episode(env, agent, seed)
    return {"index": index, "seed": seed, "outcome": metrics.outcome, "metrics": metrics.to_dict(), **extras}


def _results(spec: EvalSpec, indices: Sequence[int]) -> Iterator[dict[str, Any]]:
    """The records of episodes ``indices`` as they finish (any order), run by ``spec.backend``."""
    if not indices:
        return
    if spec.backend not in BACKENDS:
        raise EvalError(f"backend: unknown {spec.backend!r} (known: {', '.join(BACKENDS)})")
    yield from BACKENDS[spec.backend](spec, indices)


def _check_policy(spec: EvalSpec) -> None:
    """Load the policy here, so a bad one fails in seconds, before any worker starts."""
    # deferred: ~0.2 s (planners: MPC, numba, scipy, osqp), not needed by `mjnav evaluate --help`/`tables --help`
    from mjnav.eval.policies import load_policy

    try:
        load_policy(spec.policy, mode=spec.action, planner=spec.planner)
    except (ValueError, ConfigError) as err:
        raise EvalError(str(err)) from err


def _local_results(spec: EvalSpec, indices: Sequence[int]) -> Iterator[dict[str, Any]]:
    """Episodes in this process (``workers`` <= 1) or in ``workers`` spawned processes, yielded
    chunk by chunk (at most 8 episodes, so the JSONL and the progress advance often) as they finish.

    A :class:`concurrent.futures.ProcessPoolExecutor` with one chunk per worker in flight, shut down
    and never killed. ``multiprocessing.Pool`` ended an evaluation with ``terminate()``, which hung
    for good in 2 of 40 repeats of a failed worker setup: it kills workers that may be sending a
    result, and its task-handler thread can then wait forever on a lock a dead worker held. On an
    error or an early close the pending chunks are dropped and the running ones (at most 8 episodes
    each) end first; Ctrl-C reaches the workers too and stops them at once.
    """
    if spec.workers <= 1:
        _init_worker(spec)
        yield from map(_work, indices)
        return
    _check_policy(spec)
    chunks = iter(_chunks(indices, spec.workers, most=8))
    pool = ProcessPoolExecutor(spec.workers, mp_context=mp.get_context("spawn"), initializer=_end_with_parent)
    try:
        running = {pool.submit(_run_chunk, spec, chunk) for chunk in itertools.islice(chunks, spec.workers)}
        while running:
            done, running = wait(running, return_when=FIRST_COMPLETED)
            running |= {pool.submit(_run_chunk, spec, chunk) for chunk in itertools.islice(chunks, len(done))}
            for future in done:
                yield from future.result()
    finally:
        pool.shutdown(wait=True, cancel_futures=True)


def _end_with_parent() -> None:
    """Exit this worker process when its parent ends, however it ends.

    A parent killed by SIGTERM or SIGKILL (``timeout``, a batch system's time limit) runs no cleanup;
    its workers would wait for work forever, holding their memory.
    """
    sentinel = mp.parent_process().sentinel

    def watch() -> None:
        mp.connection.wait([sentinel])
        os._exit(1)

    threading.Thread(target=watch, name="end-with-parent", daemon=True).start()


def _run_chunk(spec: EvalSpec, indices: Sequence[int]) -> list[dict[str, Any]]:
    """One task of a local worker process or of Ray: episodes ``indices`` in this process.

    A worker process runs many tasks, so the environment and policy are built by the
    first task the process runs and kept for the next ones (:data:`_WORKER`), also across
    evaluations that differ only in their episodes (:attr:`EvalSpec.setup`).
    """
    previous = _WORKER.get("spec")
    if previous is None or previous.setup != spec.setup or "error" in _WORKER:
        _init_worker(spec)
    _WORKER["spec"] = spec
    return [_work(index) for index in indices]


def _chunks(indices: Sequence[int], workers: int, most: int | None = None) -> list[list[int]]:
    """``indices`` cut into about four consecutive chunks per worker (a slow chunk is not the last one
    to start), each at least one episode and at most ``most`` (None: no limit)."""
    size = max(1, math.ceil(len(indices) / (4 * max(1, workers))))
    if most is not None:
        size = min(size, most)
    return [list(indices[k:k + size]) for k in range(0, len(indices), size)]


def _ray_results(spec: EvalSpec, indices: Sequence[int]) -> Iterator[dict[str, Any]]:
    """Episodes as Ray tasks of :func:`_run_chunk` (at most 8 episodes each, so a kill loses few),
    yielded chunk by chunk as they finish.

    Joins the running Ray if this process already called ``ray.init`` (a benchmark times the
    evaluation alone), else starts one (``spec.address``'s cluster, or a local Ray with ``workers``
    CPUs and no dashboard) and shuts it down at the end.
    """
    try:
        import ray  # deferred: an optional extra (pip install mjnav[ray]), only for backend=ray
    except ImportError:
        raise EvalError("backend=ray needs Ray: pip install 'mjnav[ray]'") from None
    _check_policy(spec)
    try:
        with joined_ray(ray, spec.address, spec.workers):
            task = ray.remote(num_cpus=1, max_retries=0)(_run_chunk)
            pending = [task.remote(spec, chunk) for chunk in _chunks(indices, spec.workers, most=8)]
            while pending:
                done, pending = ray.wait(pending, num_returns=1)
                try:
                    yield from ray.get(done[0])
                except ray.exceptions.RayError as err:  # a task's exception, a crashed worker, a lost node
                    cause = getattr(err, "cause", None)
                    raise EvalError(f"Ray task failed: {cause if cause is not None else err}") from None
    except ConnectionError as err:  # nothing at address=, or address=auto and no cluster running
        raise EvalError(f"backend=ray: {err}") from None


#: Where the episodes of an evaluation run: ``backend=NAME`` → ``results(spec, indices)``, the
#: records of those episodes as they finish. Every backend gives the same record per episode.
BACKENDS: dict[str, Callable[[EvalSpec, Sequence[int]], Iterator[dict[str, Any]]]] = {
    "local": _local_results,
    "ray": _ray_results,
}


def _progress(items: Iterator, total: int, label: str) -> Iterator:
    try:
        from tqdm import tqdm  # deferred: optional (not a dependency), only for a terminal; ~4 ms
    except ImportError:
        tqdm = None
    if tqdm is not None and sys.stderr.isatty():
        yield from tqdm(items, total=total, desc=label, unit="ep")
        return
    for k, item in enumerate(items, 1):
        if k == total or k % max(1, total // 20) == 0:
            print(f"{label}: {k}/{total} episodes", file=sys.stderr, flush=True)
        yield item


def evaluate(spec: EvalSpec, out_dir: str | Path | None = None, progress: bool = True) -> dict[str, Any]:
    """Evaluate one policy on one task's held-out scenarios.

    Args:
        spec: Task, policy, episode count, seed offset, workers.
        out_dir: Folder for ``<task>.jsonl`` (one line per episode, by index); None writes nothing.
        progress: Show a progress bar (tqdm) or a plain counter on stderr.

    Returns:
        The summary row (:func:`mjnav.eval.metrics.summary_row`, the social metrics'
        :func:`mjnav.eval.social.aggregate_social`, ``task_version``, ``commit``, ``seed_offset``) of
        episodes 0 .. ``spec.episodes`` − 1.

    Raises:
        EvalError: ``<task>.jsonl`` in ``out_dir`` holds another evaluation's episodes (nothing is
            changed; :func:`_resumable`).
    """
    common = _common(spec)
    task, policy_name = common["task"], common["policy"]
    path = None if out_dir is None else Path(out_dir) / jsonl_name(task, spec.shard)
    done = _resumable(path, common, spec) if path is not None else {}
    todo = [i for i in spec.indices if i not in done]
    if done and progress:
        print(f"{path}: {len(done)} of {len(spec.indices)} episodes already there, running {len(todo)}",
              file=sys.stderr, flush=True)
    stream = _results(spec, todo)
    if progress:
        stream = _progress(stream, len(todo), f"{task}/{policy_name}{shard_suffix(spec.shard)}")
    rows = [*done.values(), *(stream if path is None else _append(path, common, stream))]
    rows.sort(key=lambda r: r["index"])
    if path is not None:
        _rewrite_sorted(path)
    return summarise(rows, common, spec.seed_offset)


def summarise(rows: Sequence[dict[str, Any]], common: dict[str, Any], seed_offset: int) -> dict[str, Any]:
    """The summary row of an evaluation's episode records (sorted by index) and shared fields ``common``.

    Returns:
        :func:`mjnav.eval.metrics.summary_row`, the social metrics' :func:`mjnav.eval.social.aggregate_social`,
        ``task_version``, ``commit``, ``seed_offset`` and ``planner_privileged``.
    """
    summary = aggregate([EpisodeMetrics.from_dict(r["metrics"]) for r in rows])
    policy_name = common["policy"]
    if (common.get("planner_params") or {}).get("tracks") is True:  # planner.tracks=true: "teb + tracks"
        policy_name = f"{policy_name} + tracks"
    return {**summary_row(summary, common["task"], policy_name), **aggregate_social(rows),
            "task_version": common["task_version"], "commit": common["commit"], "seed_offset": seed_offset,
            "planner_privileged": ",".join(common["planner_privileged"] or ())}


def _common(spec: EvalSpec) -> dict[str, Any]:
    """The fields every JSONL record of evaluation ``spec`` shares (``_COMMON_KEYS``), then the
    evaluation's episode count (``planned_episodes``: a merge of shards checks they are all there)
    and the shard (``shard``, last)."""
    # deferred: mjnav.envs ~0.5 s after mjnav.config (MuJoCo, dm_control), not needed by `mjnav evaluate --help`
    from mjnav.envs.factory import resolve_config
    # deferred: ~0.2 s (planners: MPC, numba, scipy, osqp), not needed by `mjnav evaluate --help`/`tables --help`
    from mjnav.eval.policies import planner_record
    from mjnav.policy import policy_name

    config = resolve_config(spec.task, spec.task_overrides or None)
    return {"task": config.name, "task_version": config.version, "task_sha256": task_sha256(config),
            "policy": policy_name(spec.policy),
            "policy_source": spec.policy, "policy_sha256": policy_sha256(spec.policy, spec.planner),
            "commit": git_commit(), "overrides": spec.task_overrides,
            "policy_overrides": list(spec.policy_overrides), "collision": config.collision,
            "design": config.design, "action_mode": spec.action, "planner_overrides": list(spec.planner),
            **planner_record(spec.policy, spec.planner), "planned_episodes": spec.episodes,
            **_shard_field(spec.shard)}


def _shard_field(shard: tuple[int, int]) -> dict[str, str]:
    """``{"shard": "i/n"}`` in the records of a shard (last, so a merge drops it); nothing for a whole evaluation."""
    return {} if shard[1] == 1 else {"shard": f"{shard[0]}/{shard[1]}"}


def seed_paper_rule(contact_jsonl: str | Path, spec: EvalSpec, out_dir: str | Path) -> int:
    """Start the paper's-rule evaluation ``spec`` from a contact-rule evaluation of the same policy.

    A contact-rule episode determines its outcome under the paper's rule in all but one case
    (:meth:`_Recorder.paper_rule`), so those episodes are written to ``<out_dir>/<task>.jsonl``
    (marked ``"derived_from": "contact"``) as an interrupted run of ``spec``; :func:`evaluate` then
    runs only the rest. Nothing is written unless the contact records are of the same task,
    policy, action mode, seeds, code commit and overrides (but the rule) as ``spec``.

    Returns:
        The number of episodes written.
    """
    common = _common(spec)
    if common["collision"] != "scan":
        raise ValueError(f"seed_paper_rule: spec must use collision=scan, got {common['collision']!r}")
    rest = [o for o in common["overrides"] if not o.startswith("collision=")]
    # deferred: mjnav.envs ~0.5 s after mjnav.config (MuJoCo, dm_control), not needed by `mjnav evaluate --help`
    from mjnav.envs.factory import resolve_config

    contact = {**common, "task_sha256": task_sha256(resolve_config(spec.task, [*rest, "collision=contact"]))}
    derived = []
    for record in read_jsonl(contact_jsonl):
        index, paper = record.get("index"), record.get("paper_rule")
        same = (record.get("collision") == "contact" and isinstance(index, int)
                and [o for o in record.get("overrides", []) if not o.startswith("collision=")] == rest
                and all(record.get(k) == contact[k] for k in _SPEC_KEYS if k != "overrides"))
        if not same:
            return 0
        if (paper is not None and index < spec.episodes and spec.in_shard(index)
                and record.get("seed") == held_out_seed(index, spec.seed_offset)):
            derived.append({**common, "index": index, "seed": record["seed"], **paper, "start": record.get("start"),
                            "goal": record.get("goal"), "derived_from": "contact"})
    if derived:
        with _open_for_append(Path(out_dir) / jsonl_name(common["task"], spec.shard)) as f:
            f.writelines(json.dumps(r) + "\n" for r in derived)
    return len(derived)


def settle_from_contact(spec: EvalSpec, contact: str | Path, out_dir: str | Path, report: bool = True) -> int:
    """Write the episodes of paper's-rule ``spec`` that a contact run settles (:func:`seed_paper_rule`).

    ``contact`` is the contact run's JSONL, or its folder (then ``<contact>/<task>.jsonl``). The
    output file must hold episodes of ``spec`` only (as :func:`evaluate` resumes them); an index
    settled twice keeps its first record when :func:`evaluate` rewrites the file, so settling
    twice, or into an interrupted run, never duplicates or mixes. Contact records of another
    commit, policy, seed range or overrides settle nothing (0, reported).

    Raises:
        EvalError: ``spec`` is not evaluated under the paper's rule (``collision=scan``), or the output
            file holds another evaluation's episodes (left unchanged).
    """
    common = _common(spec)
    if common["collision"] != "scan":
        raise EvalError(f"from_contact: the evaluation must use task.collision=scan, got {common['collision']!r}")
    path = Path(out_dir) / jsonl_name(common["task"], spec.shard)
    done = _resumable(path, common, spec)
    contact = Path(contact)
    if contact.is_dir():
        contact = contact / f"{common['task']}.jsonl"
    wanted = len(spec.indices)
    settled = seed_paper_rule(contact, spec, out_dir) if len(done) < wanted else 0
    if report:
        why = "" if settled or len(done) == wanted else (
            " (missing, or not a contact run of this policy, seeds, overrides and code commit)")
        print(f"{path}: {settled} of {wanted} episodes settled by {contact}{why}", file=sys.stderr, flush=True)
    return settled


def read_jsonl(path: str | Path) -> list[dict[str, Any]]:
    """The records of a JSONL file ([] if it does not exist; a line cut by a kill is skipped)."""
    path = Path(path)
    if not path.is_file():
        return []
    rows = []
    for line in path.read_text(encoding="utf-8").splitlines():
        try:
            rows.append(json.loads(line))
        except json.JSONDecodeError:
            continue
    return rows


#: Fields every record of one evaluation shares (the rest is the episode's, from :func:`_work`).
_COMMON_KEYS = ("task", "task_version", "task_sha256", "policy", "policy_source", "policy_sha256", "commit",
                "overrides", "policy_overrides", "collision", "design", "action_mode", "planner_overrides",
                "planner_source", "planner_sha256", "planner_params", "planner_privileged")
#: Fields that must match for an interrupted evaluation to be continued rather than started over.
_SPEC_KEYS = ("task", "task_version", "task_sha256", "policy_source", "policy_sha256", "commit", "overrides",
              "action_mode", "planner_overrides", "planner_source", "planner_sha256", "planner_params")


def _append(path: Path, common: dict[str, Any], stream: Iterator[dict[str, Any]]) -> Iterator[dict[str, Any]]:
    """Pass the episodes on, appending each to ``path`` as it finishes (a restart resumes from them).

    The file is opened at the first episode, so a policy that fails to load writes nothing.
    """
    f = None
    try:
        for row in stream:
            if f is None:
                f = _open_for_append(path)
            f.write(json.dumps({**common, **row}) + "\n")
            f.flush()
            yield row
    finally:
        if f is not None:
            f.close()


def _open_for_append(path: Path):  # noqa: ANN202 - a text file object
    """``path`` opened for appending lines (folder made); a last line cut by a kill is ended first,
    so it stays one unreadable line (skipped by :func:`read_jsonl`) instead of swallowing the next."""
    path.parent.mkdir(parents=True, exist_ok=True)
    f = open(path, "a+b")  # noqa: SIM115 - the caller closes it
    if f.tell() > 0:
        f.seek(-1, os.SEEK_END)
        if f.read(1) != b"\n":
            f.write(b"\n")
    f.close()
    return open(path, "a", encoding="utf-8")  # noqa: SIM115


def _rewrite_sorted(path: Path) -> None:
    """Rewrite ``path`` with its records sorted by index, one per index (the first), atomically.

    Every record of the file is kept (indices past this run's episode count too); lines cut by a kill
    are dropped. The new content goes to a temporary file in the same folder, is flushed to disk
    (fsync), then replaces ``path`` in one ``os.replace``: a kill at any moment leaves the old file
    or the new one, never a truncated one.
    """
    if not path.is_file():
        return
    unique: dict[int, dict[str, Any]] = {}
    for record in read_jsonl(path):
        unique.setdefault(record["index"], record)
    text = "".join(json.dumps(unique[i]) + "\n" for i in sorted(unique))
    if path.read_text(encoding="utf-8") == text:
        return
    write_atomic(path, text)


def task_sha256(config: TaskConfig) -> str:
    """First 16 hex digits of the SHA-256 of a resolved task config (its overrides applied).

    The task's name is its file's stem: two YAML files ``a/stage5.yaml`` and ``b/stage5.yaml`` are
    both ``stage5``, and only this tells their records apart.
    """
    text = json.dumps(to_dict(config), sort_keys=True)
    return hashlib.sha256(text.encode()).hexdigest()[:16]


def policy_sha256(spec: str, planner: Sequence[str] = ()) -> str | None:
    """First 16 hex digits of the SHA-256 of what a policy spec acts with.

    A policy file or shipped policy name: the file's bytes. A baseline with parameters (``teb``,
    ``dwa``): its resolved parameters (defaults plus ``planner`` overrides), so records made before
    a default changed no longer match. None for other baselines and run names.
    """
    # deferred: ~0.2 s (planners: MPC, numba, scipy, osqp), not needed by `mjnav evaluate --help`/`tables --help`
    from mjnav.planners import PLANNERS, planner_config

    if spec in PLANNERS and PLANNERS.get(spec).config_class is not None:
        text = json.dumps(dataclasses.asdict(planner_config(spec, planner)), sort_keys=True)
        return hashlib.sha256(text.encode()).hexdigest()[:16]
    path = Path(spec) if Path(spec).is_file() else shipped.resolve(spec)
    if path is None or not path.is_file():
        return None
    return hashlib.sha256(path.read_bytes()).hexdigest()[:16]


def _resumable(path: Path, common: dict[str, Any], spec: EvalSpec) -> dict[int, dict[str, Any]]:
    """Episodes 0 .. ``spec.episodes`` − 1 of an earlier run of the same evaluation in ``path``, by index.

    A record counts when its task, policy (path and file hash), code commit, overrides, action mode
    and seed match this evaluation (uncommitted code changes are not detected: use another ``out``
    after changing code); duplicates keep the first, a line cut by a kill is skipped. Records past
    the episode count stay in the file (a smaller ``episodes=`` summarises the first ones). The file
    is only read: it only ever grows (:func:`_append`) and is rewritten sorted, atomically, with
    every record kept (:func:`_rewrite_sorted`).

    Raises:
        EvalError: A record belongs to another evaluation; the message names the fields that differ.
            Nothing is deleted or changed.
    """
    kept: dict[int, dict[str, Any]] = {}
    for record in read_jsonl(path):  # a line cut by a kill is skipped
        index = record.get("index")
        differ = _differences(record, common, spec)
        if differ:
            raise EvalError(f"{path} holds episodes of another evaluation ({'; '.join(differ)}); it is left "
                            f"as it is: write this evaluation elsewhere with out=DIR, or move that file away")
        if index < spec.episodes:  # in this shard (_differences)
            kept.setdefault(index, record)
    return kept


def _differences(record: dict[str, Any], common: dict[str, Any], spec: EvalSpec) -> list[str]:
    """``field: file's value vs this evaluation's`` for each field that makes ``record`` another evaluation's."""
    out = [f"{k}: {record.get(k)!r} there, {common.get(k)!r} here" for k in (*_SPEC_KEYS, "shard")
           if record.get(k) != common.get(k)]
    index = record.get("index")
    if not isinstance(index, int) or index < 0:
        out.append(f"index: {index!r} is not an episode index")
    elif not spec.in_shard(index):
        out.append(f"index: episode {index} is not in shard {spec.shard[0]}/{spec.shard[1]}")
    elif record.get("seed") != held_out_seed(index, spec.seed_offset):
        seed = record.get("seed")
        there = seed - HELD_OUT_BASE - index if isinstance(seed, int) else f"seed {seed!r}"
        out.append(f"seed_offset: {there} there, {spec.seed_offset} here")
    return out


def evaluate_tasks(
    specs: Sequence[EvalSpec], out_dir: str | Path, progress: bool = True, from_contact: str | Path | None = None
) -> list[dict[str, Any]]:
    """Evaluate several tasks; writes per-task JSONL plus ``summary.csv`` and ``summary.md``.

    Args:
        from_contact: Folder of a contact-rule evaluation of the same policy, seeds and code commit:
            each paper's-rule ``spec`` first takes the episodes it settles (:func:`settle_from_contact`).
    """
    rows = []
    for spec in specs:
        if from_contact is not None:
            settle_from_contact(spec, from_contact, out_dir, progress)
        rows.append(evaluate(spec, out_dir, progress))
    write_summaries(rows, out_dir, shard_suffix(specs[0].shard) if specs else "")
    return rows


def write_summaries(rows: Sequence[dict[str, Any]], out_dir: str | Path, suffix: str = "") -> None:
    """``summary<suffix>.csv`` and ``summary<suffix>.md`` (one row per task) in ``out_dir``.

    ``rows`` take the place of the rows of their tasks; the rows of other tasks already there are
    kept as they are (an evaluation of stage 5 into the folder of one of stage 3 keeps stage 3's row).
    """
    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    path = out / f"summary{suffix}.csv"
    rows = _with_earlier_rows(rows, path)
    write_csv(rows, path)
    (out / f"summary{suffix}.md").write_text(format_markdown(rows), encoding="utf-8")


def _with_earlier_rows(rows: Sequence[dict[str, Any]], path: Path) -> list[dict[str, Any]]:
    """The rows of summary file ``path`` (as text) with those of the tasks of ``rows`` replaced in
    place, then the rows of new tasks."""
    if not path.is_file():
        return list(rows)
    with open(path, newline="", encoding="utf-8") as f:
        earlier = list(csv.DictReader(f))
    new = {row["task"]: row for row in rows}
    return [*(new.pop(row.get("task"), row) for row in earlier), *new.values()]


# ---------------------------------------------------------------------------- command line

@dataclasses.dataclass(frozen=True)
class EvaluateOptions:
    """The ``evaluate`` verb's own keys (``mjnav evaluate --help``).

    Attributes:
        policy: A run folder, ``policy.pt``, ``model_<it>.pt``, a shipped policy or a planner (mpc_goal,
            mpc_gap, mpc_crowd, mpc_tracked, teb, dwa, random_jerk, ``package.module:Class``,
            ``file.py:Class``); required.
        task: Bundled stage name or task YAML path.
        tasks: Comma-separated stages, one evaluation each (instead of ``task``).
        episodes: Held-out scenarios per task.
        workers: Worker processes (0: this process; default: one per CPU core this process may use).
        out: Output folder (default ``evals/<policy>``; with ``merge=``, the first source's folder).
        seed_offset: Scenario i uses the episode seed 2**32 + seed_offset + i (never a training seed).
        action: ``mean`` (the policy's mean action), ``expected`` or ``sample`` (its Gaussian; checkpoints only).
        from_contact: Folder of a contact-rule evaluation of the same policy, seeds and commit whose
            settled episodes a ``task.collision=scan`` evaluation takes.
        shard: ``i/n``: only the episodes whose index is i modulo n (same seeds) into
            ``<task>.shard-i-of-n.jsonl``, so the jobs of an array can share one ``out`` (``merge=`` joins them).
        backend: ``local`` (worker processes on this machine) or ``ray`` (Ray tasks, ``pip install
            mjnav[ray]``), with the same records.
        address: Ray cluster to join with ``backend=ray`` (``auto``, ``HOST:6379``); default: a local Ray
            with ``workers`` CPUs.
        merge: Comma-separated shard folders or JSONL files to merge into ``out`` (one JSONL per task and
            the summary of the whole evaluation) instead of evaluating; refuses overlapping or
            disagreeing shards and missing episodes (all of the count the shards were run with, or
            of ``episodes=`` when given with ``merge=``).
    """

    policy: str | None = None
    task: str = "stage6"
    tasks: str | None = None
    episodes: int = 1000
    workers: int | None = None
    out: str | None = None
    seed_offset: int = 0
    action: str = "mean"
    from_contact: str | None = None
    shard: str | None = None
    backend: str = "local"
    address: str | None = None
    merge: str | None = None


def grammar() -> Grammar:
    """What ``evaluate`` accepts: :class:`EvaluateOptions`, ``task.*`` overrides and ``planner.*`` parameters."""
    # deferred: mjnav.config ~0.3 s (numba, scipy, osqp), not needed by `mjnav tables --help` (imports this module)
    from mjnav.config import TASK_SECTIONS

    return Grammar(EvaluateOptions, ("task", "planner"), {}, TASK_SECTIONS)


def parse_args(argv: Sequence[str]) -> tuple[list[EvalSpec], Path, Path | None]:
    """``key=value`` arguments (:mod:`mjnav.args`) → evaluation specs (one per task), the output
    folder and the ``from_contact`` folder (None when not given).

    Raises:
        ValueError: On an unknown key, a missing policy or a malformed argument.
    """
    parsed = parse(argv, grammar())
    opts = parsed.options
    if opts.policy is None:
        raise ValueError("policy= is required (mjnav evaluate --help)")
    workers = _at_least("workers", usable_cores() if opts.workers is None else opts.workers, 0)
    episodes, offset = _at_least("episodes", opts.episodes, 1), _at_least("seed_offset", opts.seed_offset, 0)
    # deferred: ~0.2 s (planners: MPC, numba, scipy, osqp), not needed by `mjnav evaluate --help`/`tables --help`
    from mjnav.eval.policies import ACTION_MODES
    from mjnav.policy import training_overrides

    try:
        trained = training_overrides(opts.policy)
    except FileNotFoundError as err:
        raise ValueError(str(err)) from None
    if opts.action not in ACTION_MODES:
        raise ValueError(f"action: expected one of {ACTION_MODES}, got {opts.action!r}")
    if opts.backend not in BACKENDS:
        raise ValueError(f"backend: expected one of {', '.join(BACKENDS)}, got {opts.backend!r}")
    if opts.address is not None and opts.backend != "ray":
        raise ValueError("address: a Ray cluster address; needs backend=ray")
    shard = parse_shard(opts.shard) if opts.shard is not None else (0, 1)
    tasks = (opts.tasks or opts.task).split(",")
    specs = [EvalSpec(t.strip(), opts.policy, episodes, offset, parsed.task, workers, trained, opts.action,
                      parsed.planner, shard, opts.backend, opts.address) for t in tasks if t.strip()]
    out = Path(opts.out or Path("evals") / opts.policy.replace(os.sep, "_").removesuffix(".pt"))
    from_contact = Path(opts.from_contact) if opts.from_contact is not None else None
    if from_contact is not None and not from_contact.is_dir():
        raise ValueError(f"from_contact: no such folder {str(from_contact)!r}")
    return specs, out, from_contact


def _at_least(key: str, value: int, minimum: int) -> int:
    if value < minimum:
        raise ValueError(f"{key}: must be >= {minimum}, got {value}")
    return value


def main(argv: Sequence[str]) -> int:
    """Command-line entry: evaluate, write the files, print the table; returns the exit code."""
    try:
        specs, out, from_contact = parse_args(argv)
    except ValueError as err:
        print(f"error: {err}", file=sys.stderr)
        return 2
    try:
        rows = evaluate_tasks(specs, out, from_contact=from_contact)
    except (ValueError, FileNotFoundError, EvalError) as err:  # bad task, override, policy or planner
        print(f"error: {err}", file=sys.stderr)
        return 2
    print(format_markdown(rows), end="")
    suffix = shard_suffix(specs[0].shard)
    print(f"wrote {out}/summary{suffix}.csv, {out}/summary{suffix}.md and one JSONL per task")
    return 0
