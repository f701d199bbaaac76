"""Multi-target bookkeeping: constant-velocity Kalman filters, gated greedy assignment, birth and death.

One numba kernel advances every track by one control step. Tracks live in fixed slots of
arrays (see :class:`TrackArrays`); x and y are filtered independently (the motion model and the
measurement noise are isotropic), so each axis keeps a 2×2 covariance ``[p_pos, p_cross, p_vel]``.
Units: metres, seconds, m/s.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

__all__ = ["FREE", "TENTATIVE", "CONFIRMED", "TrackArrays", "update_kernel"]

FREE, TENTATIVE, CONFIRMED = 0, 1, 2


class TrackArrays:
    """Fixed-capacity track slots (T = capacity) in two arrays (few arguments per kernel call).

    ``floats`` (T, 14) holds ``state`` (columns 0-3), ``cov`` (4-9) and ``shape`` (10-13);
    ``ints`` (T, 5) holds ``status`` (0), ``ids`` (1) and ``counts`` (2-4). The views:

    Attributes:
        state: (T, 4) ``[x, y, vx, vy]``, world metres and m/s.
        cov: (T, 6) per axis x then y ``[var pos (m²), cov pos-vel (m²/s), var vel (m²/s²)]``.
        shape: (T, 4) ``[radius (m), origin x, origin y, largest distance from origin (m)]``.
        status: (T,) FREE, TENTATIVE or CONFIRMED.
        ids: (T,) track identities (never reused within an episode).
        counts: (T, 3) ``[age (steps), hits, consecutive misses]``.
    """

    def __init__(self, capacity: int) -> None:
        """All slots free."""
        self.floats = np.zeros((capacity, 14))
        self.ints = np.zeros((capacity, 5), dtype=np.int64)
        self.ints[:, 1] = -1
        self.state, self.cov, self.shape = split_floats(self.floats)
        self.status, self.ids, self.counts = split_ints(self.ints)


@njit(cache=True, error_model="numpy")
def split_floats(floats: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """``(state, cov, shape)`` views of the float slots."""
    return floats[:, 0:4], floats[:, 4:10], floats[:, 10:14]


@njit(cache=True, error_model="numpy")
def split_ints(ints: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """``(status, ids, counts)`` views of the integer slots."""
    return ints[:, 0], ints[:, 1], ints[:, 2:5]


@njit(cache=True, error_model="numpy")
def _predict(state: np.ndarray, cov: np.ndarray, t: int, dt: float, q: float) -> None:
    """Constant-velocity prediction with white-acceleration spectral density ``q`` (m²/s³)."""
    for ax in range(2):
        state[t, ax] += dt * state[t, 2 + ax]
        pp, pv, vv = cov[t, 3 * ax], cov[t, 3 * ax + 1], cov[t, 3 * ax + 2]
        cov[t, 3 * ax] = pp + 2.0 * dt * pv + dt * dt * vv + q * dt ** 3 / 3.0
        cov[t, 3 * ax + 1] = pv + dt * vv + q * dt * dt / 2.0
        cov[t, 3 * ax + 2] = vv + q * dt


@njit(cache=True, error_model="numpy")
def _correct(state: np.ndarray, cov: np.ndarray, t: int, zx: float, zy: float, r2: float) -> None:
    """Kalman update of slot ``t`` with a position measurement of variance ``r2`` (m²)."""
    for ax in range(2):
        z = zx if ax == 0 else zy
        pp, pv, vv = cov[t, 3 * ax], cov[t, 3 * ax + 1], cov[t, 3 * ax + 2]
        s = pp + r2
        kp, kv = pp / s, pv / s
        y = z - state[t, ax]
        state[t, ax] += kp * y
        state[t, 2 + ax] += kv * y
        cov[t, 3 * ax] = (1.0 - kp) * pp
        cov[t, 3 * ax + 1] = (1.0 - kp) * pv
        cov[t, 3 * ax + 2] = vv - kv * pv


@njit(cache=True, error_model="numpy")
def _gated_pairs(state: np.ndarray, cov: np.ndarray, status: np.ndarray, det: np.ndarray, n: int,
                 r2: float, chi2: float, gate: float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(cost, track, detection) of pairs inside both gates; tentative tracks cost 1000 more."""
    cap = status.shape[0]
    cost = np.empty(cap * n)
    ti = np.empty(cap * n, np.int64)
    di = np.empty(cap * n, np.int64)
    m = 0
    for t in range(cap):
        if status[t] == FREE:
            continue
        for d in range(n):
            ex, ey = det[d, 0] - state[t, 0], det[d, 1] - state[t, 1]
            dist = math.sqrt(ex * ex + ey * ey)
            maha = ex * ex / (cov[t, 0] + r2) + ey * ey / (cov[t, 3] + r2)
            if dist <= gate and maha <= chi2:
                cost[m] = dist + (1000.0 if status[t] == 1 else 0.0)
                ti[m], di[m] = t, d
                m += 1
    return cost[:m], ti[:m], di[:m]


