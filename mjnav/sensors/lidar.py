"""Planar 360° LiDAR with two interchangeable backends (spec §2).

Both backends return the **noise-free** ranges (metres, ``max_range`` where nothing is hit)
of the beams ``beam_angles(beams)`` (beam 0 along +x, counter-clockwise) cast horizontally
from the robot centre at LiDAR height; the simulation adds the Gaussian noise, so the backends
can be compared exactly.

- ``analytic``: exact 2-D casting (:func:`mjnav.geometry.raycast.cast_uniform_rays_kernel`) against the
  wall faces and obstacle edges (``segments``) and the pedestrian circles (``circles``).
- ``mujoco``: MuJoCo's own ray casting on the compiled scene, evaluated once per call (never
  inside ``mj_step``: the simulation disables sensors while stepping). ``method="multiray"``
  casts all beams with one ``mj_multiRay`` from the robot centre (the robot's body excluded,
  exactly the rangefinder semantics); ``method="sensor"`` evaluates the rangefinder sensors
  (``ray_000`` ...) with ``mj_sensorPos``. Both read the current kinematics (``geom_xpos``),
  so call them after the physics is synchronised (``mj_step1``/``mj_kinematics``/``mj_forward``).

:func:`mjnav.sensors.make_lidar` picks the backend named by ``LidarConfig.backend``.
"""

from __future__ import annotations

from typing import TYPE_CHECKING, Literal, Protocol

import mujoco
import numpy as np
from dm_control import mjcf

from mjnav.geometry.raycast import beam_angles, beam_trig, cast_uniform_rays_kernel
from mjnav.schema import LidarConfig

if TYPE_CHECKING:
    from mjnav.entities.robot import OmniRobot

__all__ = ["AnalyticLidar", "Lidar", "MujocoLidar"]

_NO_SEGMENTS = np.zeros((0, 4))
_NO_CIRCLES = np.zeros((0, 3))


class Lidar(Protocol):
    """A noise-free planar scanner."""

    name: str

    def scan(
        self, physics: mjcf.Physics | None, origin: np.ndarray, segments: np.ndarray | None,
        circles: np.ndarray | None,
    ) -> np.ndarray:
        """(B,) noise-free ranges from ``origin`` (2,), metres."""


class AnalyticLidar:
    """Exact 2-D ray casting against segments and circles (the physics is not read)."""

    name = "analytic"

    def __init__(self, config: LidarConfig) -> None:
        """Precomputes the beam directions.

        Args:
            config: Beam count and ``max_range`` (metres).
        """
        self.config = config
        self._cos, self._sin, _ = beam_trig(beam_angles(config.beams))  # shared by the process's LiDARs
        self._max_range = float(config.max_range)

    def scan(self, physics: mjcf.Physics | None, origin: np.ndarray, segments: np.ndarray | None = None,
             circles: np.ndarray | None = None) -> np.ndarray:
        """Noise-free ranges.

        Args:
            physics: Unused (kept for a common interface).
            origin: (2,) robot centre, metres.
            segments: (S, 4) contiguous float64 ``[x0, y0, x1, y1]`` walls and obstacle edges.
            circles: (C, 3) contiguous float64 ``[x, y, r]`` pedestrians.

        Returns:
            (B,) float64 ranges in [0, max_range], metres.
        """
        del physics
        return cast_uniform_rays_kernel(  # the beams are beam_angles(B): circles culled by angle
            float(origin[0]), float(origin[1]), self._cos, self._sin,
            _NO_SEGMENTS if segments is None else segments, _NO_CIRCLES if circles is None else circles,
            self._max_range,
        )


class MujocoLidar:
    """MuJoCo ray casting on the compiled scene (the robot's rangefinder semantics)."""

    name = "mujoco"

    def __init__(
        self, config: LidarConfig, robot: OmniRobot, method: Literal["multiray", "sensor"] = "multiray"
    ) -> None:
        """Binds the backend to a robot entity.

        Args:
            config: Beam count, ``max_range`` and ``height`` (metres).
            robot: The :class:`~mjnav.entities.robot.OmniRobot` carrying the rangefinders.
            method: ``multiray`` (one ``mj_multiRay``) or ``sensor`` (``mj_sensorPos``).
        """
        if method not in ("multiray", "sensor"):
            raise ValueError(f"method {method!r}: use 'multiray' or 'sensor'")
        self.config = config
        self.method = method
        self._robot = robot
        angles = beam_angles(config.beams)
        dirs = np.stack([np.cos(angles), np.sin(angles), np.zeros_like(angles)], axis=1)
        self._dirs = np.ascontiguousarray(dirs.ravel())
        self._dist = np.zeros(config.beams)
        self._geomid = np.zeros(config.beams, dtype=np.int32)
        self._pnt = np.array([0.0, 0.0, config.height])
        self._max_range = float(config.max_range)
        self._model = None

    def _bind(self, physics: mjcf.Physics) -> None:
        model = physics.model.ptr
        if self._model is model:
            return
        self._body = self._robot.body_id(physics)
        if self.method == "sensor":
            if not self._robot.rangefinders:
                raise ValueError("method='sensor' needs a robot built with rangefinders")
            ids = np.asarray(physics.bind(self._robot.rangefinders).element_id, dtype=np.int64)
            adr = model.sensor_adr[ids].astype(np.int64)
            if not np.array_equal(adr, np.arange(adr[0], adr[0] + len(adr))):
                raise RuntimeError("rangefinder sensors are not contiguous")
            self._sensor_slice = slice(int(adr[0]), int(adr[0]) + len(adr))
        self._model = model

    def scan(self, physics: mjcf.Physics, origin: np.ndarray, segments: np.ndarray | None = None,
             circles: np.ndarray | None = None) -> np.ndarray:
        """Noise-free ranges from the current MuJoCo kinematics.

        Args:
            physics: The physics, synchronised (``geom_xpos`` current).
            origin: (2,) robot centre, metres (``multiray``; ``sensor`` uses the sites).
            segments: Unused.
            circles: Unused.

        Returns:
            (B,) float64 ranges in [0, max_range], metres (no hit reads max_range).
        """
        del segments, circles
        self._bind(physics)
        model, data = physics.model.ptr, physics.data.ptr
        if self.method == "multiray":
            self._pnt[0], self._pnt[1] = origin[0], origin[1]
            mujoco.mj_multiRay(model, data, self._pnt, self._dirs, None, 1, self._body, self._geomid,
                               self._dist, None, len(self._dist), self._max_range)
            dist = self._dist.copy()
        else:
            flags = model.opt.disableflags
            model.opt.disableflags = flags & ~int(mujoco.mjtDisableBit.mjDSBL_SENSOR)
            try:
                mujoco.mj_sensorPos(model, data)
            finally:
                model.opt.disableflags = flags
            dist = data.sensordata[self._sensor_slice].copy()
        dist[(dist < 0) | (dist > self._max_range)] = self._max_range
        return dist
