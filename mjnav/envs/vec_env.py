"""rsl-rl adapter: N gymnasium environments stepped by W workers.

:class:`NavVecEnv` implements :class:`rsl_rl.env.VecEnv` over environments built by a picklable
factory ``env_fn(index) -> gymnasium.Env``. Environment ``i`` lives in worker ``w`` (contiguous
blocks); observations, actions, rewards and flags travel through one shared-memory block, and a
pipe per worker process carries the step command and a small reply (per-worker sums of the reward
terms and MPC statistics). By default the calling process is worker 0: it steps the first block
itself while W - 1 worker processes step the others (on a 2-core VM, measured 1.2-1.8x the
env steps/s of two worker processes and an idle caller, whose three-way hand-offs left cores
idle). With ``workers=0`` every environment is stepped in the calling process.

The adapter owns the episode clock (style pattern 6): it auto-resets finished environments,
truncates when ``episode_length_buf`` reaches ``max_episode_length`` (the runner may overwrite the
buffer) and reports ``extras["time_outs"]`` and ``extras["log"]``. Log keys contain a ``/``, so
rsl-rl's logger writes them unchanged (no ``Episode/`` prefix): ``episode/<metric>`` holds one value
per episode finished at this step, ``reward/<term>`` the per-step mean over all environments,
``mpc/<stat>`` one value per reporting environment, ``perf/env_step_ms`` the step's wall time,
``perf/own_block_ms`` the part of it this process spent stepping its own block (0 when it steps
none), ``perf/wait_ms`` the part it then waited for the worker processes and
``perf/transfer_ms`` the part spent moving actions into and observations, rewards and flags out
of the shared buffers (with the tensors made of them) and sending the step command down the
pipes; the rest of a step is the adapter's own bookkeeping (episode clock, logs).
``perf/worker_step_ms`` and ``perf/worker_step_max_ms`` are the mean and the longest time the
worker processes took to step their blocks, timed inside them (0 without worker processes):
``wait`` beyond ``worker_step_max - own_block`` is hand-off latency; ``perf/worker_cpu_max_ms`` is
the largest CPU time among them (without the time spent waiting for a core on a shared machine).
A step served from a rollout (:meth:`NavVecEnv.rollout`) logs the rollout's times: ``own_block_ms``
this process's stepping of its block in that step and ``perf/rollout_policy_ms`` its policy calls,
``wait_ms`` the rest of the rollout spread evenly over its steps (sending the policy to the worker
processes, the record, the wait for them at the end), ``env_step_ms`` the serving plus
``own_block_ms`` and ``wait_ms``, and the worker processes' step and CPU times their policy calls
included (so the hand-off rule above does not apply).
``extras["outcomes"]`` holds each environment's outcome code (:data:`OUTCOMES` index) for the step.

:meth:`NavVecEnv.dispatch` starts a step early: the worker processes step with the actions while
the caller goes on (PPO's value estimates and storage), and the next :meth:`NavVecEnv.step` with
the same actions steps this process's block and collects; the results are those of ``step``
alone. The ``perf/*`` times then leave out the dispatch (writing the actions, sending the command).

:meth:`NavVecEnv.rollout` goes further: given a picklable policy (``policy(t, indices, obs,
critic) -> (actions, aux)``, :class:`mjnav.train.ppo.RolloutActor` for PPO), every worker runs the
next ``steps`` steps of its block by itself, choosing its environments' actions, without waiting
for the others or for the caller at each step; the record (actions, ``aux``, results) goes to a
second shared-memory block, and the next ``steps`` calls of :meth:`NavVecEnv.step` serve it in
order, each returning what ``step`` with those actions returns (``perf/*`` times as above). A
worker runs its block in parts of at most ``rollout_envs`` environments, each part through every
step before the next, so that a part's environments stay in the cache.

Seeding: environment ``i``'s first reset uses ``seed + i``; later resets draw from the
environment's own generator, so the same seed and actions give the same rollouts.
"""

from __future__ import annotations

import contextlib
import dataclasses
import os
import time
from collections import Counter
from multiprocessing.shared_memory import SharedMemory
from typing import Any

import numpy as np
import torch
from rsl_rl.env import VecEnv
from tensordict import TensorDict

