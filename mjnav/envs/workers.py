"""Worker side of :class:`mjnav.envs.vec_env.NavVecEnv` (no torch here).

A worker process owns a contiguous block of environments, steps them with the actions found in
a shared-memory block and writes observations, rewards and flags back; the reply on its pipe is
only the per-worker sums of the reward terms and MPC statistics. A worker also runs whole
rollouts with a policy it is sent (:meth:`_EnvGroup.rollout`), recording them in a second shared
block. :class:`_LocalHandle` runs the same protocol in the calling process (``workers=0``).
"""

from __future__ import annotations

import contextlib
import multiprocessing as mp
import os
import signal
import time
import traceback
from collections import Counter
from collections.abc import Callable, Iterator, Sequence
from multiprocessing import forkserver
from multiprocessing.connection import Connection
from multiprocessing.shared_memory import SharedMemory
from pathlib import Path
from typing import Any

import gymnasium as gym
import numpy as np

from mjnav.jobs import usable_cores

__all__ = ["OUTCOMES", "EnvError", "rollout_parts", "step_in_stages", "usable_cores"]

OUTCOMES: tuple[str, ...] = ("running", "success", "collision", "timeout")
"""Outcome names; ``extras["outcomes"]`` holds their indices."""

_CODES = {name: code for code, name in enumerate(OUTCOMES)}

EnvFn = Callable[[int], gym.Env]

RolloutPolicy = Callable[[int, range, np.ndarray, "np.ndarray | None"], tuple[np.ndarray, np.ndarray]]
"""``policy(t, indices, obs, critic) -> (actions, aux)``: a worker's actions for its environments
``indices`` at step ``t`` of a rollout, from their observations (and privileged critic inputs, or
None), with any other per-environment outputs to record (``aux``, float32)."""


class EnvError(RuntimeError):
    """An environment or worker failed; the message carries the original traceback."""


def _layout(num_envs: int, obs_dim: int, act_dim: int, critic_dim: int = 0) -> tuple[dict[str, tuple], int]:
    """Byte offsets (64-aligned), dtypes and shapes of the shared buffers, and the total size."""
    n = num_envs
    return _pack({
        "obs": (np.float32, (n, obs_dim)),
        "critic": (np.float32, (n, critic_dim)),
        "actions": (np.float32, (n, act_dim)),
        "rewards": (np.float32, (n,)),
        "terminated": (np.bool_, (n,)),
        "truncated": (np.bool_, (n,)),
        "force": (np.bool_, (n,)),
        "outcome": (np.int8, (n,)),
    })


def _record_layout(
    steps: int, num_envs: int, obs_dim: int, act_dim: int, critic_dim: int, aux_dim: int
) -> tuple[dict[str, tuple], int]:
    """The shared record of a rollout (:meth:`_EnvGroup.rollout`): each step's actions, the policy's
    other outputs (``aux``) and the step's results, for ``steps`` steps of ``num_envs`` environments."""
    t, n = steps, num_envs
    return _pack({
        "actions": (np.float32, (t, n, act_dim)),
        "aux": (np.float32, (t, n, aux_dim)),
        "obs": (np.float32, (t, n, obs_dim)),
        "critic": (np.float32, (t, n, critic_dim)),
        "rewards": (np.float32, (t, n)),
        "terminated": (np.bool_, (t, n)),
        "truncated": (np.bool_, (t, n)),
        "outcome": (np.int8, (t, n)),
    })


#: The fields of a step's results, copied from the step buffers into a rollout's record.
_RESULTS = ("obs", "critic", "rewards", "terminated", "truncated", "outcome")


