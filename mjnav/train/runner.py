"""Build rsl-rl's (unmodified) :class:`~rsl_rl.runners.OnPolicyRunner` from a :class:`TrainConfig`.

rsl-rl 5 specifics used here:

* observation groups: the adapter returns ``TensorDict(policy=...)``; ``obs_groups`` maps both the
  ``actor`` and ``critic`` sets to ``["policy"]``.
* models: ``actor``/``critic`` dicts name a class; :class:`~mjnav.train.model.LayerwiseMLPModel`
  adds per-layer activations (ReLU, ReLU, Hardswish). The actor's ``GaussianDistribution`` uses
  ``std_type="log"`` with ``init_std = exp(init_log_std)``: a learnable, state-independent log-std.
* optimizer: ``algorithm.optimizer = "adamw"`` (rsl-rl resolves adam/adamw/sgd/rmsprop);
  ``schedule = "fixed"`` keeps the authors' constant learning rate.
* logging: ``logger`` names :class:`ProgressWriter`, a rsl-rl ``LogWriter`` that writes TensorBoard
  events and prints one progress line per iteration; rsl-rl's own per-iteration block is
  filtered from stdout unless ``verbose``.
* iteration count: inside ``learn`` rsl-rl keeps ``current_learning_iteration`` at the last
  *completed* iteration (what checkpoints store as ``iter``) and starts the next ``learn`` there,
  repeating one number. Here, between calls, it is the *next* iteration: :func:`learn`,
  :func:`load_checkpoint` and :func:`save_checkpoint` convert, so chunks and resumed runs number
  their iterations without repeats.
"""

from __future__ import annotations

import contextlib
import dataclasses
import functools
import math
import os
import re
import signal
import sys
import time
from collections.abc import Iterator
from pathlib import Path
from typing import TYPE_CHECKING, Any, TextIO

import gymnasium as gym
import torch
from rsl_rl.runners import OnPolicyRunner
from rsl_rl.utils.log_writer import LogWriter
from torch.utils.tensorboard import SummaryWriter

from mjnav.envs.gym_env import make_gym_env
from mjnav.envs.vec_env import EnvError, NavVecEnv
from mjnav.train import distributed
from mjnav.train.config import TrainConfig
from mjnav.train.ppo import PipelinedPPO

if TYPE_CHECKING:
    from mjnav.config import TaskConfig

__all__ = [
    "ProgressWriter",
    "TaskEnvFactory",
    "TrainingInterrupted",
    "build_runner",
    "checkpoints",
    "handle_interrupts",
    "learn",
    "load_checkpoint",
    "make_vec_env",
    "request_stop",
    "rsl_config",
    "save_checkpoint",
    "save_weights",
    "widen_columns",
    "widen_inputs",
]

#: The weights-only checkpoint every run writes at the end (actor with its std, critic; no optimizer state).
WEIGHTS_FILE = "checkpoint_weights.pt"


class TrainingInterrupted(Exception):
    """Raised at the end of an iteration after SIGINT/SIGTERM; the caller saves and exits.

    Attributes:
        iteration: The last completed iteration.
    """

    def __init__(self, iteration: int) -> None:
        """Record the last completed iteration."""
        super().__init__(f"stopped after iteration {iteration}")
        self.iteration = iteration


#: ``requested``: this process was asked to stop (a signal, :func:`request_stop`). ``agreed``: under
#: torchrun, whether any rank had asked at the last update's all-reduce (:func:`_agree_on_stops`);
#: None otherwise. A request that arrives after the all-reduce waits for the next one, so no rank
#: stops alone and leaves the others blocked in their next all-reduce.
_STOP: dict[str, bool | None] = {"requested": False, "agreed": None}


def _stop_now() -> bool:
    """Whether to stop after this iteration: the ranks' agreed flag under torchrun, else the request."""
    agreed = _STOP["agreed"]
    return bool(_STOP["requested"]) if agreed is None else agreed


@dataclasses.dataclass(frozen=True)
class TaskEnvFactory:
    """Picklable ``env_fn(index)`` building the gymnasium env of a task (seeded by the adapter)."""

    task: TaskConfig

    def __call__(self, index: int) -> gym.Env:
        """Build environment ``index`` (unseeded: the adapter resets it with ``seed + index``)."""
        return make_gym_env(self.task)


