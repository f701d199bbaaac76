"""Gymnasium ids ``mjnav/Stage<N>-v1``, one per ``stage<N>`` file in the tasks folder (registered on
``import mjnav``), and next to each its ``-v2`` (:data:`V2_ENV_IDS`: the same environment with
bounded spaces for standard RL clients, :mod:`mjnav.envs.bounded`; the env card in the docs).

The ids follow the files (:mod:`mjnav.stages`): ``tasks/stage8.yaml`` adds ``mjnav/Stage8-v1`` and
``mjnav/Stage8-v2``. The entry points (:func:`mjnav.envs.gym_env.make_registered`,
:func:`mjnav.envs.bounded.make_bounded`) wrap each environment in a ``TimeLimit`` of its configured
episode length, so ``spec.max_episode_steps`` is set (300 by default, the value of
``timing.episode_steps`` when overridden).
"""

from __future__ import annotations

import gymnasium as gym

from mjnav.stages import env_id, stage_name, stage_numbers

__all__ = ["ENV_IDS", "V2_ENV_IDS", "env_ids", "register_envs", "v2_id"]


def env_ids() -> tuple[str, ...]:
    """The ``-v1`` ids of the numbered stages in the tasks folder now, in stage order."""
    return tuple(env_id(stage_name(n)) for n in stage_numbers())


def v2_id(v1_id: str) -> str:
    """The bounded-spaces id registered next to a ``-v1`` id (``mjnav/Stage6-v1`` -> ``mjnav/Stage6-v2``)."""
    return v1_id.removesuffix("-v1") + "-v2"


#: The ids at import time (:func:`env_ids` re-reads the tasks folder).
ENV_IDS = env_ids()
V2_ENV_IDS = tuple(v2_id(i) for i in ENV_IDS)


def register_envs() -> tuple[str, ...]:
    """Register the ``-v1`` and ``-v2`` ids of every numbered stage (idempotent: call again after
    adding a stage file); returns the ``-v1`` ids. The env modules are imported on ``make``."""
    for number in stage_numbers():
        name = stage_name(number)
        if env_id(name) not in gym.registry:
            gym.register(id=env_id(name), entry_point="mjnav.envs.gym_env:make_registered", kwargs={"task": name})
        if v2_id(env_id(name)) not in gym.registry:
            gym.register(id=v2_id(env_id(name)), entry_point="mjnav.envs.bounded:make_bounded", kwargs={"task": name})
    return env_ids()
