"""The built-in pedestrian models through the task config: ORCA by name, and crowd.reactive."""

from __future__ import annotations

import numpy as np
import pytest

from mjnav.config import load_task
from mjnav.envs.gym_env import NavGymEnv
from mjnav.schema import ConfigError
from mjnav.world import make_pedestrian_model
from mjnav.world.orca import OrcaModel


def _gaps(env: NavGymEnv, steps: int) -> float:
    """Smallest surface gap between two pedestrians over ``steps`` control steps (metres)."""
    smallest = np.inf
    env.reset(options={"episode_seed": 11})
    for _ in range(steps):
        env.step(np.zeros(4, np.float32))
        peds = env.task.sim.pedestrian_circles()
        d = np.linalg.norm(peds[:, None, :2] - peds[None, :, :2], axis=-1) - peds[:, None, 2] - peds[None, :, 2]
        smallest = min(smallest, float(d[np.triu_indices(len(peds), 1)].min()))
    return smallest


def test_orca_is_a_crowd_model_by_name():
    config = load_task("stage7", ["crowd.model=orca", "crowd.orca.time_horizon=3"])
    model = make_pedestrian_model(config.crowd)
    assert isinstance(model, OrcaModel) and model.config.time_horizon == 3.0 and not model.reacts_to_robot
    assert make_pedestrian_model(load_task("stage7", ["crowd.model=orca", "crowd.reactive=true"]).crowd).reacts_to_robot


def test_reactive_switch_for_each_model():
    sf = make_pedestrian_model(load_task("stage6", ["crowd.model=social_force"]).crowd)
    assert sf.reacts_to_robot  # social force's own behaviour (the replayed episodes) is kept
    assert not make_pedestrian_model(load_task("stage6", ["crowd.model=social_force", "crowd.reactive=false"]).crowd).reacts_to_robot
    with pytest.raises(ConfigError, match="random walk cannot react"):
        make_pedestrian_model(load_task("stage6", ["crowd.reactive=true"]).crowd)


def test_bad_orca_parameter_names_its_key():
    with pytest.raises((ConfigError, ValueError), match="time_horizon"):
        load_task("stage7", ["crowd.model=orca", "crowd.orca.time_horizon=-1"])


def test_orca_pedestrians_never_touch_in_a_stage7_episode():
    env = NavGymEnv("stage7", overrides=["crowd.model=orca"], seed=0)
    try:
        assert _gaps(env, 60) > 0.0
    finally:
        env.close()
