"""The robot's motion model, its limits and its tracking laws, written once.

The robot is a triple integrator per axis driven by a jerk held over one control period t_c
(spec §1): ``p⁺ = p + v t + a t²/2 + j t³/6``, ``v⁺ = v + a t + j t²/2``, ``a⁺ = a + j t``.
The MPC predicts with it (:func:`transition_matrices`, :func:`rollout`), the action layer and the
QP bound its reach with it (:func:`coast`, :func:`jerk_travel`), the robot entity follows it as
its reference (:func:`integrate`) and the random baseline keeps its velocity inside the limits
with it. :class:`Limits` are the per-axis bounds every planner reads, the MPC and its QP included
(:attr:`mjnav.control.mpc.MpcConfig.limits`, :meth:`Limits.bounds`); their defaults are the
task schema's (:class:`mjnav.schema.RobotConfig` and its neighbours), so each number is written once.

Two tracking laws live here too: :func:`track_velocity` (the jerk that drives the velocity to a
command, used by the task's escape and the DWA/TEB baselines) and :func:`tracking_force` (the
force per unit mass that makes the MuJoCo body follow the reference; the Python substep loop of
:mod:`mjnav.entities.robot` and the compiled one of :mod:`mjnav.fused` both call it).

The scalar functions are numba-compiled so compiled kernels (QP rows, action reach) call the same
code as Python; the operation order of each is the one the recorded episodes were made with
(``tests/test_replay.py``): do not "simplify" ``a*t*t/2`` into ``a*(t*t/2)``.
Units are SI; positions in the robot frame (the robot never rotates).
"""

from __future__ import annotations

import dataclasses
from typing import Protocol

import numpy as np
from numba import njit

from mjnav.geometry.region import RegionConfig
from mjnav.schema import LidarConfig, RobotConfig, TimingConfig

__all__ = [
    "Limits",
    "TaskSections",
    "brake",
    "clamp",
    "coast",
    "escape",
    "integrate",
    "jerk_travel",
    "rollout",
    "rollout_kernel",
    "track_velocity",
    "tracking_force",
    "transition_matrices",
]


class TaskSections(Protocol):
    """The sections of a :class:`mjnav.config.TaskConfig` that :meth:`Limits.from_task` reads."""

    timing: TimingConfig
    robot: RobotConfig
    region: RegionConfig
    lidar: LidarConfig


@dataclasses.dataclass(frozen=True)
class Limits:
    """The robot's per-axis limits and sizes, as the planners, the MPC and its QP read them.

    The defaults are those of the task config's sections (robot, timing, region, lidar).

    Attributes:
        control_period: t_c, seconds.
        v_max: Per-axis velocity limit, m/s.
        a_max: Per-axis acceleration limit, m/s².
        j_max: Per-axis jerk limit, m/s³.
        radius: Robot radius, metres.
        inflation: Safety radius R_inf (robot radius + margin), metres.
        max_range: LiDAR range, metres.
    """

    control_period: float = TimingConfig.control_period
    v_max: float = RobotConfig.v_max
    a_max: float = RobotConfig.a_max
    j_max: float = RobotConfig.j_max
    radius: float = RobotConfig.radius
    inflation: float = RegionConfig.inflation
    max_range: float = LidarConfig.max_range

    @classmethod
    def from_task(cls, config: TaskSections) -> Limits:
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

    def bounds(self) -> np.ndarray:
        """The ``(3,)`` per-axis bounds ``[j_max, v_max, a_max]`` (m/s³, m/s, m/s²), in the order the
        QP kernels of :mod:`mjnav.control.qp` read them."""
        return np.array([self.j_max, self.v_max, self.a_max])


# ---------------------------------------------------------------------------- motion model


@njit(cache=True)
def coast(v, a, t):  # noqa: ANN001, ANN201 - numba: floats or arrays
    """Travel ``v t + a t²/2`` over ``t`` seconds with zero jerk, metres (v m/s, a m/s²)."""
    return v * t + a * t * t / 2.0


