"""Extension points share one registry shape, and unknown names fail with the known ones listed.

That a new stage, planner, pedestrian model, robot, design or LiDAR backend is one file or one
module and one registration is tested by running the "Extending mjnav" page
(``tests/test_docs_extending.py``)."""

from __future__ import annotations

import pytest

from mjnav.config import load_task
from mjnav.entities import ROBOTS
from mjnav.planners import PLANNERS, make_planner
from mjnav.registry import Registry
from mjnav.schema import ConfigError
from mjnav.sensors import LIDAR_BACKENDS
from mjnav.stages import STAGES
from mjnav.tasks.design import DESIGNS
from mjnav.world import PEDESTRIAN_MODELS


def test_unknown_names_list_the_known_ones() -> None:
    """An unknown pedestrian model, design, planner, LiDAR backend or robot names the key and the closest."""
    with pytest.raises(ConfigError, match=r"crowd\.model: unknown pedestrian model 'socal_force'.*closest: social_force"):
        load_task("stage5", ["crowd.model=socal_force"])
    with pytest.raises(ConfigError, match=r"design: unknown design 'desgn1'.*closest: design1"):
        load_task("stage2", ["design=desgn1"])
    with pytest.raises(KeyError, match=r"unknown planner 'mpc_gaol'.*closest: mpc_goal"):
        make_planner("mpc_gaol")
    from mjnav.sim import NavSim

    with pytest.raises(ConfigError, match=r"lidar\.backend: unknown LiDAR backend 'analytical'"):
        NavSim(load_task("stage1", ["lidar.backend=analytical"]))
    with pytest.raises(ConfigError, match=r"robot\.model: unknown robot 'omnii'.*closest: omni"):
        NavSim(load_task("stage1", ["robot.model=omnii"]))


def test_every_extension_point_is_a_registry_with_its_entry_point_group() -> None:
    """Planners, pedestrian models, designs, LiDAR backends, robots and stages share one registry shape."""
    groups = {registry.group: registry
              for registry in (PLANNERS, PEDESTRIAN_MODELS, DESIGNS, LIDAR_BACKENDS, ROBOTS, STAGES)}
    assert all(isinstance(r, Registry) for r in groups.values())
    assert set(groups) == {"mjnav.planners", "mjnav.pedestrian_models", "mjnav.designs", "mjnav.lidar_backends",
                           "mjnav.robots", "mjnav.stages"}
    assert {"mpc_goal", "teb", "dwa", "random_jerk"} <= set(PLANNERS.names())
    assert set(PEDESTRIAN_MODELS.names()) >= {"random_walk", "social_force"}
    assert set(DESIGNS.names()) >= {"ours", "design1", "design4"}
    assert set(LIDAR_BACKENDS.names()) >= {"analytic", "mujoco"} and "omni" in ROBOTS
