"""Observation of spec §6: 133 values per frame, 3 frames stacked → 399 (float32).

Per frame: a polygon block (60 boundary points as interleaved r̂, θ̂ → 120 values)
and a 13-value state block::

    [dθ/π, ρ/40, v_x/2.5, v_y/2.5, region_ok,
     θ(Q_s)/π, θ(Q_l)/π, (|Q_s|+R)/10, (|Q_l|+R)/10,
     θ(Q*_1)/π, θ(Q*_N)/π, (|Q*_1|+R)/10, (|Q*_N|+R)/10]

The stack is ``[polygon_{t-2}, polygon_{t-1}, polygon_t, state_{t-2}, state_{t-1}, state_t]``
(oldest first); at reset every slot holds the first frame.
"""

from __future__ import annotations

import dataclasses
import math

import numpy as np

__all__ = [
    "DISTANCE_SCALE",
    "POLYGON_SIZE",
    "STATE_SIZE",
    "FrameStack",
    "Plan",
    "observation_size",
    "polygon_block",
    "state_block",
]

DISTANCE_SCALE = 40.0  # ρ normaliser, metres
SPEED_SCALE = 2.5  # velocity normaliser, m/s (per-axis limit)
RANGE_SCALE = 10.0  # point-distance normaliser, metres (LiDAR range)
POLYGON_SIZE = 120
STATE_SIZE = 13


@dataclasses.dataclass(frozen=True)
class Plan:
    """The last action and MPC plan, as the observation needs them.

    Attributes:
        q_s, q_l: Action points relative to the robot at action time (network's own Q_l), metres.
        q1, qn: Planned p₁ and p_N relative to the robot at planning time, metres.
        q1_world, qn_world: The same planned points in the world frame, metres.
    """

    q_s: np.ndarray
    q_l: np.ndarray
    q1: np.ndarray
    qn: np.ndarray
    q1_world: np.ndarray
    qn_world: np.ndarray


def observation_size(frames: int = 3, points: int = 60) -> int:
    """Length of the stacked observation (399 for the defaults)."""
    return frames * (2 * points + STATE_SIZE)


def polygon_block(boundary: np.ndarray, inflation: float) -> np.ndarray:
    """Interleaved (r̂, θ̂) of the resampled boundary points.

    Args:
        boundary: (M, 2) points as (r, θ) with r the shrunk distance in metres and θ in [0, 2π).
        inflation: R_inf in metres, added back to r.

    Returns:
        (2M,) float64 with r̂ = clip((r + R_inf)/10, 0, 1) and θ̂ = θ/2π.
    """
    out = np.empty(2 * len(boundary))
    r_hat = (boundary[:, 0] + inflation) / RANGE_SCALE
    np.maximum(r_hat, 0.0, out=r_hat)
    out[0::2] = np.minimum(r_hat, 1.0, out=r_hat)
    out[1::2] = boundary[:, 1] / (2.0 * math.pi)
    return out


def _angle_between(a: np.ndarray, b: np.ndarray) -> float:
    """Signed angle from vector a to vector b in [−π, π] (0 for a zero vector)."""
    cross = a[0] * b[1] - a[1] * b[0]
    dot = a[0] * b[0] + a[1] * b[1]
    return math.atan2(cross, dot)


def _polar(p: np.ndarray, inflation: float) -> tuple[float, float]:
    return math.atan2(p[1], p[0]) / math.pi, (math.hypot(p[0], p[1]) + inflation) / RANGE_SCALE


def _heading_error(position, velocity, goal, plan: Plan | None, mode: str) -> float:
    if mode == "mpc" and plan is not None:
        return _angle_between(plan.qn_world - plan.q1_world, goal - plan.q1_world)
    return _angle_between(velocity, goal - position)


def state_block(
    position: np.ndarray,
    velocity: np.ndarray,
    goal: np.ndarray,
    region_ok: bool,
    plan: Plan | None,
    inflation: float,
    angle_mode: str = "mpc",
) -> np.ndarray:
    """The 13 state values of one frame.

    Args:
        position: Robot position, world frame, metres.
        velocity: Robot velocity, m/s.
        goal: Goal position, world frame, metres.
        region_ok: The free-space polygon succeeded for this frame's scan.
        plan: The last successful plan, or None at reset or after a failed plan.
        inflation: R_inf, metres.
        angle_mode: ``mpc`` (code) or ``velocity`` (paper) for the heading-error term.

    Returns:
        (13,) float64.
    """
    out = np.empty(STATE_SIZE)
    out[0] = _heading_error(position, velocity, goal, plan, angle_mode) / math.pi
    out[1] = math.hypot(*(goal - position)) / DISTANCE_SCALE
    out[2:4] = velocity / SPEED_SCALE
    out[4] = 1.0 if region_ok else 0.0
    if plan is None:
        out[5:7] = 0.0
        out[7:9] = inflation / RANGE_SCALE
        out[9:11] = 0.0
        out[11:13] = inflation / RANGE_SCALE
        return out
    (out[5], out[7]), (out[6], out[8]) = _polar(plan.q_s, inflation), _polar(plan.q_l, inflation)
    (out[9], out[11]), (out[10], out[12]) = _polar(plan.q1, inflation), _polar(plan.qn, inflation)
    return out


class FrameStack:
    """Keeps the last ``frames`` polygon and state blocks and lays them out as spec §6."""

    def __init__(self, frames: int = 3, points: int = 60) -> None:
        """Create an empty stack for ``frames`` frames of ``points`` boundary points."""
        self._polygons = np.zeros((frames, 2 * points))
        self._states = np.zeros((frames, STATE_SIZE))

    def reset(self, polygon: np.ndarray, state: np.ndarray) -> np.ndarray:
        """Fill every slot with the first frame and return the observation."""
        self._polygons[:] = polygon
        self._states[:] = state
        return self.observation()

    def push(self, polygon: np.ndarray, state: np.ndarray) -> np.ndarray:
        """Drop the oldest frame, append this one and return the observation."""
        self._polygons[:-1] = self._polygons[1:]
        self._states[:-1] = self._states[1:]
        self._polygons[-1] = polygon
        self._states[-1] = state
        return self.observation()

    def observation(self) -> np.ndarray:
        """Stacked observation, float32: polygon blocks oldest first, then state blocks."""
        return np.concatenate([self._polygons.ravel(), self._states.ravel()]).astype(np.float32)
