"""Gymnasium ids ``mjnav/Stage1-v1`` … ``mjnav/Stage7-v1`` (registered on ``import mjnav``)."""

from __future__ import annotations

import gymnasium as gym

__all__ = ["ENV_IDS", "register_envs"]

ENV_IDS = tuple(f"mjnav/Stage{i}-v1" for i in range(1, 8))


def register_envs() -> None:
    """Register the seven stage ids (idempotent; the env module is imported on ``make``)."""
    for i, env_id in enumerate(ENV_IDS, start=1):
        if env_id not in gym.registry:
            gym.register(id=env_id, entry_point="mjnav.envs.gym_env:NavGymEnv", kwargs={"task": f"stage{i}"})
