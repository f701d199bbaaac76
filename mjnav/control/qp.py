"""The condensed MPC's QP (:mod:`mjnav.control.mpc`): assembly kernels and solver backends.

:func:`assemble` (numba) builds the linear cost, the velocity/acceleration row bounds and the
polygon rows that survive the reachability test for one step; :func:`plan_violation` checks a
plan (its rollout: :func:`mjnav.control.dynamics.rollout`).

Every backend solves

    min ½ zᵀHz + fᵀz   s.t.   lb <= z <= ub,   lo <= A_fixed z <= hi,   A_poly z <= b_poly

where ``A_fixed`` (velocity and acceleration rows) is constant and the polygon rows change at
every call. Backends never raise on a failed solve: they return ``ok=False`` with the solver's
status.

* :class:`DaqpBackend` (default): dense dual active set; when given a warm start (the shifted
  previous solution, off by default for DAQP) it is passed as ``primal_start`` (DAQP derives the
  initial active set from it), retried cold when the warm start is rejected. Its constraint
  buffers persist; the MPC writes each QP straight into them with :func:`fill_daqp`.
* :class:`OsqpBackend`: sparse ADMM built once with a frozen sparsity pattern: the polygon rows
  live in ``steps × max_halfplanes`` slots whose lower-triangular entries are always structural
  (unused slots are inert: zero coefficients, bounds ±inf). Only ``q``, ``l``, ``u`` and the slot
  values are updated, OSQP warm-starts from its previous iterate, and ``info.status_val`` is
  checked after every solve.
* :class:`QuadprogBackend`: the authors' setup (Goldfarb-Idnani, dense, no warm start).
"""

from __future__ import annotations

import dataclasses

import daqp
import numpy as np
import osqp
import quadprog
from numba import njit
from scipy import sparse

from mjnav.control.dynamics import coast, jerk_travel, rollout_kernel

__all__ = [
    "DaqpBackend",
    "OsqpBackend",
    "QpProblem",
    "QpSolution",
    "QuadprogBackend",
    "assemble",
    "fill_daqp",
    "make_backend",
    "plan_violation",
    "polygon_rows",
]

INF = 1e30  # DAQP's infinity; also used for inert OSQP rows


@dataclasses.dataclass(eq=False)
class QpProblem:
    """One QP instance (see the module docstring); ``n`` variables.

    Attributes:
        h: ``(n, n)`` Hessian (the same object between calls while it does not change).
        f: ``(n,)`` linear cost.
        lb: ``(n,)`` variable lower bounds.
        ub: ``(n,)`` variable upper bounds.
        lo: ``(m0,)`` lower bounds of the fixed rows.
        hi: ``(m0,)`` upper bounds of the fixed rows.
        a_poly: ``(R, n)`` polygon rows.
        b_poly: ``(R,)`` polygon right-hand sides.
        slot: ``(R,)`` slot index ``k·max_halfplanes + j`` of each polygon row (OSQP).
        nx: ``(R,)`` x component of each polygon row's normal (OSQP).
        ny: ``(R,)`` y component of each polygon row's normal (OSQP).
    """

    h: np.ndarray
    f: np.ndarray
    lb: np.ndarray
    ub: np.ndarray
    lo: np.ndarray
    hi: np.ndarray
    a_poly: np.ndarray
    b_poly: np.ndarray
    slot: np.ndarray
    nx: np.ndarray
    ny: np.ndarray


@dataclasses.dataclass(eq=False, slots=True)
class QpSolution:
    """Backend result: ``x`` is ``None`` unless ``ok`` (made every solve, so not frozen: read-only by convention)."""

    x: np.ndarray | None
    ok: bool
    status: str
    iterations: int