def make_vec_env(
    task: TaskConfig, train: TrainConfig, seed: int | None = None, num_envs: int | None = None
) -> NavVecEnv:
    """The rsl-rl adapter over ``num_envs`` (default ``train.num_envs``) environments of ``task``.

    Without ``seed`` the environments start from this rank's seed (:func:`distributed.rank_seed`:
    ``train.seed`` in one process); ``train.workers=-1`` gives one worker per core of the rank.
    """
    ranks = distributed.current()
    count = num_envs or train.num_envs
    workers = min(train.workers, count) if train.workers >= 0 else None
    if workers is None and ranks.distributed:
        workers = min(count, distributed.rank_cores(ranks))
    return NavVecEnv(
        TaskEnvFactory(task),
        num_envs=count,
        seed=distributed.rank_seed(train.seed, train.num_envs, ranks) if seed is None else seed,
        workers=workers,
        device=train.device,
        max_episode_length=task.timing.episode_steps,
        start_method=train.start_method,
        main_envs=train.main_envs if train.main_envs >= 0 else None,
        rollout_envs=train.rollout_envs,
        cfg={"task": task.name},
    )


def rsl_config(train: TrainConfig, label: str = "", privileged_critic: bool = False) -> dict[str, Any]:
    """The ``OnPolicyRunner`` configuration dictionary of ``train``; with ``privileged_critic`` the
    critic reads the adapter's ``critic`` group after the actor's ``policy`` group."""
    policy = train.policy
    return {
        "num_steps_per_env": train.steps_per_env,
        "save_interval": train.save_interval,
        "obs_groups": {"actor": ["policy"], "critic": ["policy", "critic"] if privileged_critic else ["policy"]},
        "check_for_nan": True,
        "run_name": label,
        "logger": {
            "class_name": "mjnav.train.runner:ProgressWriter",
            "label": label,
            "total_iterations": train.iterations,
            "steps_per_env": train.steps_per_env,
        },
        "algorithm": {
            "class_name": "mjnav.train.ppo:PipelinedPPO" if train.pipeline else "PPO",
            **({"worker_rollouts": train.rollouts} if train.pipeline else {}),
            "num_learning_epochs": train.epochs,
            "num_mini_batches": train.minibatches,
            "clip_param": train.clip,
            "gamma": train.gamma,
            "lam": train.lam,
            "value_loss_coef": train.value_loss_coef,
            "entropy_coef": train.entropy,
            "learning_rate": train.learning_rate,
            "max_grad_norm": train.max_grad_norm,
            "optimizer": train.optimizer,
            "use_clipped_value_loss": train.value_clip,
            "schedule": train.schedule,
            "desired_kl": train.desired_kl,
        },
        "actor": {
            "class_name": "mjnav.train.model:LayerwiseMLPModel",
            "hidden_dims": list(policy.actor_hidden_dims),
            "activation": list(policy.actor_activations),
            "obs_normalization": policy.obs_normalization,
            "output_gain": policy.actor_output_gain,
            "distribution_cfg": {
                "class_name": "GaussianDistribution",
                "init_std": math.exp(policy.init_log_std),
                "std_type": "log",
            },
        },
        "critic": {
            "class_name": "mjnav.train.model:LayerwiseMLPModel",
            "hidden_dims": list(policy.critic_hidden_dims),
            "activation": list(policy.critic_activations),
            "obs_normalization": policy.obs_normalization,
        },
    }


def build_runner(
    env: NavVecEnv, train: TrainConfig, log_dir: str | Path | None, label: str = ""
) -> OnPolicyRunner:
    """Seed torch and construct the runner (networks, PPO, storage, logger) on ``train.device``.

    Under torchrun (an open process group, :mod:`mjnav.train.distributed`) it is this rank's runner:
    torch seeded with the rank's seed, gradients averaged over the ranks, ``log_dir`` used by rank 0
    only, and a stop requested on any rank honoured by all after the same iteration.
    """
    ranks = distributed.current()
    torch.manual_seed(distributed.rank_seed(train.seed, train.num_envs, ranks))
    if train.torch_threads > 0:
        torch.set_num_threads(train.torch_threads)
    with contextlib.redirect_stdout(_ModelPrintFilter(sys.stdout, train.verbose)):
        runner = distributed.DistributedRunner(
            env,
            rsl_config(train, label, privileged_critic=getattr(env, "critic_dim", 0) > 0),
            None if log_dir is None else str(log_dir),
            train.device,
        )
    runner.add_git_repo_to_log(str(Path(__file__).resolve()))  # git diff of mjnav into <run>/git/
    if isinstance(runner.alg, PipelinedPPO):  # the logger's per-step work also overlaps the workers
        runner.logger.process_env_step = runner.alg.deferring(runner.logger.process_env_step)
    _thread_the_update(runner, train.update_threads or distributed.rank_cores(ranks))
    _warm_up_critic(runner, train.critic_warmup)
    _count_updates(runner)
    if ranks.distributed:
        _agree_on_stops(runner, ranks)
    _atomic_saves(runner)
    runner.mjnav_verbose = train.verbose  # type: ignore[attr-defined]
    return runner


