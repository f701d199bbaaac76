"""Privileged inputs for an asymmetric critic (training only; not in the paper).

With ``task.observation.critic_pedestrians = K > 0`` every step reports, beside the policy's
observation (spec §6), the ground truth of the K pedestrians nearest to the robot: what the scan
shows only as a region changing by a few centimetres between frames. The rsl-rl adapter gives these
values to the critic alone (``obs_groups``: actor ``policy``, critic ``policy`` + ``critic``), so
the trained actor, the exported policy and every evaluation still see the paper's observation.

Per pedestrian, :data:`PEDESTRIAN_FEATURES` values, nearest surface first::

    [x/10, y/10, v_x, v_y, r, 1]

with ``(x, y)`` its centre relative to the robot (metres), ``(v_x, v_y)`` its velocity (m/s,
differenced over one control period by :class:`CrowdTracker`; 0 when first seen), both in the
observation's axes (world, or turned so that the goal lies at angle 0 with
``observation.frame=goal``), ``r`` its radius (metres) and a 1 marking a present pedestrian.
Missing slots (fewer than K pedestrians) are all zeros.
"""

from __future__ import annotations

import math

import numpy as np

__all__ = ["PEDESTRIAN_FEATURES", "CrowdTracker", "critic_size", "pedestrian_features"]

PEDESTRIAN_FEATURES = 6
"""Values per pedestrian in :func:`pedestrian_features`."""

_POSITION_SCALE = 10.0  # metres, as the observation's point distances


def critic_size(pedestrians: int) -> int:
    """Length of the privileged critic input for ``pedestrians`` slots (0: none)."""
    return PEDESTRIAN_FEATURES * pedestrians


class CrowdTracker:
    """Pedestrian velocities from positions seen one control step apart (zeros at first sight)."""

    def __init__(self) -> None:
        """An empty tracker: the first positions it sees get zero velocities."""
        self._seen: tuple[float, np.ndarray] | None = None  # (time, positions) at the last update
        self.velocities = np.zeros((0, 2))

    def reset(self) -> None:
        """Forget the crowd seen so far (a new episode)."""
        self._seen = None
        self.velocities = np.zeros((0, 2))

    def update(self, time: float, positions: np.ndarray) -> np.ndarray:
        """Velocities (P, 2), m/s, of ``positions`` (P, 2) at ``time`` (s); calling twice at the same
        time keeps the estimate, a changed count starts again from zeros."""
        seen = self._seen
        if seen is None or seen[1].shape != positions.shape:
            self.velocities = np.zeros_like(positions)
        elif time > seen[0] + 1e-9:
            self.velocities = (positions - seen[1]) / (time - seen[0])
        else:
            return self.velocities
        self._seen = (time, positions.copy())
        return self.velocities


def pedestrian_features(
    position: np.ndarray, circles: np.ndarray, velocities: np.ndarray, count: int, rotation: float = 0.0
) -> np.ndarray:
    """The ``count`` nearest pedestrians as the critic sees them (module docstring).

    Args:
        position: (2,) robot centre, metres (world).
        circles: (P, 3) pedestrians ``[x, y, r]``, metres (world).
        velocities: (P, 2) their velocities, m/s (world).
        count: Slots K (>= 0); the nearest K by surface distance, the rest zeros.
        rotation: Angle (rad) of the observation's x axis in the world.

    Returns:
        (K·6,) float32.

    Raises:
        ValueError: Shapes that do not match, or a negative ``count``.
    """
    circles = np.asarray(circles, dtype=np.float64).reshape(-1, 3) if np.size(circles) else np.zeros((0, 3))
    velocities = np.asarray(velocities, dtype=np.float64).reshape(-1, 2) if np.size(velocities) else np.zeros((0, 2))
    if count < 0:
        raise ValueError(f"count must be >= 0, got {count}")
    if len(velocities) != len(circles):
        raise ValueError(f"{len(velocities)} velocities for {len(circles)} pedestrians")
    out = np.zeros((count, PEDESTRIAN_FEATURES), dtype=np.float32)
    if count == 0 or len(circles) == 0:
        return out.ravel()
    c, s = math.cos(rotation), math.sin(rotation)
    turn = np.array([[c, s], [-s, c]])  # world -> observation axes
    relative = circles[:, :2] - np.asarray(position, dtype=np.float64)[:2]
    order = np.argsort(np.hypot(relative[:, 0], relative[:, 1]) - circles[:, 2], kind="stable")[:count]
    k = len(order)
    out[:k, 0:2] = relative[order] @ turn.T / _POSITION_SCALE
    out[:k, 2:4] = velocities[order] @ turn.T
    out[:k, 4] = circles[order, 2]
    out[:k, 5] = 1.0
    return out.ravel()