class DaqpBackend:
    """Dense active-set backend (DAQP), optionally warm-started with a primal start."""

    name = "daqp"

    def __init__(self, a_fixed: np.ndarray, primal_tol: float = 1e-7) -> None:
        """Args: a_fixed: ``(m0, n)`` constant rows; primal_tol: DAQP primal tolerance."""
        self._a_fixed = np.ascontiguousarray(a_fixed, dtype=float)
        self._tol = primal_tol
        self._grow(0)

    def _grow(self, rows: int) -> None:
        """Buffers for up to ``rows`` polygon rows, reused by every solve (DAQP does not write to them)."""
        m0, n = self._a_fixed.shape
        self._rows = rows
        self._a = np.zeros((m0 + rows, n))
        self._a[:m0] = self._a_fixed
        self._upper = np.zeros(n + m0 + rows)
        self._lower = np.full(n + m0 + rows, -INF)  # polygon rows: no lower bound
        self._f = np.zeros(n)

    def reserve(self, rows: int) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
        """The buffers, with room for at least ``rows`` polygon rows, for :meth:`solve_rows`.

        Returns:
            ``A`` ``(m0 + capacity, n)`` (fixed rows first), the upper and lower bounds
            (variables, fixed rows, polygon rows; polygon lower bounds stay ``-INF``) and ``f``.
        """
        if rows > self._rows:
            self._grow(max(rows, 2 * self._rows))
        return self._a, self._upper, self._lower, self._f

    def solve(self, problem: QpProblem, warm: np.ndarray | None) -> QpSolution:
        """Solve one QP (see :class:`QpProblem`)."""
        rows = problem.b_poly.shape[0]
        a, upper, lower, f = self.reserve(rows)
        (m0, n), end = self._a_fixed.shape, self._a_fixed.shape[0] + rows
        a[m0:end] = problem.a_poly
        upper[:n], upper[n : n + m0], upper[n + m0 : n + end] = problem.ub, problem.hi, problem.b_poly
        lower[:n], lower[n : n + m0] = problem.lb, problem.lo
        f[:] = problem.f
        return self.solve_rows(problem.h, rows, warm)

    def solve_rows(self, h: np.ndarray, rows: int, warm: np.ndarray | None) -> QpSolution:
        """Solve the QP held in the buffers (see :meth:`reserve`) with its first ``rows`` polygon rows."""
        end = self._a_fixed.shape[0] + rows
        a, upper, lower = self._a[:end], self._upper[: self._f.shape[0] + end], self._lower[: self._f.shape[0] + end]
        x, _, flag, info = daqp.solve(h, self._f, a, upper, lower, primal_start=warm, primal_tol=self._tol)
        if flag == -6 and warm is not None:  # overdetermined initial working set: retry cold
            x, _, flag, info = daqp.solve(h, self._f, a, upper, lower, primal_tol=self._tol)
        ok = flag in (1, 2)
        return QpSolution(np.asarray(x) if ok else None, ok, f"daqp:{flag}", int(info["iterations"]))


class QuadprogBackend:
    """Dense Goldfarb-Idnani backend (quadprog), no warm start: the authors' solver."""

    name = "quadprog"

    def __init__(self, a_fixed: np.ndarray) -> None:
        """Args: a_fixed: ``(m0, n)`` constant rows."""
        self._a_fixed = np.asarray(a_fixed, dtype=float)

    def solve(self, problem: QpProblem, warm: np.ndarray | None) -> QpSolution:
        """Solve one QP (``warm`` is ignored)."""
        n = problem.f.shape[0]
        eye = np.eye(n)
        rows = [eye, -eye, self._a_fixed, -self._a_fixed, -problem.a_poly]
        rhs = [problem.lb, -problem.ub, problem.lo, -problem.hi, -problem.b_poly]
        c = np.concatenate(rows)
        b = np.concatenate(rhs)
        finite = np.abs(b) < INF
        try:
            x, _, _, iters, _, _ = quadprog.solve_qp(problem.h, -problem.f, c[finite].T.copy(), b[finite], 0)
        except ValueError as err:  # "constraints are inconsistent" or a non-PD matrix
            return QpSolution(None, False, f"quadprog:{err}", 0)
        return QpSolution(np.asarray(x), True, "quadprog:solved", int(iters[0]))


