"""Shared pieces of the baselines: limits, scan points and a jerk-limited velocity tracker.

The robot is a triple integrator per axis driven by jerk over one control period t_c
(spec §1). Baselines that think in velocities (DWA, the TEB band) reach the commanded velocity
through :func:`track_velocity`: a jerk-limited law that anticipates the velocity still gained
while the acceleration is brought back to zero, so it does not overshoot the velocity limit.

All positions are in the robot frame (the robot never rotates, so its axes are the world
axes); units are SI.
"""

from __future__ import annotations

import dataclasses
from typing import TYPE_CHECKING

import numpy as np

if TYPE_CHECKING:
    from mjnav.config import TaskConfig

__all__ = ["Limits", "brake", "escape", "nearest_per_sector", "scan_points", "track_velocity"]


@dataclasses.dataclass(frozen=True)
class Limits:
    """Robot limits used by a baseline.

    Attributes:
        control_period: t_c, seconds.
        v_max: Per-axis velocity limit, m/s.
        a_max: Per-axis acceleration limit, m/s².
        j_max: Per-axis jerk limit, m/s³.
        radius: Robot radius, metres.
        inflation: Safety radius R_inf (robot radius + margin), metres.
        max_range: LiDAR range, metres.
    """

    control_period: float = 0.1
    v_max: float = 2.5
    a_max: float = 4.0
    j_max: float = 8.0
    radius: float = 0.225
    inflation: float = 0.325
    max_range: float = 10.0

    @classmethod
    def from_task(cls, config: TaskConfig) -> Limits:
        """Limits of a :class:`mjnav.config.TaskConfig`."""
        return cls(
            control_period=config.timing.control_period,
            v_max=config.robot.v_max,
            a_max=config.robot.a_max,
            j_max=config.robot.j_max,
            radius=config.robot.radius,
            inflation=config.region.inflation,
            max_range=config.lidar.max_range,
        )


def scan_points(scan: np.ndarray, angles: np.ndarray, max_range: float) -> np.ndarray:
    """Obstacle points of a scan in the robot frame.

    Beams at (or beyond) the maximum range, including +inf, carry no obstacle.

    Args:
        scan: (B,) ranges, metres.
        angles: (B,) beam angles, radians.
        max_range: Sensor range, metres.

    Returns:
        (M, 2) points, metres (M may be 0).

    Raises:
        ValueError: Mismatched shapes or a NaN range (the planners brake and count it).
    """
    r = np.asarray(scan, dtype=np.float64).reshape(-1)
    th = np.asarray(angles, dtype=np.float64).reshape(-1)
    if r.shape != th.shape or np.isnan(r).any() or not np.all(np.isfinite(th)):
        raise ValueError(f"degenerate scan: {r.shape} ranges for {th.shape} angles or NaN values")
    hit = r < max_range - 1e-6
    r = np.maximum(r[hit], 0.0)
    return np.column_stack([r * np.cos(th[hit]), r * np.sin(th[hit])])


def nearest_per_sector(points: np.ndarray, sectors: int, reach: float) -> np.ndarray:
    """Subsample obstacle points: the nearest one per angular sector, within a reach.

    Args:
        points: (M, 2) points in the robot frame, metres.
        sectors: Number of equal angular sectors around the robot.
        reach: Points farther than this are dropped, metres.

    Returns:
        (≤ sectors, 2) points, metres.
    """
    if len(points) == 0:
        return points
    dist = np.hypot(points[:, 0], points[:, 1])
    keep = dist <= reach
    points, dist = points[keep], dist[keep]
    if len(points) == 0:
        return points
    sector = (np.floor((np.arctan2(points[:, 1], points[:, 0]) + np.pi) / (2 * np.pi) * sectors)).astype(int)
    order = np.lexsort((dist, sector))
    first = np.ones(len(order), dtype=bool)
    first[1:] = sector[order][1:] != sector[order][:-1]
    return points[order[first]]


def track_velocity(
    velocity: np.ndarray,
    accel: np.ndarray,
    v_ref: np.ndarray,
    limits: Limits,
    gain: float = 3.0,
    a_ref: np.ndarray | None = None,
) -> np.ndarray:
    """Jerk that drives the velocity to ``v_ref`` within the acceleration and jerk limits.

    Per axis: the velocity still gained while a jerk-limited ramp brings the acceleration to 0
    is ``a·|a|/(2·j_max)``; the desired acceleration is ``gain·(v_ref − v − that) + a_ref``,
    clipped to ±a_max, and the jerk reaches it in one period where the jerk limit allows.

    Args:
        velocity: (2,) current velocity, m/s.
        accel: (2,) current acceleration, m/s².
        v_ref: (2,) commanded velocity, m/s (clipped to ±v_max per axis).
        limits: Robot limits.
        gain: Velocity error gain, 1/s.
        a_ref: (2,) feed-forward acceleration, m/s² (default 0).

    Returns:
        (2,) jerk, m/s³, within ±j_max.
    """
    v_ref = np.clip(np.asarray(v_ref, dtype=np.float64), -limits.v_max, limits.v_max)
    ff = np.zeros(2) if a_ref is None else np.asarray(a_ref, dtype=np.float64)
    ramp = accel * np.abs(accel) / (2.0 * limits.j_max)
    a_des = np.clip(gain * (v_ref - velocity - ramp) + ff, -limits.a_max, limits.a_max)
    jerk = (a_des - accel) / limits.control_period
    return np.clip(jerk, -limits.j_max, limits.j_max)


def brake(velocity: np.ndarray, accel: np.ndarray, limits: Limits) -> np.ndarray:
    """Jerk that brings the robot to rest as fast as the limits allow, m/s³."""
    return track_velocity(velocity, accel, np.zeros(2), limits, gain=limits.a_max)


def escape(scan: np.ndarray, angles: np.ndarray, velocity: np.ndarray, accel: np.ndarray, limits: Limits,
           speed: float, band: float = 0.1) -> np.ndarray:
    """Jerk that backs the robot away from its nearest returns at ``speed`` m/s.

    The direction is minus the mean unit vector of the beams within ``band`` metres of the
    shortest one (so a corner pushes out of the corner); where they cancel, the robot brakes.

    Args:
        scan: (n,) ranges, metres.
        angles: (n,) beam angles, radians (robot frame).
        velocity: (2,) velocity, m/s.
        accel: (2,) acceleration, m/s².
        limits: Robot limits.
        speed: Escape speed, m/s.
        band: Beams this close to the shortest count, metres.

    Returns:
        (2,) jerk, m/s³, within ±j_max.
    """
    close = scan <= scan.min() + band
    push = -np.array([np.cos(angles[close]).mean(), np.sin(angles[close]).mean()])
    norm = float(np.hypot(*push))
    target = speed * push / norm if norm > 0.2 else np.zeros(2)
    return track_velocity(velocity, accel, target, limits, gain=limits.a_max)