def _atomic_saves(runner: OnPolicyRunner) -> None:
    """Make every checkpoint write atomic: rsl-rl writes ``<path>.<pid>.partial``, which then replaces
    ``<path>`` in one rename, so a run killed mid-write (SIGKILL, power) leaves the previous
    checkpoints intact and never a truncated ``model_<it>.pt`` (:func:`checkpoints` ignores the
    ``.partial`` file). Wraps ``runner.save`` on the instance, as for the update."""
    save = runner.save

    @functools.wraps(save)
    def atomic_save(path: str, *args: Any, **kwargs: Any) -> None:
        partial = f"{path}.{os.getpid()}.partial"  # two ranks saving at once write apart
        save(partial, *args, **kwargs)
        os.replace(partial, path)

    runner.save = atomic_save


def _thread_the_update(runner: OnPolicyRunner, threads: int) -> None:
    """Run each PPO update with ``threads`` intra-op threads, collection with the current count.

    The env workers wait while the trainer updates, so the update can use every core; during
    collection extra torch threads would spin against the workers. Wraps the runner's
    ``alg.update`` on the instance (rsl-rl itself is not modified).
    """
    update = runner.alg.update

    @functools.wraps(update)
    def threaded_update(*args: Any, **kwargs: Any) -> Any:
        collecting = torch.get_num_threads()
        torch.set_num_threads(threads)
        try:
            return update(*args, **kwargs)
        finally:
            torch.set_num_threads(collecting)

    runner.alg.update = threaded_update


def _warm_up_critic(runner: OnPolicyRunner, iterations: int) -> None:
    """Freeze the actor (weights and log-std) in the updates of iterations ``0 .. iterations-1``.

    With ``requires_grad`` off the actor's parameters get no gradient, and the optimiser skips
    parameters without one, so only the critic moves; the surrogate and entropy terms are then
    constants of the loss. Reads the number of the iteration from :func:`_count_updates`. Wraps
    the runner's ``alg.update`` on the instance, as :func:`_thread_the_update` does.
    """
    if iterations <= 0:
        return
    update = runner.alg.update

    @functools.wraps(update)
    def update_with_warmup(*args: Any, **kwargs: Any) -> Any:
        iteration = runner.mjnav_iteration
        if iteration >= iterations:
            return update(*args, **kwargs)
        actor = list(runner.alg.actor.parameters())
        for p in actor:
            p.requires_grad_(False)
        try:
            return update(*args, **kwargs)
        finally:
            for p in actor:
                p.requires_grad_(True)

    runner.alg.update = update_with_warmup


def _count_updates(runner: OnPolicyRunner) -> None:
    """Keep ``runner.mjnav_iteration``, the number of the iteration whose update comes next: one more
    after each update that ends (:func:`learn` sets it at each call). rsl-rl's own counter does not
    tell "no iteration done in this call" from "the first one done". Wraps ``alg.update``."""
    runner.mjnav_iteration = 0  # type: ignore[attr-defined]
    update = runner.alg.update

    @functools.wraps(update)
    def counted_update(*args: Any, **kwargs: Any) -> Any:
        result = update(*args, **kwargs)
        runner.mjnav_iteration += 1  # type: ignore[attr-defined]
        return result

    runner.alg.update = counted_update


