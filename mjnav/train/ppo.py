"""PPO whose environment worker processes step while the trainer finishes each step's bookkeeping.

In rsl-rl's rollout loop the trainer samples the actions, evaluates the critic and the actions'
log-probabilities (:meth:`PPO.act`), steps the environments, then stores the transition
(:meth:`PPO.process_env_step`). With :class:`mjnav.envs.vec_env.NavVecEnv`'s worker processes
stepping most environments, everything the trainer does between one step's results and the next
step's actions leaves them idle: 1.7 ms of the policy and about 0.9 ms of storage and logs per
step of 64 environments, measured on the 2-core development machine (the performance page).

:class:`PipelinedPPO` does the same work in another order. ``act`` samples the actions as rsl-rl
does and hands them at once to the adapter's ``dispatch``, so the worker processes start
stepping; then it stores the previous step's transition (``process_env_step`` only keeps its
arguments until here, and so do rsl-rl's logger's when wrapped by :meth:`PipelinedPPO.deferring`)
and evaluates the critic and the log-probabilities for the new one. ``compute_returns`` first
stores the rollout's last transition. The same operations run on the same tensors, so rollouts,
storage and updates are rsl-rl's bit for bit (``tests/train/test_ppo.py``). It keeps rsl-rl's
order for recurrent models and RND (where storing a step feeds the next action) and for
environments without ``dispatch``.

With ``worker_rollouts`` it goes further, on CPU: at the first step of a rollout it draws the noise
of every step's sampling as rsl-rl's calls would, in the same order, and hands the adapter a copy of
the actor with it (:class:`RolloutActor`, :meth:`mjnav.envs.vec_env.NavVecEnv.rollout`). Each
worker then runs the whole rollout of its environments, choosing their actions itself, without
waiting for the others or for the trainer at every step, and evaluates the critic there too;
``act`` then takes each step's recorded actions, means and values and stores the transitions as
before. The actions and values equal rsl-rl's when the actor's and the critic's outputs for a
block of rows equal their rows of the whole batch's. This is checked in the trainer before every
rollout, on its first observations: a rollout that would differ (or whose record would not fit in
the shared memory) is not started, and collection falls back to the per-step pipeline for good
(counted in :attr:`PipelinedPPO.rollout_fallbacks`, with a warning). After the rollout the
workers' own first outputs are compared with the trainer's: should they differ (another kernel
in a worker process), that rollout is kept, consistent in itself (its log-probabilities come from
the recorded means) but not rsl-rl's in the last bits, and the later ones fall back, with a warning.
"""

from __future__ import annotations

import copy
import functools
import warnings
from collections.abc import Callable
from typing import Any

import numpy as np
import torch
from rsl_rl.algorithms import PPO
from rsl_rl.modules.distribution import GaussianDistribution
from tensordict import TensorDict

__all__ = ["PipelinedPPO", "RolloutActor"]