from mjnav.envs.workers import (
    _CODES,
    _RESULTS,
    OUTCOMES,
    EnvError,
    EnvFn,
    RolloutPolicy,
    _context,
    _default_workers,
    _layout,
    _LocalHandle,
    _record_layout,
    _views,
    _WorkerHandle,
    rollout_parts,
)
from mjnav.schema import ConfigError

__all__ = ["OUTCOMES", "EnvError", "NavVecEnv"]

def _blocks(num_envs: int, workers: int, first: int | None = None) -> list[range]:
    """Contiguous blocks of environment indices, one per worker (one block for ``workers`` <= 1).

    Args:
        num_envs: Number of environments N.
        workers: Workers W.
        first: Size of the first block with W >= 2 (the others share the rest evenly); None:
            even blocks. Ignored with fewer than 2 workers (one block).

    Raises:
        ConfigError: ``first`` leaves a block empty (it must be in [1, N - W + 1]).
    """
    count = max(1, workers)
    if first is None or count == 1:
        sizes = [len(b) for b in np.array_split(np.arange(num_envs), count)]
    elif 1 <= first <= num_envs - count + 1:
        sizes = [first, *(len(b) for b in np.array_split(np.arange(num_envs - first), count - 1))]
    else:
        raise ConfigError(f"main_envs must be in [1, {num_envs - count + 1}] with {num_envs} environments "
                          f"on {workers} workers, got {first}")
    ends = np.cumsum(sizes)
    return [range(int(end - size), int(end)) for size, end in zip(sizes, ends, strict=True)]


def _same(actions: torch.Tensor, expected: np.ndarray) -> bool:
    """Whether ``actions`` are, as float32, the actions ``expected`` (those the workers stepped with)."""
    return np.array_equal(actions.detach().to("cpu", torch.float32).numpy(), expected)


@dataclasses.dataclass
class _Replay:
    """A rollout being served by :meth:`NavVecEnv.step`: its length, each step's worker replies
    (in the order of the handles), this process's wait for the others spread over the steps, and
    the steps served so far."""

    steps: int
    replies: list[list[tuple]]
    wait_s: float  # this process's wait for the worker processes in the rollout, per step
    served: int = 0


