"""Typed, frozen PPO training config (kept apart from the task config).

Defaults follow spec §8 (the authors' PPO values) where they are hardware independent and are
scaled down for a 2-core CPU where they are not:

* rollout: 64 envs x 256 steps = 16,384 transitions per iteration (authors: ~115k). Until
  2026-12-02 it was 64 x 64 = 4,096, which trained stage 2 under the contact rule but, under the
  paper's collision rule (``task.collision=scan``), swung between a timid and a reckless policy
  and collapsed with more steps (measured when the issue was filed: return down to -190 near
  2.4M steps, 34.7 % held-out success at 4M);
  with 16,384 per update stochastic training success rose steadily (0.99 by 1.1M steps on
  stage 2) and held (the results page). More environments per adapter step share its fixed
  costs (the hand-off to the worker process, the wait for the slower half, rsl-rl's actor and
  critic forward passes), so 64 environments are kept; the longer rollout costs nothing per step.
* update: 5 epochs x 4 minibatches of 4,096 = 20 gradient steps per iteration (the authors: 16
  passes in minibatches of 32,768 over 115k transitions).
* entropy 0.005 and rsl-rl's KL-adaptive learning rate (desired KL 0.01, starting at 1e-4)
  instead of the authors' 0.05 and fixed 1e-4. Measured on stage 2 (init from the same stage-1
  policy, same batch): with 0.05/fixed the exploration std grew every iteration (0.64 -> 0.79)
  and the policy learned to creep, trading the approach reward for lower change/feasibility
  penalties (stochastic success 0.48 -> 0.3, deterministic 48 % -> 27 % over 150 iterations);
  with 0.005/adaptive stochastic success rose from 0.45 to 0.95 within 80 iterations. With
  batches 30x smaller than the authors', the deterministic entropy gradient dominates the noisy
  policy gradient; both values stay overridable (``train.entropy=0.05 train.schedule=fixed``).

Override any field from the command line (``train.num_envs=32``, ``train.policy.init_log_std=-1``).
"""

from __future__ import annotations

import dataclasses
import re
from typing import Any, Literal

from mjnav.schema import apply_overrides
from mjnav.schema import check as _check
from mjnav.stages import stage_numbers

__all__ = ["CurriculumConfig", "PolicyConfig", "TrainConfig", "load_train"]



@dataclasses.dataclass(frozen=True)
class PolicyConfig:
    """Actor and critic networks (spec §8).

    Attributes:
        actor_hidden_dims: Actor MLP widths (399 -> 256 -> 256 -> 256 -> 4).
        actor_activations: One activation per actor hidden layer.
        critic_hidden_dims: Critic MLP widths (399 -> 320 -> 320 -> 320 -> 1).
        critic_activations: One activation per critic hidden layer (ElegantRL's critic: as the actor).
        init_log_std: Initial state-independent log-std (std = exp(-0.5) = 0.607).
        actor_output_gain: Orthogonal gain of the actor's output layer (ElegantRL: 0.1); 0 keeps
            PyTorch's default initialisation.
        obs_normalization: Running mean/std normalisation of observations (the observation is
            already scaled to about [0, 1], so off).
    """

    actor_hidden_dims: tuple[int, int, int] = (256, 256, 256)
    actor_activations: tuple[str, str, str] = ("relu", "relu", "hardswish")
    critic_hidden_dims: tuple[int, int, int] = (320, 320, 320)
    critic_activations: tuple[str, str, str] = ("relu", "relu", "hardswish")
    init_log_std: float = -0.5
    actor_output_gain: float = 0.1
    obs_normalization: bool = False

    def __post_init__(self) -> None:
        dims = self.actor_hidden_dims + self.critic_hidden_dims
        _check(all(d >= 1 for d in dims), "hidden_dims", "widths must be >= 1")
        _check(self.actor_output_gain >= 0, "actor_output_gain", "must be >= 0")