class PipelinedPPO(PPO):
    """rsl-rl's PPO that dispatches each step's actions before its value estimates and storage
    (see :meth:`connect` for where it does)."""

    def __init__(self, *args: Any, worker_rollouts: bool = False, **kwargs: Any) -> None:
        """rsl-rl's arguments; ``worker_rollouts``: let the adapter's workers run each rollout
        (module docstring) where that keeps rsl-rl's results."""
        super().__init__(*args, **kwargs)
        self._dispatch: Callable[[torch.Tensor], None] | None = None
        self._deferred: list[tuple[Callable, tuple]] = []  # calls kept for the next act
        self.worker_rollouts = worker_rollouts
        self._rollout_env: Any = None  # the adapter running rollouts (None: step by step)
        self.rollout_fallbacks = 0  # times rollouts were turned off (module docstring)

    @staticmethod
    def construct_algorithm(obs: TensorDict, env: Any, cfg: dict, device: str) -> PPO:
        """rsl-rl's construction (the class named in ``cfg["algorithm"]``), then :meth:`connect` to ``env``."""
        alg = PPO.construct_algorithm(obs, env, cfg, device)
        if isinstance(alg, PipelinedPPO):
            alg.connect(env)
        return alg

    def connect(self, env: Any) -> None:
        """Dispatch actions to ``env.dispatch`` from now on, where that keeps rsl-rl's results; with
        ``worker_rollouts`` on CPU, a Gaussian actor and an ``env`` offering ``rollout``, run each
        rollout in its workers instead (module docstring). An ``env`` still serving a rollout (an
        earlier ``learn()`` raised within it) is reset, so that its state matches its observations;
        the storage that ``learn()`` left part-filled is rsl-rl's matter, as without rollouts.

        Not for recurrent actors or critics (their hidden states are reset when a step is
        stored, before the next action) or with RND (its intrinsic reward is computed when a
        step is stored), nor for an ``env`` without ``dispatch``: those keep rsl-rl's order.
        """
        recurrent = self.actor.is_recurrent or self.critic.is_recurrent
        dispatch = getattr(env, "dispatch", None)
        self._store_deferred()
        if getattr(env, "replaying", False):  # a rollout left part-served (an earlier learn() raised)
            warnings.warn("the environment was still serving a rollout: it is reset", stacklevel=2)
            env.reset()
        self._dispatch = None if recurrent or self.rnd is not None or not callable(dispatch) else dispatch
        rollouts = (self.worker_rollouts and self._dispatch is not None and callable(getattr(env, "rollout", None))
                    and torch.device(self.device).type == "cpu"
                    and type(self.actor.distribution) is GaussianDistribution)
        self._rollout_env = env if rollouts else None

    @property
    def pipelined(self) -> bool:
        """Whether actions go to the environment's ``dispatch``."""
        return self._dispatch is not None

    def act(self, obs: TensorDict) -> torch.Tensor:
        """Sample actions, dispatch them, store the previous step, then record this step's values."""
        if self._dispatch is None:
            return super().act(obs)
        env = self._rollout_env
        if env is not None and (env.replaying or (self.worker_rollouts and self._start_rollout(env, obs))):
            actions, outputs = env.recorded()
            self.actor.distribution.update(outputs[:, :-1])  # the actor's output for obs, as in its forward
            values = outputs[:, -1:]  # the critic's
        else:
            actions = self.actor(obs, stochastic_output=True).detach()
            self._dispatch(actions)
            values = None
        self._store_deferred()
        transition = self.transition
        transition.hidden_states = (self.actor.get_hidden_state(), self.critic.get_hidden_state())
        transition.actions = actions
        transition.values = self.critic(obs).detach() if values is None else values
        transition.actions_log_prob = self.actor.get_output_log_prob(actions).detach()
        transition.distribution_params = tuple(p.detach() for p in self.actor.output_distribution_params)
        transition.observations = obs
        return actions

    def _start_rollout(self, env: Any, obs: TensorDict) -> bool:
        """Start the adapter's rollout of this iteration's steps from ``obs``; False (and rollouts off
        for good, counted) when a block of rows would give other outputs than the whole batch, or
        the record does not fit in the shared memory."""
        actor, critic, steps = self.actor, self.critic, self.storage.num_transitions_per_env
        with torch.inference_mode():
            latent, critic_latent = actor.get_latent(obs), critic.get_latent(obs)
            mean, values = actor.mlp(latent), critic.mlp(critic_latent)
            blocks = env.rollout_blocks
            agree = _blocks_agree(actor, latent, mean, blocks) and _blocks_agree(critic, critic_latent, values, blocks)
            if not agree:
                return self._fall_back("the actor's or critic's output for a block of environments differs from "
                                       "the whole batch's in the last bits")
            if not env.can_record(steps, mean.shape[1] + 1):
                return self._fall_back(f"a rollout of {steps} steps does not fit in the shared memory (/dev/shm)")
            actor.distribution.update(mean)
            std = actor.output_distribution_params[1].expand_as(mean).contiguous()
            noise = torch.empty((steps, *mean.shape), dtype=mean.dtype)
            for t in range(steps):  # rsl-rl draws each step's noise in turn (torch.normal of that shape)
                noise[t].normal_()
        policy = RolloutActor(_detached_copy(actor), _detached_copy(critic), std, noise)
        env.rollout(policy, steps, aux_dim=mean.shape[1] + 1)
        if not torch.equal(env.recorded()[1], torch.cat((mean, values), dim=1)):  # the workers' own numerics
            self._fall_back("the workers' actor or critic outputs differed in the last bits from the trainer's at "
                            "this rollout's first step (it stands: its log-probabilities use the recorded means)")
        return True

    def _fall_back(self, why: str) -> bool:
        """Turn rollouts off for good, after any rollout being served (counted, with a warning
        saying ``why``); False."""
        self.rollout_fallbacks += 1
        self.worker_rollouts = False
        warnings.warn(f"{why}: rollouts fall back to the per-step pipeline (train.rollouts=false chooses it "
                      "from the start)", stacklevel=3)
        return False

    def process_env_step(
        self, obs: TensorDict, rewards: torch.Tensor, dones: torch.Tensor, extras: dict[str, torch.Tensor]
    ) -> None:
        """Record one environment step: at once in rsl-rl's order, otherwise at the next :meth:`act`."""
        if self._dispatch is None:
            super().process_env_step(obs, rewards, dones, extras)
        else:
            self._deferred.append((super().process_env_step, (obs, rewards, dones, extras)))

    def deferring(self, method: Callable[..., None]) -> Callable[..., None]:
        """``method`` made to run when this step's transition is stored, while pipelined.

        For other per-step bookkeeping of the rollout loop that reads nothing the next action
        needs, such as rsl-rl's logger (``runner.logger.process_env_step``): it then also
        overlaps the worker processes' stepping, in its original order.
        """

        @functools.wraps(method)
        def deferred(*args: Any, **kwargs: Any) -> None:
            if self._dispatch is None:
                method(*args, **kwargs)
            else:
                self._deferred.append((functools.partial(method, **kwargs), args))

        return deferred

    def compute_returns(self, obs: TensorDict) -> None:
        """Store the rollout's last step, then rsl-rl's returns and advantages."""
        self._store_deferred()
        super().compute_returns(obs)

    def _store_deferred(self) -> None:
        calls, self._deferred = self._deferred, []
        for method, args in calls:
            method(*args)