class NavVecEnv(VecEnv):
    """``num_envs`` gymnasium environments behind rsl-rl's :class:`~rsl_rl.env.VecEnv` interface.

    Attributes:
        num_envs: Number of environments.
        num_actions: Action dimension.
        critic_dim: Length of the privileged critic inputs (``info["critic"]``, the envs'
            ``critic_size``; 0: none, and observations hold the ``policy`` group only).
        max_episode_length: Control steps before the adapter truncates an episode.
        episode_length_buf: Steps of each running episode (``long``, on ``device``); the runner may
            overwrite it (e.g. random initial lengths) and truncation honours the new values.
        device: Device of the returned tensors.
        cfg: Dictionary stored by rsl-rl's logger (task config and adapter settings).
        workers: Workers stepping environments in parallel, this process included when
            ``step_in_main`` (0: all in this process).
        blocks: The environment indices of each worker, this process's first when ``step_in_main``.
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
        step_in_main: bool = True,
        main_envs: int | None = None,
        rollout_envs: int = 16,
    ) -> None:
        """Start the workers, build and reset the environments.

        Args:
            env_fn: Picklable factory; ``env_fn(i)`` builds environment ``i``.
            num_envs: Number of environments N.
            seed: Base seed; environment ``i`` is first reset with ``seed + i``.
            workers: Workers W <= N stepping environments in parallel; None: one per CPU core; 0:
                all in this process.
            device: Device of the returned tensors.
            max_episode_length: Truncation limit in steps; None: the env's ``spec.max_episode_steps``.
            start_method: ``forkserver`` (Linux default) or ``spawn``; plain fork is unsafe with torch.
            step_timeout_s: Longest wait for a step or reset reply, seconds.
            start_timeout_s: Longest wait for a worker to build its environments, seconds.
            cfg: Extra configuration to expose as ``self.cfg``.
            step_in_main: This process is worker 0 (W - 1 worker processes); False: W worker
                processes and this process only waits.
            main_envs: With ``step_in_main`` and W >= 2: the environments this process steps
                itself (the first block; the worker processes share the rest evenly). None: an even
                share; ignored with W < 2. Fewer leave it time for its own per-step work (the policy, the adapter's
                bookkeeping) while the worker processes step; rollouts do not depend on it.
            rollout_envs: Most environments a worker runs together through a :meth:`rollout` (its
                block in parts of at most this many, one part after another; 0: the whole block).
                Fewer keep a part's environments in the cache; results do not depend on it.

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
        self.step_in_main = step_in_main
        if main_envs is not None and not step_in_main:
            raise ValueError("main_envs needs step_in_main=True (this process steps the first block)")
        self.blocks = _blocks(num_envs, self.workers, main_envs)
        if rollout_envs < 0:
            raise ValueError(f"rollout_envs must be >= 0, got {rollout_envs}")
        self.rollout_envs = rollout_envs
        self.step_timeout_s = step_timeout_s
        self._handles: list[Any] = []
        self._shm: SharedMemory | None = None
        self._shm_named = False  # the segment still has its name in /dev/shm
        self._closed = False
        self._split = (0.0, 0.0)  # seconds of the last call: own block, wait
        self._pending: np.ndarray | None = None  # episode lengths after the dispatched step
        self._record: tuple[SharedMemory | None, dict[str, np.ndarray], tuple] = (None, {}, ())
        self._replay: _Replay | None = None  # the rollout being served by step()
        self._remote = 0  # worker processes (the first handles)
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
        blocks = self.blocks
        local = self.workers == 0 or self.step_in_main
        remote = blocks[1:] if local else blocks
        if remote:
            ctx = _context(start_method)
            first = len(blocks) - len(remote)
            self._handles = [_WorkerHandle(ctx, env_fn, b, self.seed, first + k) for k, b in enumerate(remote)]
            self._remote = len(self._handles)
        if local:  # last, so the worker processes get each command before this process steps
            self._handles.append(_LocalHandle(env_fn, blocks[0], self.seed))
        described = [h.result(timeout) for h in self._handles]
        self._check_spaces(described, limit)
        layout, nbytes = _layout(self.num_envs, self.observation_space.shape[0], self.num_actions, self.critic_dim)
        if remote:
            self._shm, self._shm_named = SharedMemory(create=True, size=nbytes), True
            self._buf = _views(self._shm.buf, layout)
        else:
            self._buf = _views(bytearray(nbytes), layout)
        for handle in self._handles:
            handle.request("attach", self._buf if isinstance(handle, _LocalHandle) else (self._shm.name, layout))
        for handle in self._handles:
            handle.result(timeout)
        if self._shm is not None:  # every worker has mapped it: its name goes (the mappings stay valid),
            self._shm.unlink()  # so a SIGKILL of every process leaves nothing in /dev/shm
            self._shm_named = False
        self._term_names: set[str] = set()
        self.reset()

    def _check_spaces(self, described: list[tuple], limit: int | None) -> None:
        obs_space, act_space, env_limit, critic_dim = described[0]
        for other in described[1:]:
            if other[0].shape != obs_space.shape or other[1].shape != act_space.shape or other[3] != critic_dim:
                raise ValueError(
                    f"environments disagree on spaces: {obs_space} / {act_space} / critic {critic_dim} vs "
                    f"{other[0]} / {other[1]} / critic {other[3]}"
                )
        if len(obs_space.shape) != 1 or len(act_space.shape) != 1:
            raise ValueError(f"expected flat Box spaces, got {obs_space} and {act_space}")
        limit = limit if limit is not None else env_limit
        if limit is None:
            raise ValueError("max_episode_length not given and the env has no spec.max_episode_steps")
        self.observation_space, self.action_space = obs_space, act_space
        self.num_actions = int(act_space.shape[0])
        self.critic_dim = int(critic_dim)
        self.max_episode_length = int(limit)

    def _call(self, command: str, arg: Any = None) -> list[Any]:
        """Send ``command`` to every worker, then collect the replies; close everything on failure."""
        self._send(command, arg)
        return self._finish(command, arg)

    def _send(self, command: str, arg: Any = None) -> None:
        """Send ``command`` to the worker processes (not to this process's own block); closes
        everything on failure."""
        try:
            for handle in self._handles[: self._remote]:
                handle.request(command, arg)
        except BaseException:
            self.close()
            raise

    def _finish(self, command: str, arg: Any = None, timeout: float | None = None) -> list[Any]:
        """Run ``command`` on this process's own block (when it steps one), then collect every reply.

        The worker processes must have been sent ``command`` (:meth:`_send`). Notes in ``_split``
        the seconds this process spent on its own block (0 when it steps none) and the seconds it
        then waited for the replies (at most ``timeout`` each, default ``step_timeout_s``); closes
        everything on failure.
        """
        try:
            start = time.perf_counter()
            local = self._handles[self._remote :]
            for handle in local:
                handle.request(command, arg)
            ready = time.perf_counter()
            replies = [handle.result(timeout or self.step_timeout_s) for handle in self._handles]
            self._split = (ready - start if local else 0.0, time.perf_counter() - ready)
            return replies
        except BaseException:
            self.close()
            raise

    def reset(self) -> TensorDict:
        """Reset every environment and the episode clock (the runner never calls this).

        Raises:
            RuntimeError: A step was dispatched and not yet finished by :meth:`step`.
        """
        self._check_idle("reset")
        self._replay = None  # a rollout still being served is dropped: every environment restarts
        self._call("reset")
        self.episode_length_buf = torch.zeros(self.num_envs, dtype=torch.long, device=self.device)
        self._returns = np.zeros(self.num_envs)
        self._steps = np.zeros(self.num_envs, dtype=np.int64)
        self._read_observations()
        return self.get_observations()

    def _read_observations(self, buf: dict[str, np.ndarray] | None = None) -> None:
        """Take the observations (and critic inputs) from ``buf`` (default: the step buffers)."""
        buf = self._buf if buf is None else buf
        self._obs = torch.from_numpy(buf["obs"].copy()).to(self.device)
        if self.critic_dim:
            self._critic = torch.from_numpy(buf["critic"].copy()).to(self.device)

    def get_observations(self) -> TensorDict:
        """Current observations as ``TensorDict(policy=(N, obs_dim))``, plus ``critic=(N, critic_dim)``
        when the environments report privileged critic inputs (``critic_dim`` > 0); never resets."""
        groups = {"policy": self._obs.clone()}
        if self.critic_dim:
            groups["critic"] = self._critic.clone()
        return TensorDict(groups, batch_size=[self.num_envs], device=self.device)

    def dispatch(self, actions: torch.Tensor) -> None:
        """Start a step: the worker processes step their blocks with ``actions`` while this returns.

        :meth:`step` with the same actions then steps this process's own block and collects the
        results, exactly those of :meth:`step` alone. In between, the caller may do its own work
        (PPO's value estimates and storage: :class:`mjnav.train.ppo.PipelinedPPO`) while the
        worker processes step, instead of before they start. Without worker processes it only
        checks and stores the actions.

        Args:
            actions: Raw policy outputs, shape (N, num_actions).

        Raises:
            ValueError: Actions of the wrong shape or with NaN/inf (nothing is started).
            RuntimeError: A step is already dispatched (call :meth:`step` first).
            EnvError: A worker died; the adapter is closed.
        """
        self._check_idle("dispatch")
        self._start_step(actions)

    def _start_step(self, actions: torch.Tensor) -> None:
        """Check and write the actions and the forced truncations, send the step to the worker processes."""
        values = self._checked_actions(actions)
        lengths = self.episode_length_buf.cpu().numpy() + 1
        self._buf["actions"][:] = values
        self._buf["force"][:] = lengths >= self.max_episode_length
        self._send("step")
        self._pending = lengths

    def _check_open(self, call: str) -> None:
        if self._closed:
            raise RuntimeError(f"{call}() on a closed adapter (by close(), or after a failed step or worker)")

    def _check_idle(self, call: str) -> None:
        self._check_open(call)
        if self._pending is not None:
            raise RuntimeError(f"{call}() while a dispatched step is running: call step() with its actions first")
        if self._replay is not None and call != "reset":
            raise RuntimeError(f"{call}() while a rollout is being served: step() through its "
                               f"{self._replay.steps - self._replay.served} remaining steps first")

    def step(self, actions: torch.Tensor) -> tuple[TensorDict, torch.Tensor, torch.Tensor, dict]:
        """Step every environment; finished ones are reset and report the new episode's observation.

        Finishes the step :meth:`dispatch` started, when it was called with these actions.

        Args:
            actions: Raw policy outputs, shape (N, num_actions).

        Returns:
            Observations, rewards (N,) float32, dones (N,) long, extras with ``time_outs`` (N,) bool,
            ``outcomes`` (N,) int8 and ``log``.

        Raises:
            ValueError: Actions of the wrong shape or with NaN/inf (the envs are not stepped), or
                not those of the dispatched step (the adapter is closed: its worker processes
                already stepped with the dispatched ones).
            EnvError: An environment raised or a worker died; the adapter is closed.
        """
        start = time.perf_counter()
        self._check_open("step")
        if self._replay is not None:
            return self._serve(actions, start)
        if self._pending is None:
            self._start_step(actions)
        elif not _same(actions, self._buf["actions"]):
            # the dispatched actions were checked (shape, finite) before they went out
            self.close()
            raise ValueError("step() got other actions than dispatch(): the worker processes stepped with "
                             "the dispatched ones, so the adapter is closed")
        lengths = self._pending
        self._pending = None
        sent = time.perf_counter()
        replies = self._finish("step")
        received = time.perf_counter()
        self._read_observations()
        read = time.perf_counter()
        return self._results(self._buf, lengths, replies, start, (sent - start) + (read - received))

    def _results(
        self, buf: dict[str, np.ndarray], lengths: np.ndarray, replies: list[tuple], start: float, transfer: float
    ) -> tuple[TensorDict, torch.Tensor, torch.Tensor, dict]:
        """A step's return value from its results in ``buf`` (observations already read): the
        episode clock, the logs and the tensors; ``transfer`` is the time spent so far moving data."""
        rewards, outcome = buf["rewards"].copy(), buf["outcome"].copy()
        terminated, truncated = buf["terminated"].copy(), buf["truncated"].copy()
        done = terminated | truncated
        self._returns += rewards
        self._steps += 1
        log = self._log(done, outcome, replies)
        self._returns[done], self._steps[done] = 0.0, 0
        self.episode_length_buf = torch.from_numpy(np.where(done, 0, lengths)).to(self.device)
        packed = time.perf_counter()
        extras = {
            "time_outs": torch.from_numpy(truncated).to(self.device),
            "outcomes": torch.from_numpy(outcome).to(self.device),
            "log": log,
        }
        dones = torch.from_numpy(done.astype(np.int64)).to(self.device)
        result = self.get_observations(), torch.from_numpy(rewards).to(self.device), dones, extras
        end = time.perf_counter()
        self._log_times(log, replies, start, end, transfer + (end - packed))
        return result

    def rollout(self, policy: RolloutPolicy, steps: int, aux_dim: int = 0) -> None:
        """Run the next ``steps`` steps at once, each worker choosing its environments' actions
        with ``policy``; the following ``steps`` calls of :meth:`step` then return them in order.

        Every worker (this process included) runs its block through all ``steps`` steps without
        waiting for the others at each step, as it would be stepped by :meth:`step` with the
        actions ``policy`` gives (auto-resets and forced truncations included), and records them;
        it runs the block in parts of at most ``rollout_envs`` environments, one after another
        (:attr:`rollout_blocks`: ``policy`` is called for one part at a time).
        :meth:`recorded` gives the actions of the next step to serve (and ``aux``, the policy's
        other outputs); :meth:`step` with them returns what :meth:`step` alone would have (the
        logged sums of reward terms and MPC statistics to rounding when blocks run in parts).
        A worker may take ``step_timeout_s`` per step.

        Args:
            policy: Picklable ``policy(t, indices, obs, critic) -> (actions, aux)``
                (:data:`mjnav.envs.workers.RolloutPolicy`); it is sent to every worker process.
            steps: Steps to run (>= 1).
            aux_dim: Length of each environment's ``aux`` row.

        Raises:
            ValueError: ``steps`` < 1 or the record does not fit in shared memory (:meth:`can_record`;
                nothing is started), or the policy gave non-finite actions (the adapter is then
                closed: the other workers stepped on).
            RuntimeError: A step is dispatched or a rollout is still being served.
            EnvError: An environment or the policy raised, the policy gave outputs of another
                shape, or a worker died; the adapter is closed.
        """
        self._check_idle("rollout")
        if steps < 1:
            raise ValueError(f"steps must be >= 1, got {steps}")
        self._ensure_record(steps, aux_dim)
        lengths = self.episode_length_buf.cpu().numpy().copy()
        arg = (policy, steps, lengths, self.max_episode_length, self.rollout_envs)
        start = time.perf_counter()
        self._send("rollout", arg)
        replies = self._finish("rollout", arg, timeout=self.step_timeout_s * steps)
        seconds = time.perf_counter() - start
        bad = [failed for _, failed in replies if failed is not None]
        if bad:
            self.close()
            t, envs = min(bad)
            raise ValueError(f"non-finite actions (NaN/inf) at rollout step {t} for envs {envs[:16]}: the "
                             "policy diverged; the adapter is closed (the other workers stepped on)")
        steps_replies = [list(step) for step in zip(*(r for r, _ in replies), strict=True)]
        own = [step[-1] for step in steps_replies] if self._steps_own_block else []
        waited = seconds - sum(reply[3] + reply[5] for reply in own)  # for the worker processes, at the end
        self._replay = _Replay(steps, steps_replies, max(waited, 0.0) / steps)

    @property
    def _steps_own_block(self) -> bool:
        """Whether this process steps a block itself (its handle comes last; its reply too)."""
        return self._remote < len(self._handles)

    @property
    def rollout_blocks(self) -> list[range]:
        """The environments for which :meth:`rollout` calls its policy together: each worker's block
        in parts of at most ``rollout_envs``."""
        return [part for block in self.blocks for part in rollout_parts(block, self.rollout_envs)]

    @property
    def replaying(self) -> bool:
        """Whether a rollout (:meth:`rollout`) is being served by :meth:`step`."""
        return self._replay is not None

    def recorded(self) -> tuple[torch.Tensor, torch.Tensor]:
        """The actions (N, num_actions) and ``aux`` (N, aux_dim) of the rollout's next step.

        Raises:
            RuntimeError: No rollout is being served.
        """
        if self._replay is None:
            raise RuntimeError("recorded() without a rollout being served (call rollout() first)")
        rec, t = self._record[1], self._replay.served
        return (torch.from_numpy(rec["actions"][t].copy()).to(self.device),
                torch.from_numpy(rec["aux"][t].copy()).to(self.device))

    def _serve(self, actions: torch.Tensor, start: float) -> tuple[TensorDict, torch.Tensor, torch.Tensor, dict]:
        """:meth:`step` while a rollout is served: its next recorded step, for its actions only."""
        replay, rec = self._replay, self._record[1]
        t = replay.served
        if not _same(actions, rec["actions"][t]):
            self.close()
            raise ValueError(f"step() got other actions than the rollout's step {t}: the workers stepped with "
                             "the policy's, so the adapter is closed")
        replay.served += 1
        if replay.served == replay.steps:
            self._replay = None
        step = {name: rec[name][t] for name in _RESULTS}
        self._read_observations(step)
        own = replay.replies[t][-1] if self._steps_own_block else None
        self._split = (0.0 if own is None else own[3], replay.wait_s)
        lengths = self.episode_length_buf.cpu().numpy() + 1
        result = self._results(step, lengths, replay.replies[t], start, time.perf_counter() - start)
        log = result[3]["log"]
        log["perf/env_step_ms"] += 1e3 * sum(self._split)  # the step's share of the rollout
        log["perf/rollout_policy_ms"] = 0.0 if own is None else 1e3 * own[5]
        return result

    def can_record(self, steps: int, aux_dim: int = 0) -> bool:
        """Whether a :meth:`rollout` of ``steps`` steps fits: its record, in shared memory with worker
        processes, needs at most the free space of ``/dev/shm`` (containers often give it 64 MB)."""
        shape = self._record_shape(steps, aux_dim)
        if not self._remote or self._record[2] == shape or not os.path.isdir("/dev/shm"):
            return True
        stat = os.statvfs("/dev/shm")
        return _record_layout(*shape)[1] <= stat.f_bavail * stat.f_frsize

    def _record_shape(self, steps: int, aux_dim: int) -> tuple[int, ...]:
        return steps, self.num_envs, self.observation_space.shape[0], self.num_actions, self.critic_dim, aux_dim

    def _ensure_record(self, steps: int, aux_dim: int) -> None:
        """A shared record for ``steps`` steps, mapped by every worker (a new one when the size changed).

        Raises:
            ValueError: It does not fit in ``/dev/shm`` (:meth:`can_record`); nothing changed.
        """
        shape = self._record_shape(steps, aux_dim)
        if self._record[2] == shape:
            return
        if not self.can_record(steps, aux_dim):
            raise ValueError(f"a rollout of {steps} steps needs {_record_layout(*shape)[1] / 2**20:.0f} MB of "
                             "shared memory, more than /dev/shm has free")
        layout, nbytes = _record_layout(*shape)
        if self._remote:
            segment = SharedMemory(create=True, size=nbytes)
            views = _views(segment.buf, layout)
        else:
            segment, views = None, _views(bytearray(nbytes), layout)
        old = self._record[0]
        self._record = (segment, views, shape)
        try:
            for handle in self._handles:
                handle.request("record", views if isinstance(handle, _LocalHandle) else (segment.name, layout))
            for handle in self._handles:
                handle.result(self.step_timeout_s)
        except BaseException:
            self.close()
            raise
        finally:
            if segment is not None:
                segment.unlink()  # mapped by every worker (or failed): the name goes
        if old is not None:
            old.close()

    def _log_times(self, log: dict[str, Any], replies: list[tuple], start: float, end: float, transfer: float) -> None:
        """The ``perf/*`` entries of one step (module docstring), in milliseconds; a rollout's worker
        processes are busy with their policy calls too (replies' wall and CPU seconds 5 and 6)."""
        busy = [reply[3] + sum(reply[5:6]) for reply in replies[: self._remote]]
        log["perf/env_step_ms"] = 1e3 * (end - start)
        log["perf/own_block_ms"], log["perf/wait_ms"] = 1e3 * self._split[0], 1e3 * self._split[1]
        log["perf/transfer_ms"] = 1e3 * transfer  # with the send, when this call sent the step
        log["perf/worker_step_ms"] = 1e3 * sum(busy) / len(busy) if busy else 0.0
        log["perf/worker_step_max_ms"] = 1e3 * max(busy, default=0.0)
        log["perf/worker_cpu_max_ms"] = 1e3 * max((reply[4] + sum(reply[6:7]) for reply in replies[: self._remote]),
                                                   default=0.0)

    def _checked_actions(self, actions: torch.Tensor) -> np.ndarray:
        """``actions`` as float32 numpy (N, num_actions); ValueError for a wrong shape or NaN/inf."""
        values = actions.detach().to("cpu", torch.float32).numpy()
        if values.shape != (self.num_envs, self.num_actions):
            raise ValueError(
                f"actions must have shape ({self.num_envs}, {self.num_actions}), got {values.shape}"
            )
        finite = np.isfinite(values).all(axis=1)
        if not finite.all():
            bad = np.flatnonzero(~finite).tolist()
            raise ValueError(f"non-finite actions (NaN/inf) for envs {bad[:16]}: the policy diverged")
        return values

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
        for reply_terms, reply_sum, reply_count, *_ in replies:
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
        self._pending = None
        for handle in self._handles:
            with contextlib.suppress(Exception):
                handle.close()
        self._buf, self._replay = {}, None
        segment, self._record = self._record[0], (None, {}, ())
        if segment is not None:
            segment.close()
        if self._shm is not None:
            self._shm.close()
            if self._shm_named:  # closed before every worker had mapped it
                self._shm.unlink()
            self._shm = None

    def __enter__(self) -> NavVecEnv:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()

    def __del__(self) -> None:
        self.close()