class OsqpBackend:
    """Sparse ADMM backend (OSQP) with a frozen sparsity pattern and padded polygon slots."""

    name = "osqp"

    def __init__(
        self, a_fixed: np.ndarray, gamma_p: np.ndarray, max_halfplanes: int, soft: bool, eps: float = 1e-7
    ) -> None:
        """Build the pattern (the solver itself is set up on the first call).

        Args:
            a_fixed: ``(m0, n)`` constant rows (their nonzeros form their pattern).
            gamma_p: ``(N, N)`` position response to one axis' jerks (lower triangular).
            max_halfplanes: Polygon slots per prediction step.
            soft: Whether the last variable is the polygon slack (coefficient -1 in every slot).
            eps: Absolute and relative tolerance (tight, because solution polishing is off: OSQP 1.1
                prints a line on every polish that finds no active set, even with verbose off).
        """
        self.max_halfplanes = max_halfplanes
        self._n = a_fixed.shape[1]
        self._eps = eps
        self._solver: osqp.OSQP | None = None
        self._h_id = 0
        rows, cols, vals = self._fixed_entries(np.asarray(a_fixed, dtype=float))
        self._m_fixed = self._n + a_fixed.shape[0]
        prows, pcols, self._slot, self._axis, self._gamma = self._slot_entries(gamma_p, max_halfplanes, soft)
        rows = np.concatenate([rows, prows + self._m_fixed])
        cols = np.concatenate([cols, pcols])
        self._vals = np.concatenate([vals, np.zeros(prows.size)])
        self._n_fixed_vals = vals.size
        self._perm = np.lexsort((rows, cols))  # COO order -> CSC data order
        self._shape = (self._m_fixed + gamma_p.shape[0] * max_halfplanes, self._n)
        self._rows, self._cols = rows, cols

    def _fixed_entries(self, a_fixed: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        n = self._n
        r, c = np.nonzero(a_fixed)
        rows = np.concatenate([np.arange(n), r + n])
        cols = np.concatenate([np.arange(n), c])
        vals = np.concatenate([np.ones(n), a_fixed[r, c]])
        return rows, cols, vals

    def _slot_entries(self, gamma_p: np.ndarray, m: int, soft: bool) -> tuple[np.ndarray, ...]:
        steps = gamma_p.shape[0]
        rows, cols, axis, gamma = [], [], [], []
        for s in range(steps * m):
            k = s // m
            for ax in (0, 1):
                rows += [s] * (k + 1)
                cols += list(range(ax * steps, ax * steps + k + 1))
                axis += [ax] * (k + 1)
                gamma += list(gamma_p[k, : k + 1])
            if soft:
                rows.append(s)
                cols.append(self._n - 1)
                axis.append(2)
                gamma.append(0.0)
        rows_a = np.asarray(rows)
        return rows_a, np.asarray(cols), rows_a.copy(), np.asarray(axis), np.asarray(gamma)

    def _slot_values(self, problem: QpProblem) -> tuple[np.ndarray, np.ndarray]:
        count = self._shape[0] - self._m_fixed
        nx, ny, on, upper = np.zeros(count), np.zeros(count), np.zeros(count), np.full(count, np.inf)
        nx[problem.slot], ny[problem.slot], on[problem.slot] = problem.nx, problem.ny, 1.0
        upper[problem.slot] = problem.b_poly
        vals = np.where(
            self._axis == 0, nx[self._slot], np.where(self._axis == 1, ny[self._slot], -on[self._slot])
        )
        vals[self._axis < 2] *= self._gamma[self._axis < 2]
        return vals, upper

    def solve(self, problem: QpProblem, warm: np.ndarray | None) -> QpSolution:
        """Solve one QP; ``problem.slot`` must be below ``N · max_halfplanes``."""
        slot_vals, slot_upper = self._slot_values(problem)
        self._vals[self._n_fixed_vals :] = slot_vals
        ax = self._vals[self._perm]
        lower = np.concatenate([problem.lb, problem.lo, np.full(slot_upper.size, -np.inf)])
        upper = np.concatenate([problem.ub, problem.hi, slot_upper])
        lower[lower <= -INF], upper[upper >= INF] = -np.inf, np.inf
        if self._solver is None:
            self._setup(problem, ax, lower, upper)
        else:
            kwargs = {"Px": self._p_values(problem.h)} if id(problem.h) != self._h_id else {}
            self._solver.update(q=problem.f, l=lower, u=upper, Ax=ax, **kwargs)
        self._h_id = id(problem.h)
        if warm is not None:
            self._solver.warm_start(x=warm)
        res = self._solver.solve(raise_error=False)
        ok = res.info.status_val == osqp.SolverStatus.OSQP_SOLVED
        return QpSolution(
            np.asarray(res.x) if ok else None, ok, f"osqp:{res.info.status}", int(res.info.iter)
        )

    def _p_values(self, h: np.ndarray) -> np.ndarray:
        """Upper triangle of ``h`` in CSC order (the dense pattern, zeros kept)."""
        r, c = np.triu_indices(self._n)
        order = np.lexsort((r, c))
        return h[r[order], c[order]]

    def _setup(self, problem: QpProblem, ax: np.ndarray, lower: np.ndarray, upper: np.ndarray) -> None:
        n = self._n
        c = np.triu_indices(n)[1]
        p_rows = np.concatenate([np.arange(j + 1) for j in range(n)])  # CSC of the upper triangle
        p = sparse.csc_matrix((self._p_values(problem.h), p_rows, _indptr(np.sort(c), n)), shape=(n, n))
        a = sparse.csc_matrix((ax, self._rows[self._perm], _indptr(self._cols[self._perm], n)), self._shape)
        self._solver = osqp.OSQP()
        self._solver.setup(p, problem.f, a, lower, upper, eps_abs=self._eps, eps_rel=self._eps, **_OSQP)


_OSQP = {"polishing": False, "max_iter": 20000, "verbose": False, "warm_starting": True}


def _indptr(sorted_cols: np.ndarray, n: int) -> np.ndarray:
    return np.concatenate([[0], np.cumsum(np.bincount(sorted_cols, minlength=n))])


def make_backend(
    name: str, a_fixed: np.ndarray, gamma_p: np.ndarray, max_halfplanes: int, soft: bool
) -> DaqpBackend | OsqpBackend | QuadprogBackend:
    """Build the backend called ``name`` (``daqp``, ``osqp`` or ``quadprog``)."""
    if name == "daqp":
        return DaqpBackend(a_fixed)
    if name == "quadprog":
        return QuadprogBackend(a_fixed)
    if name == "osqp":
        return OsqpBackend(a_fixed, gamma_p, max_halfplanes, soft)
    raise ValueError(f"solver: unknown backend {name!r}")


@njit(cache=True)
def plan_violation(
    s: np.ndarray,
    x: np.ndarray,
    steps: int,
    dt: float,
    limits: np.ndarray,
    normals: np.ndarray,
    offsets: np.ndarray,
) -> float:  # pragma: no cover - numba
    """Largest violation of the limits and half-planes by a plan.

    Args:
        s: ``(3, 2)`` initial state (rows p, v, a).
        x: QP solution; ``x[:N]`` x-jerks, ``x[N:2N]`` y-jerks (m/s³).
        steps: Horizon N.
        dt: Step, s.
        limits: ``(3,)`` per-axis bounds (j_max, v_max, a_max): :meth:`mjnav.control.dynamics.Limits.bounds`.
        normals: ``(K, 2)`` half-plane normals (``K = 0``: no polygon check).
        offsets: ``(K,)`` half-plane offsets, metres.

    Returns:
        ``max`` over k, axes and rows of ``|u|-j_max``, ``|v|-v_max``, ``|a|-a_max``, ``n·p-c`` (SI).
    """
    traj = rollout_kernel(s, np.stack((x[:steps], x[steps : 2 * steps]), axis=1), dt)
    worst = -np.inf
    for k in range(steps):
        for d in range(2):
            worst = max(worst, abs(x[d * steps + k]) - limits[0])
            worst = max(worst, abs(traj[k, 1, d]) - limits[1], abs(traj[k, 2, d]) - limits[2])
        for i in range(normals.shape[0]):
            worst = max(worst, normals[i, 0] * traj[k, 0, 0] + normals[i, 1] * traj[k, 0, 1] - offsets[i])
    return worst


@njit(cache=True)
def assemble(
    s: np.ndarray,
    qs: np.ndarray,
    ql: np.ndarray,
    stop: bool,
    phi: np.ndarray,
    gamma: np.ndarray,
    weights: np.ndarray,
    limits: np.ndarray,
    n: int,
) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:  # pragma: no cover - numba
    """Linear cost and velocity/acceleration row bounds of one QP.

    Args:
        s: ``(3, 2)`` initial state (rows p, v, a).
        qs: ``(2,)`` short-term reference, metres.
        ql: ``(2,)`` long-term reference, metres.
        stop: Whether the ``|v_N|²`` and ``Σ|a_k|²`` terms are on.
        phi: ``(N, 3, 3)`` free response (:func:`~mjnav.control.mpc.prediction_matrices`).
        gamma: ``(3, N, N)`` jerk response.
        weights: ``(5,)`` (w_track of p_N, w_vel, w_acc, soft_weight, w_track of p_1).
        limits: ``(3,)`` (j_max, v_max, a_max): :meth:`mjnav.control.dynamics.Limits.bounds`.
        n: Number of variables (2N, or 2N + 1 with the slack as the last one).

    Returns:
        ``f`` ``(n,)``, ``lo`` and ``hi`` ``(4N,)`` for the rows (v_x, v_y, a_x, a_y blocks) and
        the free response ``(N, 3, 2)``.
    """
    steps = phi.shape[0]
    f, lo, hi, free = np.empty(n), np.empty(4 * steps), np.empty(4 * steps), np.empty((steps, 3, 2))
    _assemble_into(s, qs, ql, stop, phi, gamma, weights, limits, f, lo, hi, free)
    return f, lo, hi, free


@njit(cache=True)
def _assemble_into(
    s: np.ndarray, qs: np.ndarray, ql: np.ndarray, stop: bool, phi: np.ndarray, gamma: np.ndarray,
    weights: np.ndarray, limits: np.ndarray, f: np.ndarray, lo: np.ndarray, hi: np.ndarray, free: np.ndarray,
) -> None:  # pragma: no cover - numba
    """:func:`assemble` into given arrays (``f`` ``(n,)``, ``lo``/``hi`` ``(4N,)``, ``free`` ``(N, 3, 2)``)."""
    steps, n = phi.shape[0], f.shape[0]
    gp, gv, ga = gamma[0], gamma[1], gamma[2]
    for k in range(steps):
        for d in range(2):
            for r in range(3):
                free[k, r, d] = phi[k, r, 0] * s[0, d] + phi[k, r, 1] * s[1, d] + phi[k, r, 2] * s[2, d]
    f[:] = 0.0
    last = steps - 1
    for d in range(2):
        for i in range(steps):
            g = weights[4] * gp[0, i] * (free[0, 0, d] - qs[d]) + weights[0] * gp[last, i] * (free[last, 0, d] - ql[d])
            if stop:
                g += weights[1] * gv[last, i] * free[last, 1, d]
                for k in range(i, steps):
                    g += weights[2] * ga[k, i] * free[k, 2, d]
            f[d * steps + i] = 2.0 * g
        for k in range(steps):
            lo[d * steps + k], hi[d * steps + k] = -limits[1] - free[k, 1, d], limits[1] - free[k, 1, d]
            lo[(2 + d) * steps + k], hi[(2 + d) * steps + k] = (
                -limits[2] - free[k, 2, d],
                limits[2] - free[k, 2, d],
            )
    if n > 2 * steps:
        f[n - 1] = weights[3]


@njit(cache=True)
def polygon_rows(
    s: np.ndarray,
    free: np.ndarray,
    normals: np.ndarray,
    offsets: np.ndarray,
    drop: bool,
    gp: np.ndarray,
    limits: np.ndarray,
    dt: float,
    slots: int,
    n: int,
) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray, np.ndarray]:  # pragma: no cover - numba
    """Polygon rows ``n_j · p_k <= c_j`` in the jerks, without the provably unreachable ones.

    Row (k, j) is dropped (``drop``) when ``n_j · p <= c_j`` holds over the whole reach box of
    ``p_k`` (jerk box ∩ velocity box, see :mod:`mjnav.control.mpc`).

    Args:
        s: ``(3, 2)`` initial state.
        free: ``(N, 3, 2)`` free response from :func:`assemble`.
        normals: ``(K, 2)`` outward unit normals.
        offsets: ``(K,)`` offsets, metres.
        drop: Drop unreachable rows.
        gp: ``(N, N)`` position response to one axis' jerks.
        limits: ``(3,)`` (j_max, v_max, a_max): :meth:`mjnav.control.dynamics.Limits.bounds`.
        dt: Step, s.
        slots: Slots per step (OSQP pattern): row (k, j) has slot ``k·slots + j``.
        n: Number of variables; with ``n > 2N`` the last one is the slack (coefficient -1).

    Returns:
        ``rows`` ``(R, n)``, right-hand sides, slots, and the normals' x and y components.
    """
    size = free.shape[0] * normals.shape[0]
    rows, rhs, nx, ny = np.empty((size, n)), np.empty(size), np.empty(size), np.empty(size)
    slot = np.empty(size, dtype=np.int64)
    r = _polygon_rows_into(s, free, normals, offsets, drop, gp, limits, dt, slots, rows, rhs, slot, nx, ny)
    return rows[:r], rhs[:r], slot[:r], nx[:r], ny[:r]