@njit(cache=True)
def jerk_travel(j, t):  # noqa: ANN001, ANN201 - numba: floats or arrays
    """Travel ``j t³/6`` that a jerk ``j`` (m/s³) adds over ``t`` seconds, metres."""
    return j * t**3 / 6.0


@njit(cache=True)
def integrate(p, v, a, j, t):  # noqa: ANN001, ANN201 - numba: floats or arrays
    """The exact triple-integrator state after ``t`` seconds of constant jerk.

    Args:
        p, v, a: Position (m), velocity (m/s) and acceleration (m/s²); floats or arrays.
        j: Jerk, m/s³.
        t: Duration, s.

    Returns:
        ``(p, v, a)`` after ``t``.
    """
    return (p + v * t + a * t * t / 2.0 + j * t**3 / 6.0, v + a * t + j * t * t / 2.0, a + j * t)


@njit(cache=True)
def rollout(s: np.ndarray, jerks: np.ndarray, dt: float) -> np.ndarray:  # pragma: no cover - numba
    """States x_1..x_N under a jerk sequence (:func:`rollout_kernel`).

    Python calls go through this wrapper and jitted callers call the kernel (a cached kernel
    called from Python after cached callers loaded it fails to box its result; see
    ``tests/geometry/test_polygon.py::test_public_kernels_work_after_cached_jitted_callers``).

    Args:
        s: ``(3, 2)`` start state, rows p [m], v [m/s], a [m/s²].
        jerks: ``(N, 2)`` jerks, m/s³.
        dt: Step, s.

    Returns:
        ``(N, 3, 2)`` states (rows p, v, a).
    """
    return rollout_kernel(s, jerks, dt)


@njit(cache=True)
def rollout_kernel(s: np.ndarray, jerks: np.ndarray, dt: float) -> np.ndarray:  # pragma: no cover - numba
    """States x_1..x_N under a jerk sequence, by repeated :func:`integrate` (for jitted callers).

    Args:
        s: ``(3, 2)`` start state, rows p [m], v [m/s], a [m/s²].
        jerks: ``(N, 2)`` jerks, m/s³.
        dt: Step, s.

    Returns:
        ``(N, 3, 2)`` states (rows p, v, a).
    """
    n = jerks.shape[0]
    out = np.empty((n, 3, 2))
    for d in range(2):
        p, v, a = s[0, d], s[1, d], s[2, d]
        for k in range(n):
            p, v, a = integrate(p, v, a, jerks[k, d], dt)
            out[k, 0, d], out[k, 1, d], out[k, 2, d] = p, v, a
    return out


def transition_matrices(dt: float) -> tuple[np.ndarray, np.ndarray]:
    """One step of the per-axis model as ``x⁺ = F x + G j`` with x = (p, v, a).

    Args:
        dt: Step, s.

    Returns:
        ``F`` (3, 3) and ``G`` (3,).
    """
    f = np.array([[1.0, dt, dt**2 / 2.0], [0.0, 1.0, dt], [0.0, 0.0, 1.0]])
    g = np.array([dt**3 / 6.0, dt**2 / 2.0, dt])
    return f, g


# ---------------------------------------------------------------------------- tracking laws


def clamp(x: float, limit: float) -> float:
    """``min(max(x, -limit), limit)`` with Python's semantics (NaN stays NaN), numba-safe."""
    lo = -limit
    y = lo if lo > x else x  # noqa: FURB136 - numba's max/min may treat NaN differently
    return limit if limit < y else y  # noqa: FURB136


def tracking_force(u: float, v_ref: float, v: float, p_ref: float, p: float, kv: float, kp: float) -> float:
    """Force per unit mass (m/s²) that makes a body follow a reference along one axis.

    ``u + kv·(v_ref − v)`` plus ``kp·(p_ref − p)`` when ``kp`` is non-zero: the planned
    acceleration u (m/s²) with velocity (kv, 1/s) and position (kp, 1/s²) feedback.
    """
    f = u + kv * (v_ref - v)
    if kp != 0.0:
        f += kp * (p_ref - p)
    return f


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
