"""The LiDAR tracks as planner obstacles: constant-velocity prediction of each tracked pedestrian.

:attr:`mjnav.planners.base.PlannerInput.tracks` holds ``[x, y, vx, vy, r]`` rows (world frame,
metres, m/s). The planners that read them (``planner.tracks=true`` for ``teb``, ``dwa`` and
``mpc_goal``; ``mpc_tracked`` always) predict every track at constant velocity over their own
horizon and treat the predicted discs as obstacles in addition to the scan: time-indexed where the
planner has time along its trajectory (TEB's poses, DWA's rollouts), swept over the horizon where
it has not (the convex region of ``mpc_goal``: :func:`scan_with_discs`). TEB and DWA leave the
scan points a track explains to its prediction (:func:`untracked_points`).
"""

from __future__ import annotations

import numpy as np

from mjnav.geometry.raycast import cast_rays

__all__ = ["predicted_discs", "relative_tracks", "scan_with_discs", "untracked_points"]


def relative_tracks(tracks: np.ndarray | None, position: np.ndarray) -> np.ndarray:
    """(T, 5) ``[x, y, vx, vy, r]`` with centres relative to ``position`` (metres); (0, 5) for None."""
    if tracks is None:
        return np.zeros((0, 5))
    rows = np.array(tracks, dtype=np.float64).reshape(-1, 5)
    rows[:, :2] -= np.asarray(position, dtype=np.float64)
    return rows


def predicted_discs(tracks: np.ndarray, times: np.ndarray) -> np.ndarray:
    """Constant-velocity discs of every track at every time.

    Args:
        tracks: (T, 5) ``[x, y, vx, vy, r]`` (any frame; :func:`relative_tracks` for the robot's),
            metres and m/s.
        times: (K,) seconds ahead of the tracks' time.

    Returns:
        (K, T, 3) ``[x, y, r]`` in the tracks' frame, metres.
    """
    times = np.asarray(times, dtype=np.float64).reshape(-1)
    centres = tracks[None, :, :2] + tracks[None, :, 2:4] * times[:, None, None]
    radii = np.broadcast_to(tracks[None, :, 4:5], (len(times), len(tracks), 1))
    return np.concatenate([centres, radii], axis=2)


def scan_with_discs(scan: np.ndarray, angles: np.ndarray, discs: np.ndarray, max_range: float,
                    keep_out: float) -> np.ndarray:
    """The scan with each beam also stopped by the predicted discs (robot at the origin).

    Discs whose surface comes within ``keep_out`` of the robot are left out: the robot cannot keep
    clear of them by staying in a convex region around itself (the scan still shows the pedestrian
    where it is now).

    Args:
        scan: (B,) ranges, metres.
        angles: (B,) beam angles, radians.
        discs: (..., 3) ``[x, y, r]`` relative to the robot, metres.
        max_range: The LiDAR's range, metres.
        keep_out: Metres (the region's inflation plus a margin).

    Returns:
        (B,) ranges, never longer than ``scan``'s.
    """
    circles = np.asarray(discs, dtype=np.float64).reshape(-1, 3)
    circles = circles[np.hypot(circles[:, 0], circles[:, 1]) - circles[:, 2] > keep_out]
    if len(circles) == 0:
        return np.asarray(scan, dtype=np.float64)
    ranges = cast_rays(np.zeros(2), angles, None, np.ascontiguousarray(circles), max_range)
    return np.minimum(np.asarray(scan, dtype=np.float64), ranges)


def untracked_points(points: np.ndarray, tracks: np.ndarray, pad: float) -> np.ndarray:
    """The scan points that no track explains: those farther than its radius + ``pad`` from every
    track's centre (both relative to the robot, metres). A planner that predicts the tracks then
    keeps the static world from the scan without also freezing the tracked pedestrians in it.

    Args:
        points: (M, 2) scan points, metres.
        tracks: (T, 5) ``[x, y, vx, vy, r]`` in the points' frame.
        pad: Metres beyond each track's radius (its estimation error).

    Returns:
        (M', 2) the points kept, in their order.
    """
    if len(points) == 0 or len(tracks) == 0:
        return points
    gap = np.hypot(points[:, None, 0] - tracks[None, :, 0], points[:, None, 1] - tracks[None, :, 1])
    return points[np.all(gap > tracks[None, :, 4] + pad, axis=1)]
