"""rsl-rl adapter: N gymnasium environments stepped by W worker processes.

:class:`NavVecEnv` implements :class:`rsl_rl.env.VecEnv` over environments built by a picklable
factory ``env_fn(index) -> gymnasium.Env``. Environment ``i`` lives in worker ``w`` (contiguous
blocks); observations, actions, rewards and flags travel through one shared-memory block, and a
pipe per worker carries the step command and a small reply (per-worker sums of the reward terms
and MPC statistics). With ``workers=0`` the environments are stepped in the calling process.

The adapter owns the episode clock (style pattern 6): it auto-resets finished environments,
truncates when ``episode_length_buf`` reaches ``max_episode_length`` (the runner may overwrite the
buffer) and reports ``extras["time_outs"]`` and ``extras["log"]``. Log keys contain a ``/``, so
rsl-rl's logger writes them unchanged (no ``Episode/`` prefix): ``episode/<metric>`` holds one value
per episode finished at this step, ``reward/<term>`` the per-step mean over all environments,
``mpc/<stat>`` one value per reporting environment, ``perf/env_step_ms`` the step's wall time.
``extras["outcomes"]`` holds each environment's outcome code (:data:`OUTCOMES` index) for the step.

Seeding: environment ``i``'s first reset uses ``seed + i``; later resets draw from the
environment's own generator, so the same seed and actions give the same rollouts.
"""

from __future__ import annotations

import contextlib
import multiprocessing as mp
import os
import time
import traceback
from collections import Counter
from collections.abc import Callable, Iterator
from multiprocessing import forkserver
from multiprocessing.connection import Connection
from multiprocessing.shared_memory import SharedMemory
from pathlib import Path
from typing import Any

import gymnasium as gym
import numpy as np
import torch
from rsl_rl.env import VecEnv
from tensordict import TensorDict

__all__ = ["OUTCOMES", "EnvError", "NavVecEnv"]

OUTCOMES: tuple[str, ...] = ("running", "success", "collision", "timeout")
"""Outcome names; ``extras["outcomes"]`` holds their indices."""

_CODES = {name: code for code, name in enumerate(OUTCOMES)}

EnvFn = Callable[[int], gym.Env]


class EnvError(RuntimeError):
    """An environment or worker failed; the message carries the original traceback."""