def _pack(specs: dict[str, tuple]) -> tuple[dict[str, tuple], int]:
    """Byte offsets (64-aligned) of fields given as ``name: (dtype, shape)``, and the total size."""
    layout, offset = {}, 0
    for name, (dtype, shape) in specs.items():
        layout[name] = (offset, dtype, shape)
        offset += -(-int(np.prod(shape)) * np.dtype(dtype).itemsize // 64) * 64
    return layout, offset


def _views(buffer: Any, layout: dict[str, tuple]) -> dict[str, np.ndarray]:
    """Numpy views of the fields of ``layout`` onto ``buffer``."""
    return {name: np.ndarray(shape, dtype, buffer, offset) for name, (offset, dtype, shape) in layout.items()}


class _EnvGroup:
    """The environments of one worker, stepping into (shared) numpy buffers.

    Environments that offer ``step_stages`` (:class:`mjnav.envs.gym_env.NavGymEnv`; :attr:`staged`)
    are stepped stage by stage, the others in turn; the results are the same.
    """

    def __init__(self, env_fn: EnvFn, indices: range, seed: int) -> None:
        self.indices = indices
        self.seed = seed
        self.envs = [env_fn(i) for i in indices]
        self.buf: dict[str, np.ndarray] = {}
        self.rec: dict[str, np.ndarray] = {}  # a rollout's record (:func:`_record_layout`)
        self._seeded = False

    def describe(self) -> tuple[gym.Space, gym.Space, int | None, int]:
        """Spaces, step limit and privileged critic size (``critic_size``, 0 without) of the first environment."""
        env = self.envs[0]
        limit = env.spec.max_episode_steps if env.spec else None
        return env.observation_space, env.action_space, limit, int(getattr(env, "critic_size", 0))

    def _store_critic(self, i: int, info: dict) -> None:
        """Copy environment ``i``'s ``info["critic"]`` into the shared buffer (when the buffer has one)."""
        critic = self.buf["critic"]
        if critic.shape[1]:
            if "critic" not in info:
                raise KeyError(f"critic_size is {critic.shape[1]} but info has no 'critic' entry")
            critic[i] = info["critic"]

    def reset(self) -> None:
        """Reset every environment (seeded with ``seed + index`` the first time)."""
        for i, env in zip(self.indices, self.envs, strict=True):
            try:
                self.buf["obs"][i], info = env.reset(seed=None if self._seeded else self.seed + i)
                self._store_critic(i, info)
            except Exception as exc:
                _blame(exc, i)
                raise
        self._seeded = True
        self.buf["outcome"][self.indices.start : self.indices.stop] = 0

    def step(self, part: range | None = None) -> tuple[Counter, Counter, Counter, float, float]:
        """Step every environment (of ``part``, default all) with the shared actions; auto-reset finished ones.

        Returns:
            Sums over these environments of the reward terms, sums and counts of the MPC
            statistics, and the wall-clock and CPU seconds of this call (measured where it runs;
            the CPU time leaves out the time the process waited for a core on a shared machine).
        """
        start, cpu = time.perf_counter(), time.thread_time()
        indices = self.indices if part is None else part
        envs = self.envs[indices.start - self.indices.start : indices.stop - self.indices.start]
        terms: dict[str, float] = {}
        mpc_sum: dict[str, float] = {}
        mpc_count: dict[str, int] = {}
        buf = self.buf
        actions, force, outcomes = buf["actions"], buf["force"], buf["outcome"]
        observations, rewards, terminated_buf, truncated_buf = buf["obs"], buf["rewards"], buf["terminated"], buf["truncated"]
        if self.staged:
            steps = step_in_stages(envs, [actions[i].copy() for i in indices], indices)
        else:
            steps = self._in_turn(actions, indices, envs)
        for i, env, (obs, reward, terminated, truncated, info) in zip(indices, envs, steps, strict=True):
            try:
                for name, value in info.get("reward_terms", {}).items():  # plain dict sums: cheaper than Counter
                    terms[name] = terms.get(name, 0.0) + value
                for name, value in info.get("mpc", {}).items():
                    mpc_sum[name] = mpc_sum.get(name, 0.0) + value
                    mpc_count[name] = mpc_count.get(name, 0) + 1
                terminated = bool(terminated)
                truncated = (bool(truncated) or bool(force[i])) and not terminated
                outcomes[i] = _outcome_code(info, terminated, truncated)
                if terminated or truncated:
                    obs, info = env.reset()
                self._store_critic(i, info)
                observations[i], rewards[i] = obs, reward
                terminated_buf[i], truncated_buf[i] = terminated, truncated
            except Exception as exc:
                _blame(exc, i)
                raise
        return Counter(terms), Counter(mpc_sum), Counter(mpc_count), time.perf_counter() - start, time.thread_time() - cpu

    def rollout(
        self, policy: RolloutPolicy, steps: int, lengths: np.ndarray, limit: int, part_size: int = 0
    ) -> tuple[list[tuple], tuple[int, list[int]] | None]:
        """Step ``steps`` times with the actions ``policy`` chooses from each step's observations;
        record every step's actions, the policy's other outputs and the results in :attr:`rec`.

        Each step is :meth:`step` (auto-resets included) with the truncations the adapter would
        force: an environment whose episode reaches ``limit`` steps is truncated. The group runs
        in parts of at most ``part_size`` environments (0: all at once; :func:`rollout_parts`), each
        part through all ``steps`` before the next: a part's environments stay in the cache.

        Args:
            policy: ``policy(t, indices, obs, critic) -> (actions, aux)`` for the environments
                ``indices`` at step ``t`` (``critic`` None without privileged inputs).
            steps: Steps to run.
            lengths: Every environment's episode length before the first step (all N).
            limit: The adapter's ``max_episode_length``.
            part_size: Most environments stepped together.

        Returns:
            Each step's reply (:meth:`step`'s, then the wall and CPU seconds the policy took,
            summed over the parts), and None, or
            ``(t, environments)`` when the policy's actions at step ``t`` were not finite for those
            environments (the rollout stopped there, before stepping them).
        """
        replies: list[list[tuple]] = []
        for part in rollout_parts(self.indices, part_size):
            part_replies, failed = self._roll_part(policy, steps, lengths, limit, part)
            if failed is not None:
                return [], failed
            replies.append(part_replies)
        return [_summed(step) for step in zip(*replies, strict=True)], None

    def _roll_part(
        self, policy: RolloutPolicy, steps: int, lengths: np.ndarray, limit: int, part: range
    ) -> tuple[list[tuple], tuple[int, list[int]] | None]:
        """:meth:`rollout` of the environments ``part``."""
        rows = slice(part.start, part.stop)
        buf, rec = self.buf, self.rec
        lengths = np.array(lengths[rows], dtype=np.int64)
        replies = []
        for t in range(steps):
            critic = buf["critic"][rows] if buf["critic"].shape[1] else None
            start, cpu = time.perf_counter(), time.thread_time()
            actions, aux = policy(t, part, buf["obs"][rows], critic)
            chose = time.perf_counter() - start, time.thread_time() - cpu
            actions, aux = _checked_outputs(actions, aux, rec, part)
            finite = np.isfinite(actions).all(axis=1)
            if not finite.all():
                return replies, (t, (part.start + np.flatnonzero(~finite)).tolist())
            buf["actions"][rows] = rec["actions"][t, rows] = actions
            rec["aux"][t, rows] = aux
            lengths += 1
            buf["force"][rows] = lengths >= limit
            replies.append((*self.step(part), *chose))
            for name in _RESULTS:
                rec[name][t, rows] = buf[name][rows]
            lengths[buf["terminated"][rows] | buf["truncated"][rows]] = 0
        return replies, None

    @property
    def staged(self) -> bool:
        """Whether every environment steps as well stage by stage: it has ``step_stages`` and says
        its ``stages_are_step`` (:class:`mjnav.envs.gym_env.NavGymEnv`, not wrapped, ``step`` not overridden)."""
        return all(_stages_are_step(env) for env in self.envs)

    @staticmethod
    def _in_turn(actions: np.ndarray, indices: range, envs: list[Any]) -> Iterator[tuple]:
        """Each environment's ``step`` result, stepping it only when asked for it."""
        for i, env in zip(indices, envs, strict=True):
            try:
                yield env.step(actions[i].copy())
            except Exception as exc:
                _blame(exc, i)
                raise

    def close(self) -> None:
        """Close every environment."""
        for env in self.envs:
            env.close()


def _stages_are_step(env: Any) -> bool:
    """Whether ``env`` itself (its class, not an object it forwards attributes to) offers
    ``stages_are_step`` and it holds."""
    return hasattr(type(env), "stages_are_step") and bool(env.stages_are_step)


def step_in_stages(envs: list[Any], actions: list[np.ndarray], indices: Sequence[int] | None = None) -> list[tuple]:
    """Step environments that offer ``step_stages`` (:meth:`mjnav.envs.gym_env.NavGymEnv.step_stages`)
    stage by stage: the first stage of each, then the second ..., until every step has ended.
    Only for environments whose ``step`` runs exactly those stages (``stages_are_step``).

    An environment's stages touch only its own state, so the results are those of stepping the
    environments in turn; each stage's code and shared data stay in the cache across the
    environments (:meth:`mjnav.envs.environment.NavEnvironment.step_stages`).

    Args:
        envs: The environments.
        actions: One action per environment.
        indices: The environments' indices for error notes (default: their positions).

    Returns:
        Each environment's ``step`` result ``(obs, reward, terminated, truncated, info)``.

    Raises:
        Exception: The first one a stage raises, noted with its environment's index; the other
            environments are left within their step.
    """
    indices = range(len(envs)) if indices is None else indices
    stepping = [(k, env.step_stages(action)) for k, (env, action) in enumerate(zip(envs, actions, strict=True))]
    results: list[tuple] = [()] * len(stepping)
    while stepping:
        going = []
        for k, stages in stepping:
            try:
                next(stages)
                going.append((k, stages))
            except StopIteration as done:
                results[k] = done.value
            except Exception as exc:
                _blame(exc, indices[k])
                raise
        stepping = going
    return results


def rollout_parts(indices: range, size: int) -> list[range]:
    """``indices`` in contiguous parts of at most ``size`` (as even as possible; 0: one part)."""
    count = 1 if size <= 0 else -(-len(indices) // size)
    return [range(indices.start + int(p[0]), indices.start + int(p[-1]) + 1)
            for p in np.array_split(np.arange(len(indices)), count)]


def _summed(replies: tuple[tuple, ...]) -> tuple:
    """Replies of one rollout step for parts of a group (:meth:`_EnvGroup.step`'s, then the wall and
    CPU seconds the policy took), as one: sums of each entry."""
    terms, mpc_sum, mpc_count = Counter(), Counter(), Counter()
    for reply in replies:
        terms.update(reply[0])
        mpc_sum.update(reply[1])
        mpc_count.update(reply[2])
    return terms, mpc_sum, mpc_count, *(sum(r[k] for r in replies) for k in (3, 4, 5, 6))


def _checked_outputs(actions: Any, aux: Any, rec: dict[str, np.ndarray], part: range) -> tuple[np.ndarray, np.ndarray]:
    """A rollout policy's actions and ``aux`` for ``part`` as float32 arrays of the record's widths.

    Raises:
        ValueError: Another shape (nothing is broadcast over the environments).
    """
    actions, aux = np.asarray(actions, dtype=np.float32), np.asarray(aux, dtype=np.float32)
    wanted = ((len(part), rec["actions"].shape[2]), (len(part), rec["aux"].shape[2]))
    if (actions.shape, aux.shape) != wanted:
        raise ValueError(f"the rollout policy gave actions {actions.shape} and aux {aux.shape} for envs "
                         f"{part.start}-{part.stop - 1}; expected {wanted[0]} and {wanted[1]}")
    return actions, aux


def _blame(exc: Exception, index: int) -> None:
    """Add the environment index to an exception raised while stepping or resetting it."""
    exc.add_note(f"(in environment {index})")


def _outcome_code(info: dict, terminated: bool, truncated: bool) -> int:
    """Outcome index of one step; truncation without a terminal outcome counts as timeout."""
    name = info.get("outcome", "running")
    if name not in _CODES:
        raise ValueError(f"unknown outcome {name!r} (expected one of {OUTCOMES})")
    code = _CODES[name]
    if terminated and code in (0, 3):
        raise ValueError(f"terminated with outcome {name!r} (timeouts must be truncations)")
    if truncated and code == 0:
        code = _CODES["timeout"]
    return code


def _worker_main(conn: Connection, env_fn: EnvFn, indices: range, seed: int) -> None:
    """Worker loop: build the envs, report their spaces, then serve commands until ``close``."""
    signal.signal(signal.SIGINT, signal.SIG_IGN)  # Ctrl-C is the main process's business
    signal.signal(signal.SIGTERM, signal.SIG_IGN)  # the main process closes us (or we see EOF)
    group, shm, record = None, None, None
    try:
        group = _EnvGroup(env_fn, indices, seed)
        conn.send(("ok", group.describe()))
        while True:
            command, arg = conn.recv()
            if command == "step":
                conn.send(("ok", group.step()))
            elif command == "reset":
                group.reset()
                conn.send(("ok", None))
            elif command == "rollout":
                conn.send(("ok", group.rollout(*arg)))
            elif command == "attach":
                shm = SharedMemory(name=arg[0])
                group.buf = _views(shm.buf, arg[1])
                conn.send(("ok", None))
            elif command == "record":  # a new record replaces the last one
                group.rec = {}
                if record is not None:
                    record.close()
                record = SharedMemory(name=arg[0])
                group.rec = _views(record.buf, arg[1])
                conn.send(("ok", None))
            elif command == "close":
                break
    except (EOFError, KeyboardInterrupt):
        return
    except BaseException:  # noqa: BLE001 - forwarded to the main process
        conn.send(("error", traceback.format_exc()))
    finally:
        if group is not None:
            group.buf, group.rec = {}, {}
            with contextlib.suppress(Exception):
                group.close()
        for segment in (shm, record):
            if segment is not None:
                segment.close()


class _LocalHandle(_EnvGroup):
    """In-process stand-in for a worker (``workers=0``): same protocol, no process."""

    def request(self, command: str, arg: Any = None) -> None:
        try:
            if command == "attach":
                self._reply = self.buf.update(arg)
            elif command == "record":
                self.rec, self._reply = arg, None
            else:
                self._reply = getattr(self, command)(*(() if arg is None else arg))
        except Exception as exc:
            raise EnvError(
                f"envs {self.indices.start}-{self.indices.stop - 1} raised:\n{traceback.format_exc()}"
            ) from exc

    def result(self, timeout: float) -> Any:
        return self._reply if hasattr(self, "_reply") else self.describe()


class _WorkerHandle:
    """A worker process stepping ``indices`` and the main process's end of its pipe."""

    def __init__(self, ctx: Any, env_fn: EnvFn, indices: range, seed: int, rank: int) -> None:
        self.indices = indices
        self.name = f"worker {rank} (envs {indices.start}-{indices.stop - 1})"
        self.conn, child = ctx.Pipe()
        self.process = ctx.Process(
            target=_worker_main, args=(child, env_fn, indices, seed), name=f"mjnav-env-{rank}", daemon=True
        )
        with _worker_environment():
            self.process.start()
        child.close()

    def request(self, command: str, arg: Any = None) -> None:
        try:
            self.conn.send((command, arg))
        except (BrokenPipeError, EOFError, OSError):
            raise EnvError(f"{self.name} is gone (exit code {self.process.exitcode})") from None

    def result(self, timeout: float) -> Any:
        if not self.conn.poll(timeout):
            raise EnvError(f"{self.name} did not answer within {timeout:.0f} s")
        try:
            status, payload = self.conn.recv()
        except (EOFError, OSError):
            self.process.join(1.0)
            raise EnvError(f"{self.name} died (exit code {self.process.exitcode})") from None
        if status == "error":
            raise EnvError(f"{self.name} raised:\n{payload}")
        return payload

    def close(self) -> None:
        with contextlib.suppress(OSError):
            self.conn.send(("close", None))
        self.process.join(5.0)
        if self.process.is_alive():
            self.process.kill()
            self.process.join(1.0)
        self.conn.close()


# Each worker steps small dense problems; multi-threaded BLAS/OpenMP pools in every worker
# oversubscribe the cores (measured: 2 workers x 16 envs ran 2.5x slower with default pools).
_WORKER_ENV = {"OMP_NUM_THREADS": "1", "OPENBLAS_NUM_THREADS": "1", "MKL_NUM_THREADS": "1",
               "NUMBA_NUM_THREADS": "1"}


@contextlib.contextmanager
def _worker_environment() -> Iterator[None]:
    """Temporarily set what worker processes inherit: the package on PYTHONPATH, 1-thread pools.

    Python 3.11's forkserver ignores the parent's sys.path, so the package root is added.
    """
    root = str(Path(__file__).resolve().parents[2])
    wanted = {**_WORKER_ENV, "PYTHONPATH": os.pathsep.join(filter(None, [root, os.environ.get("PYTHONPATH")]))}
    saved = {key: os.environ.get(key) for key in wanted}
    os.environ.update({k: v if k == "PYTHONPATH" else os.environ.get(k, v) for k, v in wanted.items()})
    try:
        yield
    finally:
        for key, value in saved.items():
            if value is None:
                os.environ.pop(key, None)
            else:
                os.environ[key] = value


def _context(start_method: str) -> Any:
    """Multiprocessing context for ``start_method``.

    With forkserver, the single-threaded server preloads this module, so torch is imported once
    instead of in every worker (~3 s each).
    """
    ctx = mp.get_context(start_method)
    if start_method == "forkserver":
        ctx.set_forkserver_preload(["mjnav.envs.vec_env"])
        with _worker_environment():
            forkserver.ensure_running()
    return ctx


def _default_workers(num_envs: int) -> int:
    """One worker per usable CPU core, at most one per environment."""
    return max(1, min(num_envs, usable_cores()))
