"""Deterministic evaluation of a policy on a :class:`~mjnav.envs.vec_env.NavVecEnv`.

Deterministic means the policy mean: the environment applies the sigmoid itself, so the
evaluated action is sigmoid(mean) as in spec §8. Every environment runs a fixed quota of
episodes (``episodes`` split evenly), so short episodes are not over-represented.
"""

from __future__ import annotations

import dataclasses
from collections.abc import Callable

import numpy as np
import torch
from tensordict import TensorDict

from mjnav.envs.vec_env import OUTCOMES, NavVecEnv

__all__ = ["EvalResult", "evaluate"]

Policy = Callable[[TensorDict], torch.Tensor]


@dataclasses.dataclass(frozen=True)
class EvalResult:
    """Rates and means over the evaluated episodes.

    Attributes:
        episodes: Number of episodes.
        success: Success rate.
        collision: Collision rate.
        timeout: Timeout rate.
        length: Mean episode length, control steps.
        mean_return: Mean undiscounted return.
    """

    episodes: int
    success: float
    collision: float
    timeout: float
    length: float
    mean_return: float

    def summary(self) -> str:
        """One-line human summary."""
        return (
            f"{self.episodes} episodes: success {self.success:.3f}, collision {self.collision:.3f}, "
            f"timeout {self.timeout:.3f}, length {self.length:.1f}, return {self.mean_return:.1f}"
        )


def evaluate(policy: Policy, env: NavVecEnv, episodes: int) -> EvalResult:
    """Run ``episodes`` deterministic episodes (all environments are reset first).

    Args:
        policy: Maps observations to actions (the mean), e.g. ``runner.get_inference_policy()``.
        env: The adapter; its environments continue their own episode-seed sequences.
        episodes: Number of episodes to count.

    Returns:
        The :class:`EvalResult`.
    """
    n = env.num_envs
    quota = np.array([episodes // n + (i < episodes % n) for i in range(n)])
    counted = np.zeros(n, dtype=np.int64)
    outcomes: list[int] = []
    lengths: list[float] = []
    returns: list[float] = []
    obs = env.reset()
    with torch.inference_mode():
        while (counted < quota).any():
            obs, _, dones, extras = env.step(policy(obs))
            finished = np.flatnonzero(dones.cpu().numpy())
            if finished.size == 0:
                continue
            log = extras["log"]
            for k, i in enumerate(finished):
                if counted[i] < quota[i]:
                    counted[i] += 1
                    outcomes.append(int(extras["outcomes"][i]))
                    lengths.append(float(log["episode/length"][k]))
                    returns.append(float(log["episode/return"][k]))
    codes = np.array(outcomes)
    rate = {name: float(np.mean(codes == OUTCOMES.index(name))) for name in OUTCOMES[1:]}
    return EvalResult(
        len(codes),
        rate["success"],
        rate["collision"],
        rate["timeout"],
        float(np.mean(lengths)),
        float(np.mean(returns)),
    )