@dataclasses.dataclass(frozen=True)
class CurriculumConfig:
    """Stage promotion (spec §9, proposal).

    Attributes:
        first_stage: Stage number the curriculum starts at (0: the first ``stage<N>`` in the tasks
            folder, :func:`mjnav.stages.stage_numbers`, when walked; :meth:`stages`).
        last_stage: Stage number the curriculum ends with (0: the last in the tasks folder).
        threshold: Promote when the deterministic success rate reaches this.
        eval_episodes: Episodes per deterministic evaluation.
        eval_interval: Training iterations between evaluations.
        stage_steps: Per-stage budget in env steps; promote when spent.
        eval_seed_offset: Added to the run seed for the evaluation environments (separate from the
            training environments; not the held-out scenarios of ``scripts/evaluate.py``).
    """

    first_stage: int = 0
    last_stage: int = 0
    threshold: float = 0.9
    eval_episodes: int = 100
    eval_interval: int = 50
    stage_steps: int = 3_000_000
    eval_seed_offset: int = 1_000_000

    def __post_init__(self) -> None:
        numbers = stage_numbers()
        for name in ("first_stage", "last_stage"):
            value = getattr(self, name)
            _check(value == 0 or value in numbers, name,
                   f"no stage{value} in the tasks folder (stages: {', '.join(map(str, numbers))})")
        _check(self.first_stage == 0 or self.last_stage == 0 or self.first_stage <= self.last_stage,
               "first_stage", "needs first_stage <= last_stage")

    def stages(self) -> list[int]:
        """The stage numbers walked, in order: the tasks folder's from first to last (0 = either end)."""
        numbers = stage_numbers()
        first, last = self.first_stage or numbers[0], self.last_stage or numbers[-1]
        return [n for n in numbers if first <= n <= last]

        _check(0.0 < self.threshold <= 1.0, "threshold", "must be in (0, 1]")
        _check(self.eval_episodes >= 1 and self.eval_interval >= 1, "eval_episodes", "must be >= 1")
        _check(self.stage_steps >= 1, "stage_steps", "must be >= 1")


_DEVICE = re.compile(r"cpu|cuda(:\d+)?|mps")