def _layout(num_envs: int, obs_dim: int, act_dim: int) -> tuple[dict[str, tuple], int]:
    """Byte offsets (64-aligned), dtypes and shapes of the shared buffers, and the total size."""
    n = num_envs
    specs = {
        "obs": (np.float32, (n, obs_dim)),
        "actions": (np.float32, (n, act_dim)),
        "rewards": (np.float32, (n,)),
        "terminated": (np.bool_, (n,)),
        "truncated": (np.bool_, (n,)),
        "force": (np.bool_, (n,)),
        "outcome": (np.int8, (n,)),
    }
    layout, offset = {}, 0
    for name, (dtype, shape) in specs.items():
        layout[name] = (offset, dtype, shape)
        offset += -(-int(np.prod(shape)) * np.dtype(dtype).itemsize // 64) * 64
    return layout, offset


def _views(buffer: Any, layout: dict[str, tuple]) -> dict[str, np.ndarray]:
    """Numpy views of the fields of ``layout`` onto ``buffer``."""
    return {name: np.ndarray(shape, dtype, buffer, offset) for name, (offset, dtype, shape) in layout.items()}


class _EnvGroup:
    """The environments of one worker, stepping into (shared) numpy buffers."""

    def __init__(self, env_fn: EnvFn, indices: range, seed: int) -> None:
        self.indices = indices
        self.seed = seed
        self.envs = [env_fn(i) for i in indices]
        self.buf: dict[str, np.ndarray] = {}
        self._seeded = False

    def describe(self) -> tuple[gym.Space, gym.Space, int | None]:
        """Spaces and step limit of the first environment."""
        env = self.envs[0]
        return env.observation_space, env.action_space, env.spec.max_episode_steps if env.spec else None

    def reset(self) -> None:
        """Reset every environment (seeded with ``seed + index`` the first time)."""
        for i, env in zip(self.indices, self.envs, strict=True):
            with _blame(i):
                self.buf["obs"][i], _ = env.reset(seed=None if self._seeded else self.seed + i)
        self._seeded = True
        self.buf["outcome"][self.indices.start : self.indices.stop] = 0

    def step(self) -> tuple[Counter, Counter, Counter]:
        """Step every environment with the shared actions; auto-reset finished ones.

        Returns:
            Sums over this group of the reward terms, sums and counts of the MPC statistics.
        """
        terms, mpc_sum, mpc_count = Counter(), Counter(), Counter()
        buf = self.buf
        for i, env in zip(self.indices, self.envs, strict=True):
            with _blame(i):
                obs, reward, terminated, truncated, info = env.step(buf["actions"][i].copy())
                terms.update(info.get("reward_terms", {}))  # Counter.update adds (negatives kept)
                mpc_sum.update(info.get("mpc", {}))
                mpc_count.update(info.get("mpc", {}).keys())
                truncated = (bool(truncated) or bool(buf["force"][i])) and not terminated
                buf["outcome"][i] = _outcome_code(info, bool(terminated), truncated)
                if terminated or truncated:
                    obs, _ = env.reset()
                buf["obs"][i], buf["rewards"][i] = obs, reward
                buf["terminated"][i], buf["truncated"][i] = terminated, truncated
        return terms, mpc_sum, mpc_count

    def close(self) -> None:
        """Close every environment."""
        for env in self.envs:
            env.close()


@contextlib.contextmanager
def _blame(index: int) -> Iterator[None]:
    """Add the environment index to any exception raised inside."""
    try:
        yield
    except Exception as exc:
        exc.add_note(f"(in environment {index})")
        raise


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
    import signal

    signal.signal(signal.SIGINT, signal.SIG_IGN)  # Ctrl-C is the main process's business
    signal.signal(signal.SIGTERM, signal.SIG_IGN)  # the main process closes us (or we see EOF)
    group, shm = None, None
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
            elif command == "attach":
                shm = SharedMemory(name=arg[0])
                group.buf = _views(shm.buf, arg[1])
                conn.send(("ok", None))
            elif command == "close":
                break
    except (EOFError, KeyboardInterrupt):
        return
    except BaseException:  # noqa: BLE001 - forwarded to the main process
        conn.send(("error", traceback.format_exc()))
    finally:
        if group is not None:
            group.buf = {}
            with contextlib.suppress(Exception):
                group.close()
        if shm is not None:
            shm.close()


class _LocalHandle(_EnvGroup):
    """In-process stand-in for a worker (``workers=0``): same protocol, no process."""

    def request(self, command: str, arg: Any = None) -> None:
        try:
            self._reply = self.buf.update(arg) if command == "attach" else getattr(self, command)()
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
        ctx.set_forkserver_preload([__name__])
        with _worker_environment():
            forkserver.ensure_running()
    return ctx


def _default_workers(num_envs: int) -> int:
    """One worker per usable CPU core, at most one per environment."""
    cores = len(os.sched_getaffinity(0)) if hasattr(os, "sched_getaffinity") else os.cpu_count() or 1
    return max(1, min(num_envs, cores))


class NavVecEnv(VecEnv):
    """``num_envs`` gymnasium environments behind rsl-rl's :class:`~rsl_rl.env.VecEnv` interface.

    Attributes:
        num_envs: Number of environments.
        num_actions: Action dimension.
        max_episode_length: Control steps before the adapter truncates an episode.
        episode_length_buf: Steps of each running episode (``long``, on ``device``); the runner may
            overwrite it (e.g. random initial lengths) and truncation honours the new values.
        device: Device of the returned tensors.
        cfg: Dictionary stored by rsl-rl's logger (task config and adapter settings).
        workers: Worker processes (0: in-process).
    """

    def __init__(
        self,
        env_fn: EnvFn,
        num_envs: int,
        seed: int = 0,
        workers: int | None = None,
        device: str | torch.device = "cpu",
        max_episode_length: int | None = None,
        start_method: str = "forkserver",
        step_timeout_s: float = 120.0,
        start_timeout_s: float = 600.0,
        cfg: dict | None = None,
    ) -> None:
        """Start the workers, build and reset the environments.

        Args:
            env_fn: Picklable factory; ``env_fn(i)`` builds environment ``i``.
            num_envs: Number of environments N.
            seed: Base seed; environment ``i`` is first reset with ``seed + i``.
            workers: Worker processes W <= N; None: one per CPU core; 0: step in this process.
            device: Device of the returned tensors.
            max_episode_length: Truncation limit in steps; None: the env's ``spec.max_episode_steps``.
            start_method: ``forkserver`` (Linux default) or ``spawn``; plain fork is unsafe with torch.
            step_timeout_s: Longest wait for a step or reset reply, seconds.
            start_timeout_s: Longest wait for a worker to build its environments, seconds.
            cfg: Extra configuration to expose as ``self.cfg``.

        Raises:
            EnvError: A worker failed to start or to build an environment (with its traceback).
            ValueError: Bad arguments or inconsistent spaces.
        """
        if num_envs < 1:
            raise ValueError(f"num_envs must be >= 1, got {num_envs}")
        self.workers = _default_workers(num_envs) if workers is None else workers
        if not 0 <= self.workers <= num_envs:
            raise ValueError(f"workers must be in [0, num_envs={num_envs}], got {self.workers}")
        self.num_envs, self.seed, self.device = num_envs, seed, torch.device(device)
        self.step_timeout_s = step_timeout_s
        self._handles: list[Any] = []
        self._shm: SharedMemory | None = None
        self._closed = False
        try:
            self._start(env_fn, start_method, start_timeout_s, max_episode_length)
        except BaseException:
            self.close()
            raise
        self.cfg = {
            "num_envs": num_envs,
            "workers": self.workers,
            "seed": seed,
            "max_episode_length": self.max_episode_length,
            **(cfg or {}),
        }

    def _start(self, env_fn: EnvFn, start_method: str, timeout: float, limit: int | None) -> None:
        blocks = [
            range(int(b[0]), int(b[-1]) + 1)
            for b in np.array_split(np.arange(self.num_envs), max(1, self.workers))
        ]
        if self.workers == 0:
            self._handles = [_LocalHandle(env_fn, blocks[0], self.seed)]
        else:
            ctx = _context(start_method)
            self._handles = [_WorkerHandle(ctx, env_fn, b, self.seed, k) for k, b in enumerate(blocks)]
        described = [h.result(timeout) for h in self._handles]
        self._check_spaces(described, limit)
        layout, nbytes = _layout(self.num_envs, self.observation_space.shape[0], self.num_actions)
        if self.workers == 0:
            self._buf = _views(bytearray(nbytes), layout)
            self._handles[0].request("attach", self._buf)
        else:
            self._shm = SharedMemory(create=True, size=nbytes)
            self._buf = _views(self._shm.buf, layout)
            self._call("attach", (self._shm.name, layout))
        self._term_names: set[str] = set()
        self.reset()

    def _check_spaces(self, described: list[tuple], limit: int | None) -> None:
        obs_space, act_space, env_limit = described[0]
        for other in described[1:]:
            if other[0].shape != obs_space.shape or other[1].shape != act_space.shape:
                raise ValueError(f"environments disagree on spaces: {obs_space} / {act_space} vs {other[:2]}")
        if len(obs_space.shape) != 1 or len(act_space.shape) != 1:
            raise ValueError(f"expected flat Box spaces, got {obs_space} and {act_space}")
        limit = limit if limit is not None else env_limit
        if limit is None:
            raise ValueError("max_episode_length not given and the env has no spec.max_episode_steps")
        self.observation_space, self.action_space = obs_space, act_space
        self.num_actions = int(act_space.shape[0])
        self.max_episode_length = int(limit)

    def _call(self, command: str, arg: Any = None) -> list[Any]:
        """Send ``command`` to every worker, then collect the replies; close everything on failure."""
        try:
            for handle in self._handles:
                handle.request(command, arg)
            return [handle.result(self.step_timeout_s) for handle in self._handles]
        except BaseException:
            self.close()
            raise

    def reset(self) -> TensorDict:
        """Reset every environment and the episode clock (the runner never calls this)."""
        self._call("reset")
        self.episode_length_buf = torch.zeros(self.num_envs, dtype=torch.long, device=self.device)
        self._returns = np.zeros(self.num_envs)
        self._steps = np.zeros(self.num_envs, dtype=np.int64)
        self._obs = torch.from_numpy(self._buf["obs"].copy()).to(self.device)
        return self.get_observations()

    def get_observations(self) -> TensorDict:
        """Current observations as ``TensorDict(policy=(N, obs_dim))``; never resets."""
        return TensorDict({"policy": self._obs.clone()}, batch_size=[self.num_envs], device=self.device)

    def step(self, actions: torch.Tensor) -> tuple[TensorDict, torch.Tensor, torch.Tensor, dict]:
        """Step every environment; finished ones are reset and report the new episode's observation.

        Args:
            actions: Raw policy outputs, shape (N, num_actions).

        Returns:
            Observations, rewards (N,) float32, dones (N,) long, extras with ``time_outs`` (N,) bool,
            ``outcomes`` (N,) int8 and ``log``.

        Raises:
            ValueError: Actions of the wrong shape or with NaN/inf (the envs are not stepped).
            EnvError: An environment raised or a worker died; the adapter is closed.
        """
        start = time.perf_counter()
        self._write_actions(actions)
        lengths = self.episode_length_buf.cpu().numpy() + 1
        self._buf["force"][:] = lengths >= self.max_episode_length
        replies = self._call("step")
        buf = self._buf
        rewards, outcome = buf["rewards"].copy(), buf["outcome"].copy()
        terminated, truncated = buf["terminated"].copy(), buf["truncated"].copy()
        done = terminated | truncated
        self._obs = torch.from_numpy(buf["obs"].copy()).to(self.device)
        self._returns += rewards
        self._steps += 1
        log = self._log(done, outcome, replies)
        self._returns[done], self._steps[done] = 0.0, 0
        self.episode_length_buf = torch.from_numpy(np.where(done, 0, lengths)).to(self.device)
        log["perf/env_step_ms"] = 1e3 * (time.perf_counter() - start)
        extras = {
            "time_outs": torch.from_numpy(truncated).to(self.device),
            "outcomes": torch.from_numpy(outcome).to(self.device),
            "log": log,
        }
        dones = torch.from_numpy(done.astype(np.int64)).to(self.device)
        return self.get_observations(), torch.from_numpy(rewards).to(self.device), dones, extras

    def _write_actions(self, actions: torch.Tensor) -> None:
        values = actions.detach().to("cpu", torch.float32).numpy()
        if values.shape != (self.num_envs, self.num_actions):
            raise ValueError(
                f"actions must have shape ({self.num_envs}, {self.num_actions}), got {values.shape}"
            )
        finite = np.isfinite(values).all(axis=1)
        if not finite.all():
            bad = np.flatnonzero(~finite).tolist()
            raise ValueError(f"non-finite actions (NaN/inf) for envs {bad[:16]}: the policy diverged")
        self._buf["actions"][:] = values

    def _log(self, done: np.ndarray, outcome: np.ndarray, replies: list[tuple]) -> dict[str, Any]:
        """``extras["log"]``: finished-episode metrics, reward-term and MPC means."""
        log: dict[str, Any] = {}
        if done.any():
            codes = outcome[done]
            for name in OUTCOMES[1:]:
                log[f"episode/{name}"] = torch.from_numpy((codes == _CODES[name]).astype(np.float32))
            log["episode/length"] = torch.from_numpy(self._steps[done].astype(np.float32))
            log["episode/return"] = torch.from_numpy(self._returns[done].astype(np.float32))
        terms, mpc_sum, mpc_count = Counter(), Counter(), Counter()
        for reply_terms, reply_sum, reply_count in replies:
            terms.update(reply_terms)
            mpc_sum.update(reply_sum)
            mpc_count.update(reply_count)
        self._term_names.update(terms)
        for key in sorted(self._term_names):
            log[f"reward/{key}"] = terms.get(key, 0.0) / self.num_envs
        for key, count in mpc_count.items():
            log[f"mpc/{key}"] = torch.full((count,), mpc_sum[key] / count)
        return log

    def close(self) -> None:
        """Stop the workers (joined, killed after 5 s) and free the shared memory; idempotent."""
        if getattr(self, "_closed", True):
            return
        self._closed = True
        for handle in self._handles:
            with contextlib.suppress(Exception):
                handle.close()
        self._buf = {}
        if self._shm is not None:
            self._shm.close()
            self._shm.unlink()
            self._shm = None

    def __enter__(self) -> NavVecEnv:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()

    def __del__(self) -> None:
        self.close()