def _agree_on_stops(runner: OnPolicyRunner, ranks: distributed.Ranks) -> None:
    """Make every rank stop after the same iteration when any rank was asked to stop.

    After each update the ranks share their stop flags (one all-reduce, ``_STOP["agreed"]``); rank
    0's :class:`ProgressWriter` then raises :class:`TrainingInterrupted` after logging, and the other
    ranks, which log nothing, raise it from the logger's ``log``. Both read the agreed flag, not the
    rank's own request, which a signal may set after the all-reduce. Wraps both on the instance.
    """
    update, log = runner.alg.update, runner.logger.log

    @functools.wraps(update)
    def update_then_agree(*args: Any, **kwargs: Any) -> Any:
        result = update(*args, **kwargs)
        _STOP["agreed"] = distributed.any_rank(bool(_STOP["requested"]), runner.device)
        return result

    @functools.wraps(log)
    def log_then_stop(*args: Any, it: int, **kwargs: Any) -> None:
        log(*args, it=it, **kwargs)
        if _stop_now():
            raise TrainingInterrupted(it)

    runner.alg.update = update_then_agree
    if not ranks.main:
        runner.logger.log = log_then_stop


def learn(runner: OnPolicyRunner, iterations: int, random_initial_lengths: bool = False) -> None:
    """Run ``iterations`` PPO iterations, numbered on from ``runner.current_learning_iteration``.

    Raises:
        TrainingInterrupted: A stop was requested (see :func:`handle_interrupts`) and honoured after
            a completed iteration; the weights are not saved yet (:func:`save_checkpoint`).
        EnvError: An environment or its worker failed; ``current_learning_iteration`` is then the
            iteration after the last completed one, so :func:`save_checkpoint` can keep its weights.
    """
    runner.logger.cfg["logger"]["start_iteration"] = runner.current_learning_iteration
    runner.mjnav_iteration = runner.current_learning_iteration  # type: ignore[attr-defined]
    if isinstance(runner.alg, PipelinedPPO):
        runner.alg.connect(runner.env)  # this chunk's environment: the curriculum swaps it between stages
    try:
        with contextlib.redirect_stdout(_BlockFilter(sys.stdout, getattr(runner, "mjnav_verbose", False))):
            runner.learn(iterations, init_at_random_ep_len=random_initial_lengths)
    except TrainingInterrupted as stop:
        runner.current_learning_iteration = stop.iteration + 1
        raise
    except EnvError:
        runner.current_learning_iteration = runner.mjnav_iteration  # type: ignore[attr-defined]
        raise
    runner.current_learning_iteration += 1


def checkpoints(run_dir: str | Path) -> list[Path]:
    """``model_<iteration>.pt`` files of a run, oldest first."""
    found = [
        (int(m.group(1)), p)
        for p in Path(run_dir).glob("model_*.pt")
        if (m := re.fullmatch(r"model_(\d+)\.pt", p.name))
    ]
    return [p for _, p in sorted(found)]


def load_checkpoint(runner: OnPolicyRunner, path: str | Path, weights_only: bool = False) -> bool:
    """Load a checkpoint: everything (resume: iteration counting continues) or only the networks.

    Args:
        runner: The runner to load into.
        path: A ``model_<it>.pt`` checkpoint.
        weights_only: Load actor and critic weights only (``init=``: start a new stage from them).
            An actor trained on a shorter observation (``observation.tracks=K`` added) is widened
            first (:func:`widen_inputs`: it acts exactly as before). A critic whose shapes still
            differ from the runner's (another critic input, e.g.
            ``observation.critic_pedestrians``) is not loaded: the run keeps its fresh critic.

    Returns:
        Whether the critic was loaded (always True without ``weights_only``).
    """
    if weights_only:
        saved = torch.load(str(path), map_location=runner.device, weights_only=False)
        own = getattr(runner.alg, "_raw_critic", runner.alg.critic).state_dict()
        saved = widen_inputs(saved, getattr(runner.alg, "_raw_actor", runner.alg.actor).state_dict(), own)
        shapes = {k: tuple(v.shape) for k, v in saved.get("critic_state_dict", {}).items()}
        critic = shapes == {k: tuple(v.shape) for k, v in own.items()}
        runner.alg.load(saved, {"actor": True, "critic": critic}, strict=True)  # what runner.load does, read once
        return critic
    runner.load(str(path), map_location=runner.device)
    runner.current_learning_iteration += 1
    return True