@njit(cache=True, error_model="numpy")
def _birth(arrays_state: np.ndarray, cov: np.ndarray, status: np.ndarray, ids: np.ndarray,
           counts: np.ndarray, shape: np.ndarray, det_row: np.ndarray, r2: float, v2: float,
           next_id: int) -> int:
    """Start a tentative track on ``det_row`` in the first free slot; the next free identity."""
    for t in range(status.shape[0]):
        if status[t] == FREE:
            arrays_state[t, 0], arrays_state[t, 1] = det_row[0], det_row[1]
            arrays_state[t, 2], arrays_state[t, 3] = 0.0, 0.0
            for ax in range(2):
                cov[t, 3 * ax], cov[t, 3 * ax + 1], cov[t, 3 * ax + 2] = r2, 0.0, v2
            status[t], ids[t] = TENTATIVE, next_id
            counts[t, 0], counts[t, 1], counts[t, 2] = 1, 1, 0
            shape[t, 0], shape[t, 1], shape[t, 2], shape[t, 3] = det_row[2], det_row[0], det_row[1], 0.0
            return next_id + 1
    return next_id


@njit(cache=True, error_model="numpy")
def _bookkeep(status: np.ndarray, counts: np.ndarray, t: int, confirm_hits: int, window: int,
              max_misses: int) -> None:
    """Confirmation (M hits within the first N steps) and deletion (K misses) of slot ``t``."""
    age, hits, misses = counts[t, 0], counts[t, 1], counts[t, 2]
    if status[t] == TENTATIVE:
        if hits >= confirm_hits:
            status[t] = CONFIRMED
        elif age >= window or misses >= 2:
            status[t] = FREE
    elif misses >= max_misses:
        status[t] = FREE


@njit(cache=True, error_model="numpy")
def update_kernel(floats: np.ndarray, ints: np.ndarray, det: np.ndarray, n: int, dt: float,
                  params: np.ndarray, next_id: int) -> int:
    """Advance every track (:class:`TrackArrays` ``floats`` and ``ints``) by one step of ``dt`` seconds
    with detections ``det[:n]`` (``[x, y, r]``).

    ``params``: ``[accel_std (m/s²), measurement_std (m), initial_speed_std (m/s), gate (m),
    gate_chi2, confirm_hits, confirm_window, max_misses]``. Returns the next free identity.
    """
    state, cov, shape = split_floats(floats)
    status, ids, counts = split_ints(ints)
    q, r2, v2 = params[0] ** 2, params[1] ** 2, params[2] ** 2
    for t in range(status.shape[0]):
        if status[t] != FREE:
            _predict(state, cov, t, dt, q)
            counts[t, 0] += 1
    cost, ti, di = _gated_pairs(state, cov, status, det, n, r2, params[4], params[3])
    track_used = np.zeros(status.shape[0], np.bool_)
    det_used = np.zeros(n, np.bool_)
    for k in np.argsort(cost, kind="mergesort"):
        t, d = ti[k], di[k]
        if track_used[t] or det_used[d]:
            continue
        track_used[t] = det_used[d] = True
        _correct(state, cov, t, det[d, 0], det[d, 1], r2)
        counts[t, 1] += 1
        counts[t, 2] = 0
        shape[t, 0] = 0.8 * shape[t, 0] + 0.2 * det[d, 2]
    for t in range(status.shape[0]):
        if status[t] == FREE:
            continue
        if not track_used[t]:
            counts[t, 2] += 1
        shape[t, 3] = max(shape[t, 3], math.hypot(state[t, 0] - shape[t, 1], state[t, 1] - shape[t, 2]))
        _bookkeep(status, counts, t, int(params[5]), int(params[6]), int(params[7]))
    for d in range(n):
        if not det_used[d]:
            next_id = _birth(state, cov, status, ids, counts, shape, det[d], r2, v2, next_id)
    return next_id
