"""Tracker quality against ground truth (measurement only: never an input to the tracker).

Per control step, the reported tracks are matched one-to-one to the true pedestrian circles by
minimum total distance (Hungarian), pairs farther than ``match_distance`` (0.3 m) discarded.
A pedestrian is *in line of sight* when at least one LiDAR beam from the robot hits it first
(before any wall, obstacle or other pedestrian), and *near* when its centre is within
``near_distance`` (5 m) of the robot's centre. Metres, seconds, m/s.
"""

from __future__ import annotations

import dataclasses

import numpy as np
from scipy.optimize import linear_sum_assignment

from mjnav.geometry.raycast import cast_rays

__all__ = ["TrackingScore", "line_of_sight", "match_tracks"]


def line_of_sight(origin: np.ndarray, angles: np.ndarray, segments: np.ndarray, circles: np.ndarray,
                  max_range: float) -> np.ndarray:
    """Which pedestrians some beam hits first.

    Args:
        origin: (2,) robot centre, m.
        angles: (B,) beam angles, rad (world frame).
        segments: (S, 4) walls and obstacle edges, m.
        circles: (P, 3) pedestrians ``[x, y, r]``, m.
        max_range: LiDAR range, m.

    Returns:
        (P,) bool.
    """
    if len(circles) == 0:
        return np.zeros(0, dtype=bool)
    walls = cast_rays(origin, angles, segments, None, max_range)
    dx, dy = np.cos(angles)[:, None], np.sin(angles)[:, None]
    fx, fy = origin[0] - circles[None, :, 0], origin[1] - circles[None, :, 1]
    half_b = fx * dx + fy * dy
    disc = half_b**2 - (fx**2 + fy**2 - circles[None, :, 2] ** 2)
    root = np.sqrt(np.maximum(disc, 0.0))
    t = np.where(-half_b - root >= 0.0, -half_b - root, -half_b + root)
    t = np.where((disc >= 0.0) & (t >= 0.0), t, np.inf)  # (B, P)
    first = np.argmin(t, axis=1)
    hit = t[np.arange(len(angles)), first] < walls
    seen = np.zeros(len(circles), dtype=bool)
    seen[first[hit]] = True
    return seen


def match_tracks(tracks: np.ndarray, truth: np.ndarray, match_distance: float = 0.3) -> np.ndarray:
    """One-to-one matching of tracks to true pedestrians.

    Args:
        tracks: (n, >=2) track rows starting ``[x, y]``, m.
        truth: (P, >=2) true centres, m.
        match_distance: Largest matched distance, m.

    Returns:
        (P,) index of the matched track per pedestrian, -1 where none.
    """
    out = np.full(len(truth), -1, dtype=np.int64)
    if len(tracks) == 0 or len(truth) == 0:
        return out
    dist = np.hypot(truth[:, None, 0] - tracks[None, :, 0], truth[:, None, 1] - tracks[None, :, 1])
    rows, cols = linear_sum_assignment(np.where(dist <= match_distance, dist, 1e6))
    keep = dist[rows, cols] <= match_distance
    out[rows[keep]] = cols[keep]
    return out


@dataclasses.dataclass
class TrackingScore:
    """Counts accumulated over steps (and episodes) of one stage.

    Attributes:
        match_distance: Largest matched distance, m.
        near_distance: Radius of the "near" disc around the robot, m.
    """

    match_distance: float = 0.3
    near_distance: float = 5.0
    tracks: int = 0
    truths: int = 0
    matched: int = 0
    near_seen: int = 0
    near_seen_matched: int = 0
    pos_sq: float = 0.0
    vel_sq: float = 0.0
    vel_count: int = 0
    switches: int = 0
    _last_id: dict[int, int] = dataclasses.field(default_factory=dict)

    def new_episode(self) -> None:
        """Identities of a new episode are not switches of the last one."""
        self._last_id = {}

    def add(self, tracks: np.ndarray, truth: np.ndarray, velocity: np.ndarray | None, robot: np.ndarray,
            seen: np.ndarray) -> None:
        """Score one step.

        Args:
            tracks: (n, 6) ``[x, y, vx, vy, radius, id]`` reported tracks.
            truth: (P, 3) true circles ``[x, y, r]``.
            velocity: (P, 2) true velocities (m/s), or None on an episode's first step.
            robot: (2,) robot centre.
            seen: (P,) line of sight (:func:`line_of_sight`).
        """
        match = match_tracks(tracks, truth, self.match_distance)
        ok = match >= 0
        self.tracks += len(tracks)
        self.truths += len(truth)
        self.matched += int(ok.sum())
        near = seen & (np.hypot(truth[:, 0] - robot[0], truth[:, 1] - robot[1]) <= self.near_distance)
        self.near_seen += int(near.sum())
        self.near_seen_matched += int((near & ok).sum())
        for p in np.flatnonzero(ok):
            row = tracks[match[p]]
            self.pos_sq += float(np.sum((row[:2] - truth[p, :2]) ** 2))
            if velocity is not None:
                self.vel_sq += float(np.sum((row[2:4] - velocity[p]) ** 2))
                self.vel_count += 1
            track_id = int(row[5])
            if self._last_id.get(int(p), track_id) != track_id:
                self.switches += 1
            self._last_id[int(p)] = track_id

    def summary(self) -> dict[str, float]:
        """Precision, recall (all, and near in line of sight), position/velocity RMSE (m, m/s), switches."""
        def ratio(a: float, b: float) -> float:
            return a / b if b else float("nan")
        return {"precision": ratio(self.matched, self.tracks), "recall": ratio(self.matched, self.truths),
                "recall_near_los": ratio(self.near_seen_matched, self.near_seen),
                "pos_rmse": ratio(self.pos_sq, self.matched) ** 0.5,
                "vel_rmse": ratio(self.vel_sq, self.vel_count) ** 0.5,
                "id_switches": float(self.switches)}