def widen_inputs(saved: dict[str, Any], actor: dict[str, Any], critic: dict[str, Any]) -> dict[str, Any]:
    """A checkpoint whose networks take a longer observation, acting exactly as ``saved`` does.

    When the runner's actor reads ``n`` more values than ``saved``'s (new inputs appended to the
    actor's observation, e.g. ``observation.tracks=K``: the old values keep their places), the
    first layer gets ``n`` zero weight columns at the end and an observation normaliser mean 0 /
    std 1 for them, so the outputs ignore the new values until training moves those columns. The
    critic is widened alike, its new columns inserted after the old actor's inputs (where the
    actor's group ends in the critic's input), when it too reads exactly ``n`` more values.

    Args:
        saved: An rsl-rl checkpoint (``actor_state_dict``, ``critic_state_dict``, ...).
        actor: The runner's actor ``state_dict`` (the shapes wanted).
        critic: The runner's critic ``state_dict``.

    Returns:
        ``saved`` itself when the actor's input widths match (or nothing can be widened), else a
        copy with the widened state dicts.
    """
    first = "mlp.0.weight"
    old_actor = saved.get("actor_state_dict", {})
    if first not in old_actor or first not in actor:
        return saved
    width = old_actor[first].shape[1]
    extra = actor[first].shape[1] - width
    if extra <= 0:
        return saved
    out = {**saved, "actor_state_dict": widen_columns(old_actor, width, extra)}
    old_critic = saved.get("critic_state_dict", {})
    if first in old_critic and first in critic and critic[first].shape[1] - old_critic[first].shape[1] == extra:
        out["critic_state_dict"] = widen_columns(old_critic, width, extra)
    return out


def widen_columns(state: dict[str, Any], at: int, extra: int) -> dict[str, Any]:
    """An rsl-rl actor or critic ``state`` dict with ``extra`` inputs inserted at column ``at``:
    zero first-layer weights and, with an observation normaliser, mean 0 and variance and std 1 for
    them (a copy; the other tensors are shared)."""
    def insert(tensor: torch.Tensor, fill: float, dim: int) -> torch.Tensor:
        shape = list(tensor.shape)
        shape[dim] = extra
        pad = torch.full(shape, fill, dtype=tensor.dtype, device=tensor.device)
        head, tail = tensor.split([at, tensor.shape[dim] - at], dim=dim)
        return torch.cat([head, pad, tail], dim=dim)

    out = dict(state)
    out["mlp.0.weight"] = insert(state["mlp.0.weight"], 0.0, 1)
    for key, fill in (("obs_normalizer._mean", 0.0), ("obs_normalizer._var", 1.0), ("obs_normalizer._std", 1.0)):
        if key in state:
            out[key] = insert(state[key], fill, state[key].ndim - 1)
    return out


def save_checkpoint(runner: OnPolicyRunner, run_dir: str | Path, this_rank: bool = False) -> Path:
    """Save ``model_<last completed iteration>.pt`` into ``run_dir`` (between :func:`learn` calls);
    under torchrun rank 0 saves and the other ranks only return the path, unless ``this_rank``
    (a rank that failed alone: the ranks hold the same weights after every update)."""
    last = runner.current_learning_iteration - 1
    path = Path(run_dir) / f"model_{last}.pt"
    if not (this_rank or distributed.current().main):
        return path
    runner.current_learning_iteration = last  # checkpoints store the last completed iteration
    try:
        runner.save(str(path))
    finally:
        runner.current_learning_iteration = last + 1
    return path


def save_weights(runner: OnPolicyRunner, run_dir: str | Path) -> Path:
    """Save :data:`WEIGHTS_FILE` into ``run_dir``: the actor (its std included) and critic weights of
    the last completed iteration, ~2.3 MB against ~5-7 MB with the optimizer state; ``init=`` and a
    shipped policy's ``weights`` take it."""
    saved = runner.alg.save()
    path = Path(run_dir) / WEIGHTS_FILE
    torch.save({"actor_state_dict": saved["actor_state_dict"], "critic_state_dict": saved["critic_state_dict"],
                "iter": runner.current_learning_iteration - 1}, path)
    return path