@njit(cache=True)
def _polygon_rows_into(
    s: np.ndarray, free: np.ndarray, normals: np.ndarray, offsets: np.ndarray, drop: bool, gp: np.ndarray,
    limits: np.ndarray, dt: float, slots: int, rows: np.ndarray, rhs: np.ndarray, slot: np.ndarray,
    nx: np.ndarray, ny: np.ndarray,
) -> int:  # pragma: no cover - numba
    """:func:`polygon_rows` into the first rows of given arrays (``N·K`` long, ``rows`` ``(N·K, n)``;
    ``slot``, ``nx`` and ``ny`` may be empty: not recorded); returns the number of rows kept."""
    steps, count, n = free.shape[0], normals.shape[0], rows.shape[1]
    j_max, v_max, a_max = limits[0], limits[1], limits[2]
    per_step = coast(v_max, a_max, dt) + jerk_travel(j_max, dt)
    lo_box, hi_box = np.empty(2), np.empty(2)
    r = 0
    for k in range(steps):
        reach = j_max * np.sum(gp[k, : k + 1])
        for d in range(2):
            vel = abs(coast(s[1, d], s[2, d], dt)) + jerk_travel(j_max, dt) + k * per_step
            lo_box[d] = max(free[k, 0, d] - reach, s[0, d] - vel)
            hi_box[d] = min(free[k, 0, d] + reach, s[0, d] + vel)
            if lo_box[d] > hi_box[d]:  # limits already violated: keep the jerk box only
                lo_box[d], hi_box[d] = free[k, 0, d] - reach, free[k, 0, d] + reach
        for j in range(count):
            a, b = normals[j, 0], normals[j, 1]
            top = (a * hi_box[0] if a > 0 else a * lo_box[0]) + (b * hi_box[1] if b > 0 else b * lo_box[1])
            if drop and top < offsets[j] - 1e-9:
                continue
            rows[r, :] = 0.0
            rows[r, :steps][: k + 1] = a * gp[k, : k + 1]
            rows[r, steps : 2 * steps][: k + 1] = b * gp[k, : k + 1]
            if n > 2 * steps:
                rows[r, n - 1] = -1.0
            rhs[r] = offsets[j] - a * free[k, 0, 0] - b * free[k, 0, 1]
            if slot.shape[0]:
                slot[r], nx[r], ny[r] = k * slots + j, a, b
            r += 1
    return r


