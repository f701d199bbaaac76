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
"""

from __future__ import annotations

import functools
from collections.abc import Callable
from typing import Any

import torch
from rsl_rl.algorithms import PPO
from tensordict import TensorDict

__all__ = ["PipelinedPPO"]


class PipelinedPPO(PPO):
    """rsl-rl's PPO that dispatches each step's actions before its value estimates and storage
    (see :meth:`connect` for where it does)."""

    def __init__(self, *args: Any, **kwargs: Any) -> None:
        super().__init__(*args, **kwargs)
        self._dispatch: Callable[[torch.Tensor], None] | None = None
        self._deferred: list[tuple[Callable, tuple]] = []  # calls kept for the next act

    @staticmethod
    def construct_algorithm(obs: TensorDict, env: Any, cfg: dict, device: str) -> PPO:
        """rsl-rl's construction (the class named in ``cfg["algorithm"]``), then :meth:`connect` to ``env``."""
        alg = PPO.construct_algorithm(obs, env, cfg, device)
        if isinstance(alg, PipelinedPPO):
            alg.connect(env)
        return alg

    def connect(self, env: Any) -> None:
        """Dispatch actions to ``env.dispatch`` from now on, where that keeps rsl-rl's results.

        Not for recurrent actors or critics (their hidden states are reset when a step is
        stored, before the next action) or with RND (its intrinsic reward is computed when a
        step is stored), nor for an ``env`` without ``dispatch``: those keep rsl-rl's order.
        """
        recurrent = self.actor.is_recurrent or self.critic.is_recurrent
        dispatch = getattr(env, "dispatch", None)
        self._store_deferred()
        self._dispatch = None if recurrent or self.rnd is not None or not callable(dispatch) else dispatch

    @property
    def pipelined(self) -> bool:
        """Whether actions go to the environment's ``dispatch``."""
        return self._dispatch is not None

    def act(self, obs: TensorDict) -> torch.Tensor:
        """Sample actions, dispatch them, store the previous step, then record this step's values."""
        if self._dispatch is None:
            return super().act(obs)
        actions = self.actor(obs, stochastic_output=True).detach()
        self._dispatch(actions)
        self._store_deferred()
        transition = self.transition
        transition.hidden_states = (self.actor.get_hidden_state(), self.critic.get_hidden_state())
        transition.actions = actions
        transition.values = self.critic(obs).detach()
        transition.actions_log_prob = self.actor.get_output_log_prob(actions).detach()
        transition.distribution_params = tuple(p.detach() for p in self.actor.output_distribution_params)
        transition.observations = obs
        return actions

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
