"""Gymnasium ids ``mjnav/Stage1-v1`` … ``mjnav/Stage7-v1`` (registered on ``import mjnav``), and next
to each its ``-v2`` (:data:`V2_ENV_IDS`: the same environment with bounded spaces for standard RL
clients, :mod:`mjnav.envs.bounded`; ``docs/envs.md``).

The entry point (:func:`mjnav.envs.gym_env.make_registered`) wraps each environment in a
``TimeLimit`` of its configured episode length, so ``spec.max_episode_steps`` is set (300 by
default, the value of ``timing.episode_steps`` when overridden).
"""

from __future__ import annotations

import gymnasium as gym

__all__ = ["ENV_IDS", "V2_ENV_IDS", "register_envs", "v2_id"]

ENV_IDS = tuple(f"mjnav/Stage{i}-v1" for i in range(1, 8))


def v2_id(env_id: str) -> str:
    """The bounded-spaces id registered next to a ``-v1`` id (``mjnav/Stage6-v1`` -> ``mjnav/Stage6-v2``)."""
    return env_id.removesuffix("-v1") + "-v2"


V2_ENV_IDS = tuple(v2_id(env_id) for env_id in ENV_IDS)


def register_envs() -> None:
    """Register the seven stage ids and their ``-v2`` (idempotent; the env module is imported on ``make``)."""
    for i, env_id in enumerate(ENV_IDS, start=1):
        if env_id not in gym.registry:
            gym.register(id=env_id, entry_point="mjnav.envs.gym_env:make_registered", kwargs={"task": f"stage{i}"})
        if v2_id(env_id) not in gym.registry:
            gym.register(id=v2_id(env_id), entry_point="mjnav.envs.bounded:make_bounded", kwargs={"task": f"stage{i}"})
