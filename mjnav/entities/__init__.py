"""Composer entities: the arena, the crowd and the robot.

Robots are looked up by name in :data:`ROBOTS` (``robot.model``, default ``omni``); a factory is
called as ``factory(robot_config, lidar_config, rangefinders)`` with the task's
:class:`~mjnav.schema.RobotConfig` and :class:`~mjnav.schema.LidarConfig` and whether to compile
the rangefinder sensors, and returns an entity with :class:`~mjnav.entities.robot.OmniRobot`'s
interface (the simulation drives it through the reference/tracking methods and reads its state).
Outside packages add robots through the entry-point group ``mjnav.robots``.
"""

from __future__ import annotations

from mjnav.entities.robot import OmniRobot
from mjnav.registry import Registry
from mjnav.schema import ConfigError, LidarConfig, RobotConfig

__all__ = ["ROBOTS", "make_robot"]

#: Robot entities by ``robot.model`` name.
ROBOTS: Registry[OmniRobot] = Registry("robot", "mjnav.robots")
ROBOTS.register("omni", OmniRobot, config=RobotConfig, source="builtin")


def make_robot(robot: RobotConfig, lidar: LidarConfig, rangefinders: bool = True) -> OmniRobot:
    """The robot entity named by ``robot.model``, built from its config (not compiled yet).

    Raises:
        ConfigError: An unknown model name (known names and the closest in the message).
    """
    if robot.model not in ROBOTS:
        raise ConfigError(f"robot.model: {ROBOTS.unknown_message(robot.model)}")
    return ROBOTS.get(robot.model).factory(robot, lidar, rangefinders=rangefinders)
