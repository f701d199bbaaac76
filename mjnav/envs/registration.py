"""Gymnasium ids ``mjnav/Stage<N>-v1``, one per ``stage<N>`` file in the tasks folder (registered on ``import mjnav``).

The ids follow the files (:mod:`mjnav.stages`): ``tasks/stage8.yaml`` adds ``mjnav/Stage8-v1``.
The entry point (:func:`mjnav.envs.gym_env.make_registered`) wraps each environment in a
``TimeLimit`` of its configured episode length, so ``spec.max_episode_steps`` is set (300 by
default, the value of ``timing.episode_steps`` when overridden).
"""

from __future__ import annotations

import gymnasium as gym

from mjnav.stages import env_id, stage_name, stage_numbers

__all__ = ["ENV_IDS", "env_ids", "register_envs"]


def env_ids() -> tuple[str, ...]:
    """The ids of the numbered stages in the tasks folder now, in stage order."""
    return tuple(env_id(stage_name(n)) for n in stage_numbers())


#: The ids at import time (:func:`env_ids` re-reads the tasks folder).
ENV_IDS = env_ids()


def register_envs() -> tuple[str, ...]:
    """Register the id of every numbered stage (idempotent: call again after adding a stage file);
    returns the ids. The env module is imported on ``make``."""
    for number in stage_numbers():
        name = stage_name(number)
        if env_id(name) not in gym.registry:
            gym.register(id=env_id(name), entry_point="mjnav.envs.gym_env:make_registered", kwargs={"task": name})
    return env_ids()