@contextlib.contextmanager
def handle_interrupts() -> Iterator[None]:
    """SIGINT/SIGTERM request a stop after the current iteration; a second Ctrl-C aborts at once."""

    def on_signal(signum: int, frame: Any) -> None:
        if _STOP["requested"] and signum == signal.SIGINT:
            raise KeyboardInterrupt
        _STOP["requested"] = True
        print(
            f"\n{signal.Signals(signum).name}: finishing this iteration and saving a checkpoint "
            "(Ctrl-C again aborts without saving)",
            file=sys.stderr,
            flush=True,
        )

    previous = {s: signal.signal(s, on_signal) for s in (signal.SIGINT, signal.SIGTERM)}
    _STOP.update(requested=False, agreed=None)
    try:
        yield
    finally:
        for sig, handler in previous.items():
            signal.signal(sig, handler)
        _STOP.update(requested=False, agreed=None)


def request_stop() -> None:
    """Ask the running :func:`learn` to stop after its current iteration (as SIGTERM does)."""
    _STOP["requested"] = True


class ProgressWriter(LogWriter):
    """rsl-rl log writer: TensorBoard events plus one progress line per iteration.

    The line shows env steps/s, collection time (of which stepping the environments), update time,
    the success rate and mean return of the episodes finished in the iteration, and the ETA.
    """

    def __init__(
        self,
        log_dir: str,
        label: str = "",
        total_iterations: int = 0,
        steps_per_env: int = 1,
        start_iteration: int = 0,
    ) -> None:
        """Open the TensorBoard writer in ``log_dir``."""
        self.tb = SummaryWriter(log_dir=log_dir, flush_secs=10)
        self.label, self.total, self.steps_per_env = label, total_iterations, steps_per_env
        self.start = start_iteration
        self.values: dict[str, float] = {}
        self.elapsed = 0.0

    def add_scalar(self, tag: str, scalar_value: float, global_step: int) -> None:
        """Write the scalar; after the last per-iteration timing, print the line and honour stops."""
        self.tb.add_scalar(tag, scalar_value, global_step)
        self.values[tag] = float(scalar_value)
        if tag == "Perf/learning_time":
            print(self.line(global_step), flush=True)
            self.values = {}
            if _stop_now():
                raise TrainingInterrupted(global_step)

    def line(self, it: int) -> str:
        """The progress line of iteration ``it``."""
        v = self.values
        collect, update = v.get("Perf/collection_time", 0.0), v.get("Perf/learning_time", 0.0)
        self.elapsed += collect + update
        done = max(1, it + 1 - self.start)
        eta = self.elapsed / done * max(0, self.total - it - 1)
        env = v.get("perf/env_step_ms", 0.0) * self.steps_per_env / 1e3
        success = f"{v['episode/success']:.2f}" if "episode/success" in v else "  - "
        ret = f"{v['episode/return']:7.1f}" if "episode/return" in v else "      -"
        head = f"[{self.label}] " if self.label else ""
        eta_text = time.strftime("%H:%M:%S", time.gmtime(eta)) if eta < 86400 else f"{eta / 3600:.0f}h"
        return (
            f"{head}it {it + 1}/{self.total} | {v.get('Perf/total_fps', 0):5.0f} steps/s"
            f" | collect {collect:5.2f}s (env {env:5.2f}s) | update {update:5.2f}s"
            f" | success {success} | return {ret} | ETA {eta_text}"
        )

    def stop(self) -> None:
        """Flush and close the TensorBoard writer."""
        self.tb.close()


class _BlockFilter:
    """stdout proxy dropping rsl-rl's multi-line per-iteration block (unless ``verbose``)."""

    def __init__(self, stream: TextIO, verbose: bool) -> None:
        self.stream, self.verbose, self._skip_newline = stream, verbose, False

    def write(self, text: str) -> int:
        if not self.verbose and text.startswith(("#" * 20, "Synchronizing parameters")):
            self._skip_newline = True
            return len(text)
        if self._skip_newline and text == "\n":
            self._skip_newline = False
            return 1
        self._skip_newline = False
        return self.stream.write(text)

    def flush(self) -> None:
        self.stream.flush()

    def __getattr__(self, name: str) -> Any:
        return getattr(self.stream, name)


class _ModelPrintFilter(_BlockFilter):
    """stdout proxy dropping rsl-rl's model printout at construction (unless ``verbose``)."""

    def write(self, text: str) -> int:
        if not self.verbose and text.startswith(("Actor Model:", "Critic Model:")):
            self._skip_newline = True
            return len(text)
        return super().write(text)