@njit(cache=True)
def fill_daqp(
    s: np.ndarray, qs: np.ndarray, ql: np.ndarray, stop: bool, phi: np.ndarray, gamma: np.ndarray,
    weights: np.ndarray, limits: np.ndarray, lb: np.ndarray, ub: np.ndarray, normals: np.ndarray,
    offsets: np.ndarray, drop: bool, dt: float, free: np.ndarray, a: np.ndarray, upper: np.ndarray,
    lower: np.ndarray, f: np.ndarray,
) -> int:  # pragma: no cover - numba
    """:func:`assemble` and :func:`polygon_rows` straight into :class:`DaqpBackend`'s buffers.

    One call instead of two kernels, nine returned arrays and the copies into the solver's
    buffers (see :meth:`DaqpBackend.reserve`); the values are the same.

    Args:
        s, qs, ql, stop, phi, gamma, weights, limits: As for :func:`assemble`.
        lb: ``(n,)`` variable lower bounds; ub: ``(n,)`` upper bounds.
        normals, offsets, drop, dt: As for :func:`polygon_rows` (``gp = gamma[0]``).
        free: ``(N, 3, 2)`` scratch for the free response.
        a, upper, lower, f: The backend's buffers, with room for ``N·K`` polygon rows.

    Returns:
        The number of polygon rows kept.
    """
    n, m0 = f.shape[0], 4 * phi.shape[0]
    upper[:n], lower[:n] = ub, lb
    _assemble_into(s, qs, ql, stop, phi, gamma, weights, limits, f, lower[n : n + m0], upper[n : n + m0], free)
    none = np.empty(0, dtype=np.int64)
    empty = np.empty(0)
    return _polygon_rows_into(
        s, free, normals, offsets, drop, gamma[0], limits, dt, 0, a[m0:], upper[n + m0 :], none, empty, empty
    )
