"""Sensors: the planar LiDAR and its backends.

LiDAR backends are looked up by name in :data:`LIDAR_BACKENDS` (``lidar.backend``); a factory is
called as ``factory(lidar_config, robot, method)`` with the :class:`~mjnav.schema.LidarConfig`, the
robot entity and the ``mujoco`` backend's evaluation method, and returns a
:class:`~mjnav.sensors.lidar.Lidar`. Outside packages add backends through the entry-point group
``mjnav.lidar_backends``.
"""

from __future__ import annotations

from typing import TYPE_CHECKING

from mjnav.registry import Registry
from mjnav.schema import ConfigError, LidarConfig
from mjnav.sensors.lidar import AnalyticLidar, Lidar, MujocoLidar

if TYPE_CHECKING:
    from mjnav.entities.robot import OmniRobot

__all__ = ["LIDAR_BACKENDS", "make_lidar", "make_lidars"]

#: LiDAR backends by ``lidar.backend`` name.
LIDAR_BACKENDS: Registry[Lidar] = Registry("LiDAR backend", "mjnav.lidar_backends")


def _analytic(config: LidarConfig, robot: OmniRobot | None, method: str) -> AnalyticLidar:
    """Exact 2-D casting (needs neither the robot entity nor a method)."""
    del robot, method
    return AnalyticLidar(config)


def _mujoco(config: LidarConfig, robot: OmniRobot | None, method: str) -> MujocoLidar:
    """MuJoCo ray casting from the robot entity (``method``: ``multiray`` or ``sensor``)."""
    if robot is None:
        raise ValueError("the mujoco LiDAR backend needs the robot entity")
    return MujocoLidar(config, robot, method)  # type: ignore[arg-type]


LIDAR_BACKENDS.register("analytic", _analytic, config=LidarConfig, source="builtin")
LIDAR_BACKENDS.register("mujoco", _mujoco, config=LidarConfig, source="builtin")


def make_lidar(config: LidarConfig, robot: OmniRobot | None = None, method: str = "multiray",
               backend: str | None = None) -> Lidar:
    """The backend named by ``backend`` (default ``config.backend``).

    Args:
        config: LiDAR config.
        robot: The robot entity (required by the ``mujoco`` backend).
        method: ``mujoco`` backend evaluation method (``multiray`` or ``sensor``).
        backend: Backend name; default ``config.backend``.

    Raises:
        ConfigError: An unknown backend name (known names and the closest in the message).
        ValueError: A backend that needs the robot entity got none.
    """
    name = config.backend if backend is None else backend
    if name not in LIDAR_BACKENDS:
        raise ConfigError(f"lidar.backend: {LIDAR_BACKENDS.unknown_message(name)}")
    return LIDAR_BACKENDS.get(name).factory(config, robot, method)


def make_lidars(config: LidarConfig, robot: OmniRobot, method: str = "multiray") -> dict[str, Lidar]:
    """Every built-in backend and the configured one, by name (to compare backends on one scene)."""
    names = [n for n in LIDAR_BACKENDS.names() if LIDAR_BACKENDS.get(n).source == "builtin"]
    return {name: make_lidar(config, robot, method, name) for name in dict.fromkeys([config.backend, *names])}
