"""Scan helpers of the baselines: obstacle points of a LiDAR scan, one per angular sector.

All positions are in the robot frame (the robot never rotates, so its axes are the world
axes); units are SI. The limits and the velocity tracker the baselines share live in
:mod:`mjnav.control.dynamics`.
"""

from __future__ import annotations

import numpy as np

__all__ = ["nearest_per_sector", "scan_points"]


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
