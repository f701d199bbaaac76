"""Gymnasium ids ``mjnav/Stage1-v1`` … ``mjnav/Stage7-v1`` (registered on ``import mjnav``).

The entry point (:func:`mjnav.envs.gym_env.make_registered`) wraps each environment in a
``TimeLimit`` of its configured episode length, so ``spec.max_episode_steps`` is set (300 by
default, the value of ``timing.episode_steps`` when overridden).
"""

from __future__ import annotations

import gymnasium as gym

__all__ = ["ENV_IDS", "register_envs"]

ENV_IDS = tuple(f"mjnav/Stage{i}-v1" for i in range(1, 8))


def register_envs() -> None:
    """Register the seven stage ids (idempotent; the env module is imported on ``make``)."""
    for i, env_id in enumerate(ENV_IDS, start=1):
        if env_id not in gym.registry:
            gym.register(id=env_id, entry_point="mjnav.envs.gym_env:make_registered", kwargs={"task": f"stage{i}"})
