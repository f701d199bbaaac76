"""Extension points: a new planner, pedestrian model, design, LiDAR backend or robot is one module
and one registration, and unknown names fail with the known ones listed."""

from __future__ import annotations

from collections.abc import Iterator

import numpy as np
import pytest

from mjnav.config import TaskConfig, load_task
from mjnav.control.dynamics import Limits, track_velocity
from mjnav.entities import ROBOTS
from mjnav.planners import PLANNERS, make_planner
from mjnav.planners.base import PlannerInput
from mjnav.registry import Registry
from mjnav.schema import ConfigError
from mjnav.sensors import LIDAR_BACKENDS
from mjnav.tasks.design import DESIGNS
from mjnav.world import PEDESTRIAN_MODELS
from mjnav.world.crowd import PedestrianModel


class StraightToGoal:
    """A planner that heads straight for the goal at 1 m/s (the task scores it like any other)."""

    def __init__(self) -> None:
        self.limits = Limits()

    def reset(self, config: TaskConfig, rng: np.random.Generator) -> None:
        """Take the task's limits; no randomness."""
        del rng
        self.limits = Limits.from_task(config)

    def act(self, inp: PlannerInput) -> np.ndarray:
        """Jerk (2,), m/s³, towards a 1 m/s velocity along the goal direction."""
        to_goal = inp.goal - inp.position
        v_ref = to_goal / max(float(np.hypot(*to_goal)), 1e-9)
        return track_velocity(inp.velocity, inp.acceleration, v_ref, self.limits)


class StandStill(PedestrianModel):
    """Pedestrians that never move."""

    reacts_to_robot = False

    def __init__(self, config: object = None) -> None:
        """Takes (and ignores) the crowd config, as every pedestrian-model factory does."""
        del config
        super().__init__()

    def _initialize(self, headings: np.ndarray) -> None:
        del headings
        self._vel = np.zeros_like(self._pos)

    def step(self, dt: float, robot_position: np.ndarray | None = None, robot_radius: float = 0.225) -> None:
        """Stays put (checks ``dt`` like the built-in models)."""
        del robot_position, robot_radius
        self._check_step(dt)


@pytest.fixture
def registered() -> Iterator[None]:
    """StraightToGoal as planner ``straight`` and StandStill as pedestrian model ``still``."""
    PLANNERS.register("straight", StraightToGoal)
    PEDESTRIAN_MODELS.register("still", StandStill)
    yield
    PLANNERS.unregister("straight")
    PEDESTRIAN_MODELS.unregister("still")


def _episode(env, steps: int = 200) -> dict:
    """Step ``env`` with zero raw actions until the episode ends; the last info."""
    for _ in range(steps):
        _, _, terminated, truncated, info = env.step(np.zeros(env.action_space.shape, np.float32))
        if terminated or truncated:
            break
    return info


def test_a_registered_planner_runs_an_episode(registered: None) -> None:
    """A planner registered in one line runs a whole episode as ``policy=straight`` and reaches the goal."""
    from mjnav.envs.gym_env import NavGymEnv
    from mjnav.eval.policies import load_policy

    env = NavGymEnv("stage1", overrides=["layout.start_goal_max_distance=6.0"], seed=0)
    try:
        agent = load_policy("straight")
        agent.begin(env.task, 11)
        env.reset(options={"episode_seed": 11})
        assert isinstance(agent.planner.planner, StraightToGoal)
        assert _episode(env)["outcome"] == "success"
    finally:
        env.close()


def test_a_registered_pedestrian_model_runs_an_episode(registered: None) -> None:
    """A pedestrian model registered in one line is selected by ``crowd.model`` and its crowd stands still."""
    from mjnav.envs.gym_env import NavGymEnv

    env = NavGymEnv("stage5", overrides=["crowd.model=still"], seed=0)
    try:
        env.task.planner = make_planner("mpc_goal")
        env.reset(options={"episode_seed": 3})
        sim = env.task.sim
        assert isinstance(sim.pedestrians, StandStill) and len(sim.pedestrians.positions) > 0
        before = sim.pedestrians.positions
        info = _episode(env, steps=30)
        assert info["outcome"] in ("running", "success", "collision", "timeout")
        assert np.array_equal(sim.pedestrians.positions, before)
    finally:
        env.close()


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
    """Planners, pedestrian models, designs, LiDAR backends and robots share one registry shape."""
    groups = {registry.group: registry for registry in (PLANNERS, PEDESTRIAN_MODELS, DESIGNS, LIDAR_BACKENDS, ROBOTS)}
    assert all(isinstance(r, Registry) for r in groups.values())
    assert set(groups) == {"mjnav.planners", "mjnav.pedestrian_models", "mjnav.designs", "mjnav.lidar_backends",
                           "mjnav.robots"}
    assert {"mpc_goal", "teb", "dwa", "random_jerk"} <= set(PLANNERS.names())
    assert set(PEDESTRIAN_MODELS.names()) >= {"random_walk", "social_force"}
    assert set(DESIGNS.names()) >= {"ours", "design1", "design4"}
    assert set(LIDAR_BACKENDS.names()) >= {"analytic", "mujoco"} and "omni" in ROBOTS


def test_a_registered_robot_is_built_by_name() -> None:
    """``robot.model`` picks the registered robot entity (here the omni robot under another name)."""
    from mjnav.entities.robot import OmniRobot
    from mjnav.sim import NavSim

    built = []

    def tagged(robot, lidar, rangefinders=True):  # noqa: ANN001, ANN202 - the factory signature
        built.append(robot.model)
        return OmniRobot(robot, lidar, rangefinders=rangefinders)

    ROBOTS.register("omni_tagged", tagged)
    try:
        sim = NavSim(load_task("stage1", ["robot.model=omni_tagged"]))
        assert isinstance(sim.robot, OmniRobot) and built == ["omni_tagged"]
    finally:
        ROBOTS.unregister("omni_tagged")