@dataclasses.dataclass(frozen=True)
class TrainConfig:
    """PPO training run.

    Attributes:
        num_envs: Parallel environments N, per rank under torchrun (an iteration then collects
            ranks × N × steps_per_env transitions; :mod:`mjnav.train.distributed`).
        workers: Workers stepping environments (-1: one per CPU core, at most N, the node's cores
            shared by its ranks under torchrun; 0: in-process). The trainer process is worker 0,
            so W workers start W - 1 processes.
        main_envs: Environments the trainer process steps itself when it is one of W >= 2
            workers (-1: an even share, N / W); the worker processes share the rest. Fewer leave
            the trainer time for its own per-step work (policy inference, the adapter's and PPO's
            bookkeeping) while the worker processes step; rollouts are the same for any value
            (``mjnav bench collect`` shows the trainer's share).
        pipeline: Hand each step's actions to the worker processes before the trainer's value
            estimates and storage, so that those overlap the workers' stepping
            (:class:`mjnav.train.ppo.PipelinedPPO`); the rollouts and updates are rsl-rl's bit for
            bit either way. False: rsl-rl's PPO unchanged.
        rollouts: With ``pipeline`` on CPU: each worker (the trainer included) runs the whole
            rollout of its environments with copies of the actor and the critic and the sampling
            noise drawn as rsl-rl draws it, without waiting for the others at every step; the
            trainer then stores the recorded steps. Bit for bit rsl-rl's rollouts where a part's
            network outputs equal the whole batch's rows (checked before every rollout; where they
            would differ, as for parts of fewer than 4 environments with MKL, it warns and steps
            the workers in lockstep; :mod:`mjnav.train.ppo`). False: lockstep.
        rollout_envs: Most environments a worker runs together through a rollout: its block in
            parts of this many, one part after another, so that a part stays in the cache (0: the
            whole block). Rollouts do not depend on it.
        start_method: Worker start method (``forkserver`` or ``spawn``; never plain fork with torch).
        iterations: Total PPO iterations of the run (a resumed run continues up to this).
        steps_per_env: Rollout length per environment and iteration.
        learning_rate: AdamW learning rate (initial value with the adaptive schedule).
        gamma: Discount.
        lam: GAE lambda.
        clip: PPO ratio clip (also the value clip).
        entropy: Entropy bonus coefficient.
        epochs: Passes over each rollout.
        minibatches: Minibatches per pass.
        value_loss_coef: Value loss weight.
        value_clip: Clip each value prediction to within ``clip`` of its rollout value in the value
            loss (rsl-rl's default). The clip is absolute: with returns of order 100 (success +140)
            the loss stops pulling an estimate once it has moved by ``clip`` in one update.
        max_grad_norm: Gradient norm clip.
        optimizer: ``adamw`` (authors) or ``adam``.
        schedule: ``fixed`` (authors) or rsl-rl's KL-``adaptive`` learning rate.
        desired_kl: Target KL of the adaptive schedule.
        random_initial_lengths: Randomise the episode clock at start (rsl-rl's init_at_random_ep_len).
        critic_warmup: The run's first iterations (numbered from 0) in which only the critic
            learns: the actor's weights and log-std stay as loaded. For a run started (``init=``)
            from an actor whose critic does not fit it (an imitation warm start, another
            observation), so that the first advantages do not undo the actor. 0: off.
        device: Torch device of the networks and returned tensors (``cpu``, ``cuda``, ``cuda:1``);
            under torchrun any ``cuda`` is the rank's ``cuda:LOCAL_RANK``.
        torch_threads: Intra-op threads of the trainer process while it collects rollouts (0: torch
            default). 1 by default: on a 2-core box torch's two OpenMP threads spin against the env
            workers and made collection 3x slower (measured: 1.4 s vs 4-5 s per 1,024 transitions).
        update_threads: Intra-op threads during the PPO update, when the env workers are idle (0:
            one per usable CPU core, shared by a node's ranks). On the 2-core box two threads took 0.80 s per update of
            20 minibatches of 1,024 against 1.29 s with one.
        save_interval: Iterations between checkpoints.
        seed: Seed of torch and of the environments (env i starts from seed + i); under torchrun
            rank r uses seed + r × num_envs for both.
        verbose: Also print rsl-rl's per-iteration block (otherwise one progress line).
        policy: Network settings.
        curriculum: Curriculum settings (used with ``curriculum=true``).
    """

    num_envs: int = 64
    workers: int = -1
    main_envs: int = -1
    pipeline: bool = True
    rollouts: bool = True
    rollout_envs: int = 16
    start_method: Literal["forkserver", "spawn"] = "forkserver"
    iterations: int = 1000
    steps_per_env: int = 256
    learning_rate: float = 1e-4
    gamma: float = 0.98
    lam: float = 0.98
    clip: float = 0.2
    entropy: float = 0.005
    epochs: int = 5
    minibatches: int = 4
    value_loss_coef: float = 1.0
    value_clip: bool = True
    max_grad_norm: float = 1.0
    optimizer: Literal["adamw", "adam"] = "adamw"
    schedule: Literal["fixed", "adaptive"] = "adaptive"
    desired_kl: float = 0.01
    random_initial_lengths: bool = False
    critic_warmup: int = 0
    device: str = "cpu"
    torch_threads: int = 1
    update_threads: int = 0
    save_interval: int = 50
    seed: int = 0
    verbose: bool = False
    policy: PolicyConfig = PolicyConfig()
    curriculum: CurriculumConfig = CurriculumConfig()

    def __post_init__(self) -> None:
        _check(self.num_envs >= 1, "num_envs", "must be >= 1")
        _check(
            -1 <= self.workers <= self.num_envs, "workers", f"must be -1, 0 or <= num_envs ({self.num_envs})"
        )
        _check(self.main_envs == -1 or 1 <= self.main_envs < self.num_envs, "main_envs",
               f"must be -1 or in [1, num_envs) ({self.num_envs})")
        _check(self.main_envs == -1 or self.workers < 2 or self.main_envs <= self.num_envs - self.workers + 1,
               "main_envs", f"must leave each of the other {self.workers - 1} workers an environment "
               f"(<= {self.num_envs - self.workers + 1} of {self.num_envs})")
        _check(self.rollout_envs >= 0, "rollout_envs", "must be >= 0 (0: a worker's whole block)")
        _check(self.iterations >= 1 and self.steps_per_env >= 1, "iterations", "must be >= 1")
        _check(self.learning_rate > 0, "learning_rate", "must be > 0")
        _check(0 < self.gamma <= 1 and 0 <= self.lam <= 1, "gamma", "needs 0 < gamma <= 1, 0 <= lam <= 1")
        _check(self.clip > 0 and self.entropy >= 0, "clip", "needs clip > 0 and entropy >= 0")
        _check(self.epochs >= 1 and self.minibatches >= 1, "epochs", "epochs and minibatches must be >= 1")
        batch = self.num_envs * self.steps_per_env
        _check(batch % self.minibatches == 0, "minibatches", f"must divide num_envs*steps_per_env ({batch})")
        _check(self.save_interval >= 1, "save_interval", "must be >= 1")
        _check(self.critic_warmup >= 0, "critic_warmup", "must be >= 0")
        _check(self.torch_threads >= 0, "torch_threads", "must be >= 0")
        _check(self.update_threads >= 0, "update_threads", "must be >= 0")
        device_ok = _DEVICE.fullmatch(self.device) is not None
        _check(device_ok, "device", f"expected cpu, cuda, cuda:N or mps, got {self.device!r}")


def load_train(
    overrides: dict[str, Any] | list[str] | None = None, base: TrainConfig | None = None
) -> TrainConfig:
    """A :class:`TrainConfig` with dotted overrides applied (``["num_envs=32"]``).

    Raises:
        mjnav.schema.ConfigError: Unknown key (named) or invalid value.
    """
    return apply_overrides(base or TrainConfig(), overrides or {})