class RolloutActor:
    """Copies of the actor and the critic acting for a worker in a rollout
    (:meth:`mjnav.envs.vec_env.NavVecEnv.rollout`).

    At step ``t`` the actions of environments ``indices`` are ``noise[t] * std + mean`` on their rows,
    ``mean`` the actor's output for their observations: what rsl-rl's Gaussian sampling
    (``torch.normal(mean, std)``) computes for those rows from the same noise. The means and the
    critic's values are returned as well (``aux``, ``num_actions + 1`` columns), for the trainer's
    log-probabilities, stored distribution parameters and values.
    """

    def __init__(self, actor: torch.nn.Module, critic: torch.nn.Module, std: torch.Tensor, noise: torch.Tensor) -> None:
        """``actor``, ``critic``: CPU copies (rsl-rl models with ``get_latent`` and ``mlp``);
        ``std``: (N, A); ``noise``: (steps, N, A), standard normal."""
        self.actor, self.critic, self.std, self.noise = actor, critic, std, noise

    def __call__(self, t: int, indices: range, obs: np.ndarray, critic: np.ndarray | None) -> tuple:
        rows = slice(indices.start, indices.stop)
        groups = {"policy": torch.from_numpy(obs)}
        if critic is not None:
            groups["critic"] = torch.from_numpy(critic)
        observations = TensorDict(groups, batch_size=[len(indices)])
        with torch.inference_mode():
            mean = self.actor.mlp(self.actor.get_latent(observations))
            actions = self.noise[t, rows].mul(self.std[rows]).add(mean)
            values = self.critic.mlp(self.critic.get_latent(observations))
        return actions.numpy(), torch.cat((mean, values), dim=1).numpy()


def _blocks_agree(model: torch.nn.Module, latent: torch.Tensor, output: torch.Tensor, blocks: list[range]) -> bool:
    """Whether ``model.mlp`` of each block's rows of ``latent`` equals those rows of ``output`` (the
    whole batch's), bit for bit."""
    return all(torch.equal(model.mlp(latent[b.start : b.stop]), output[b.start : b.stop]) for b in blocks)


def _detached_copy(model: torch.nn.Module) -> torch.nn.Module:
    """A deep copy of ``model`` without its distribution's last state (rsl-rl keeps the last
    ``Normal``, whose tensors may belong to an autograd graph and cannot be deep-copied)."""
    distribution = model.distribution
    if distribution is None:
        return copy.deepcopy(model)
    last = distribution._distribution
    distribution._distribution = None
    try:
        return copy.deepcopy(model)
    finally:
        distribution._distribution = last
