"""Compiled solver of TEB's band problem, bit for bit the same as scipy's ``least_squares``.

:func:`mjnav.planners.teb.optimize_band` used to call ``scipy.optimize.least_squares(method="trf",
jac_sparsity=..., bounds=(lower, inf), x_scale=1.0, max_nfev=...)``; most of an episode went into
scipy's Python machinery around a problem of 60–120 variables (finite differences through
``VectorFunction``, ``LinearOperator`` wrappers, the pure-Python LSMR loop). :func:`solve_band`
runs the same algorithm (scipy's ``trf_bounds`` with ``tr_solver="lsmr"``, the sparse two-point
Jacobian of ``approx_derivative`` and ``scipy.sparse.linalg.lsmr``) with the residuals, the
Jacobian, its products and LSMR compiled by numba, and calls scipy and numpy for the small dense
steps (QR of an (n, 2) matrix, the 2-D trust-region problem, step selection). Every floating-point
operation is the one scipy performs, in the same order, so bands (and episodes) are bit-identical:

* sums over matrix entries run in CSR/CSC order from zero, as scipy's ``csr_matvec``/``csc_matvec``;
* vector norms and dot products call the ``ddot`` of numpy's own BLAS (``numpy.dot`` does), found
  with ctypes in numpy's bundled OpenBLAS (:func:`blas_ddot`);
* scalar powers call libm's ``pow`` (as numpy's scalar ``**`` does: ``np.float64(x) ** 2`` differs
  from ``x * x`` about once in a thousand) and hypotenuses libm's ``hypot`` (as ``numpy.hypot``
  does; Python's ``math.hypot`` differs from it).

Where numpy's BLAS, libm or scipy's private helpers cannot be found (another numpy build or
platform, another scipy layout), :func:`available` is false and the planner keeps calling
``least_squares``. ``tests/planners/test_trf.py`` compares both on random bands, bit for bit, with
the installed scipy (written against scipy 1.17).

The loops follow SciPy's ``trf_bounds`` and ``lsmr`` (SciPy, BSD-3-Clause licence, © the SciPy
developers) step for step, because bit-identity requires the same operations in the same order.
"""

from __future__ import annotations

import ctypes
import functools
import glob
import math
import os
from typing import NamedTuple

import numba
import numpy as np
from scipy.linalg import get_lapack_funcs, qr
try:  # scipy's private helpers: the algorithm this module reproduces (checked against scipy 1.17)
    from scipy.optimize._lsq.common import (
        CL_scaling_vector,
        build_quadratic_1d,
        check_termination,
        in_bounds,
        make_strictly_feasible,
        minimize_quadratic_1d,
        solve_trust_region_2d,
        update_tr_radius,
    )
    from scipy.optimize._lsq.trf import select_step
    from scipy.optimize._numdiff import _eps_for_method, group_columns
except ImportError:  # another scipy layout: available() is false and TEB calls least_squares
    _SCIPY_HELPERS = False
else:
    _SCIPY_HELPERS = True

__all__ = ["BandTerms", "available", "blas_ddot", "residuals", "solve_band", "structure"]


class BandTerms(NamedTuple):
    """Constants of TEB's residuals (see :func:`mjnav.planners.teb._residuals`); SI units."""

    sqrt_w_time: float
    sqrt_w_velocity: float
    v_limit: float  # v_max − ε, m/s
    sqrt_w_acceleration: float
    a_limit: float  # a_max − ε, m/s²
    obstacle_limit: float  # d_min + ε, m
    sqrt_w_inflation: float
    d_inflation: float  # m


# ---------------------------------------------------------------------------- foreign functions


@functools.cache
def blas_ddot() -> ctypes._CFuncPtr | None:
    """The ``cblas_ddot`` that ``numpy.dot`` calls (numpy's bundled OpenBLAS), or None if not found."""
    libs = os.path.join(os.path.dirname(np.__file__), os.pardir, "numpy.libs")
    for path in sorted(glob.glob(os.path.join(libs, "libscipy_openblas64_*.so"))):
        try:
            fn = ctypes.CDLL(path).scipy_cblas_ddot64_
        except (OSError, AttributeError):
            continue
        fn.restype = ctypes.c_double
        fn.argtypes = [ctypes.c_int64, ctypes.c_void_p, ctypes.c_int64, ctypes.c_void_p, ctypes.c_int64]
        return fn
    return None


@functools.cache
def _libm_pow() -> ctypes._CFuncPtr | None:
    """libm's ``pow`` (what numpy's and Python's scalar ``**`` call), or None if not found."""
    try:
        fn = ctypes.CDLL("libm.so.6").pow
    except (OSError, AttributeError):
        return None
    fn.restype = ctypes.c_double
    fn.argtypes = [ctypes.c_double, ctypes.c_double]
    return fn


def available() -> bool:
    """Whether :func:`solve_band` can reproduce ``least_squares`` here (numpy's BLAS and libm found)."""
    return _SCIPY_HELPERS and blas_ddot() is not None and _libm_pow() is not None


# ---------------------------------------------------------------------------- residuals


@numba.njit(cache=True)
def _npmax(a: float, b: float) -> float:
    """``numpy.maximum`` of two scalars (NaN propagates)."""
    return a if (a >= b or a != a) else b


@numba.njit(cache=True)
def _residuals(z, n, goal, v_start, assoc, terms, sqrt_w_obs, out):
    """Fill ``out`` with TEB's stacked penalties of band variables ``z`` (numpy's operations, in order)."""
    nx = 2 * (n - 1)
    k = assoc.shape[1]
    w_t, w_v, v_lim, w_a, a_lim, o_lim, w_i, d_inf = terms
    px = np.empty(n + 1)
    py = np.empty(n + 1)
    px[0], py[0], px[n], py[n] = 0.0, 0.0, goal[0], goal[1]
    for i in range(1, n):
        px[i], py[i] = z[2 * (i - 1)], z[2 * (i - 1) + 1]
    prev_x, prev_y = v_start[0], v_start[1]
    for i in range(n):
        dt = z[nx + i]
        vx, vy = (px[i + 1] - px[i]) / dt, (py[i + 1] - py[i]) / dt
        span = 0.5 * dt if i == 0 else 0.5 * (z[nx + i - 1] + dt)
        acc = math.hypot(vx - prev_x, vy - prev_y) / span
        out[i] = w_t * dt
        out[n + i] = w_v * _npmax(0.0, math.hypot(vx, vy) - v_lim)
        out[2 * n + i] = w_a * _npmax(0.0, acc - a_lim)
        prev_x, prev_y = vx, vy
    base = 3 * n
    block = (n - 1) * k
    for j in range(n - 1):
        for kk in range(k):
            gap = math.hypot(px[j + 1] - assoc[j, kk, 0], py[j + 1] - assoc[j, kk, 1])
            out[base + j * k + kk] = sqrt_w_obs * _npmax(0.0, o_lim - gap)
            out[base + block + j * k + kk] = w_i * _npmax(0.0, d_inf - gap)


def residuals(z: np.ndarray, n: int, goal: np.ndarray, v_start: np.ndarray, assoc: np.ndarray,
              terms: BandTerms, w_obs: float) -> np.ndarray:
    """TEB's weighted penalties of band variables ``z`` (poses 1..n−1 then n intervals), stacked.

    Args:
        z: (3n−2,) interior poses (x, y interleaved, metres) then intervals (seconds).
        n: Number of intervals.
        goal: (2,) fixed last pose, metres.
        v_start: (2,) robot velocity, m/s.
        assoc: (n−1, k, 2) obstacle points of each interior pose, metres.
        terms: Constants of the penalties.
        w_obs: Current obstacle weight.

    Returns:
        (3n + 2(n−1)k,) residuals: time, velocity, acceleration, obstacle, inflation.
    """
    out = np.empty(3 * n + 2 * (n - 1) * assoc.shape[1])
    _residuals(np.ascontiguousarray(z, dtype=np.float64), n, np.asarray(goal, np.float64),
               np.asarray(v_start, np.float64), np.ascontiguousarray(assoc, dtype=np.float64),
               tuple(map(float, terms)), math.sqrt(w_obs), out)
    return out


# ---------------------------------------------------------------------------- Jacobian


class Structure(NamedTuple):
    """Sparsity of the residuals' Jacobian: CSR rows (sorted columns) and scipy's column groups."""

    pattern: np.ndarray  # (m, nv) bool
    indptr: np.ndarray
    indices: np.ndarray
    groups: np.ndarray  # (nv,) group of each column, as scipy's group_columns


def structure(pattern: np.ndarray) -> Structure:
    """CSR structure and column groups of a boolean Jacobian pattern (rows: residuals)."""
    rows, cols = np.nonzero(pattern)  # row-major: rows ascending, columns ascending within a row
    indptr = np.concatenate([[0], np.cumsum(np.bincount(rows, minlength=pattern.shape[0]))]).astype(np.int64)
    groups = np.asarray(group_columns(pattern), dtype=np.int64)
    return Structure(pattern, indptr, cols.astype(np.int64), groups)


@numba.njit(cache=True)
def _jacobian(x0, f0, h, n, goal, v_start, assoc, terms, sqrt_w_obs, indptr, indices, groups, data):
    """Two-point sparse finite differences as scipy's ``_sparse_difference``, into CSR ``data``."""
    m, nv = f0.size, x0.size
    n_groups = 0
    for j in range(nv):
        n_groups = max(n_groups, groups[j] + 1)
    x = np.empty(nv)
    dx = np.empty(nv)
    f = np.empty(m)
    for g in range(n_groups):
        for j in range(nv):
            x[j] = x0[j] + h[j] * (1.0 if groups[j] == g else 0.0)
            dx[j] = x[j] - x0[j]
        _residuals(x, n, goal, v_start, assoc, terms, sqrt_w_obs, f)
        for i in range(m):
            for jj in range(indptr[i], indptr[i + 1]):
                j = indices[jj]
                if groups[j] == g:
                    data[jj] = (f[i] - f0[i]) / dx[j]


@numba.njit(cache=True)
def _matvec(indptr, indices, data, x):
    """``J @ x`` in scipy's ``csr_matvec`` order."""
    m = indptr.size - 1
    y = np.zeros(m)
    for i in range(m):
        s = y[i]
        for jj in range(indptr[i], indptr[i + 1]):
            s += data[jj] * x[indices[jj]]
        y[i] = s
    return y


@numba.njit(cache=True)
def _rmatvec(indptr, indices, data, x, nv):
    """``J.T @ x`` in scipy's ``csc_matvec`` order (the transpose of a CSR matrix)."""
    y = np.zeros(nv)
    for i in range(indptr.size - 1):
        for jj in range(indptr[i], indptr[i + 1]):
            y[indices[jj]] += data[jj] * x[i]
    return y


class _Jacobian:
    """A CSR Jacobian with its column scaling ``d`` (scipy's ``right_multiplied_operator``)."""

    def __init__(self, st: Structure, data: np.ndarray, d: np.ndarray | None = None) -> None:
        self.st, self.data, self.d = st, data, d

    def dot(self, x: np.ndarray) -> np.ndarray:
        """``J·diag(d)·x`` for a vector, or column by column for an (nv, c) matrix."""
        if x.ndim == 1:
            return _matvec(self.st.indptr, self.st.indices, self.data, np.ravel(x) * self.d)
        cols = [_matvec(self.st.indptr, self.st.indices, self.data, np.ascontiguousarray(x[:, c] * self.d))
                for c in range(x.shape[1])]
        return np.ascontiguousarray(np.column_stack(cols))

    def grad(self, f: np.ndarray) -> np.ndarray:
        """``J.T·f`` (unscaled), scipy's ``compute_grad``."""
        return _rmatvec(self.st.indptr, self.st.indices, self.data, f, len(self.st.groups))


# ---------------------------------------------------------------------------- LSMR


@numba.njit(cache=True)
def _norm(ddot, x):
    """``numpy.linalg.norm`` of a contiguous vector: the square root of numpy's BLAS ``ddot``."""
    return math.sqrt(ddot(x.size, x.ctypes.data, 1, x.ctypes.data, 1))


@numba.njit(cache=True)
def _sign(a):
    return 1.0 if a > 0 else (-1.0 if a < 0 else (0.0 if a == 0 else a))


@numba.njit(cache=True)
def _sym_ortho(a, b):
    """scipy's ``_sym_ortho`` (a stable Givens rotation): (c, s, r)."""
    if b == 0:
        return _sign(a), 0.0, abs(a)
    if a == 0:
        return 0.0, _sign(b), abs(b)
    if abs(b) > abs(a):
        tau = a / b
        s = _sign(b) / math.sqrt(1 + tau * tau)
        return s * tau, s, b / s
    tau = b / a
    c = _sign(a) / math.sqrt(1 + tau * tau)
    return c, c * tau, a / c


@numba.njit(cache=True)
def _op_matvec(indptr, indices, data, d, diag, v, m):
    """``[J·diag(d); diag(diag)]·v`` (scipy's ``regularized_lsq_operator``)."""
    out = np.empty(m + v.size)
    out[:m] = _matvec(indptr, indices, data, v * d)
    out[m:] = diag * v
    return out


@numba.njit(cache=True)
def _op_rmatvec(indptr, indices, data, d, diag, u, m):
    """``[J·diag(d); diag(diag)].T·u``."""
    nv = d.size
    return d * _rmatvec(indptr, indices, data, u[:m], nv) + diag * u[m:]


@numba.njit(cache=True)
def _pymax(a, b):
    return b if b > a else a


@numba.njit(cache=True)
def _pymin(a, b):
    return b if b < a else a


@numba.njit(cache=True)
def _lsmr(ddot, pow_, indptr, indices, data, d, diag, b, m):
    """``scipy.sparse.linalg.lsmr(op, b)[0]`` with its defaults (damp 0, atol = btol = 1e-6, conlim 1e8)."""
    atol = btol = 1e-6
    ctol = 1 / 1e8
    n = d.size
    maxiter = n
    x = np.zeros(n)
    u = b
    normb = _norm(ddot, b)
    beta = normb
    if beta > 0:
        u = (1 / beta) * u
        v = _op_rmatvec(indptr, indices, data, d, diag, u, m)
        alpha = _norm(ddot, v)
    else:
        v = np.zeros(n)
        alpha = 0.0
    if alpha > 0:
        v = (1 / alpha) * v
    itn = 0
    zetabar = alpha * beta
    alphabar = alpha
    rho = rhobar = cbar = 1.0
    sbar = 0.0
    h = v.copy()
    hbar = np.zeros(n)
    betadd = beta
    betad = 0.0
    rhodold = 1.0
    tautildeold = thetatilde = zeta = dd = 0.0
    normA2 = alpha * alpha
    maxrbar = 0.0
    minrbar = 1e100
    normA = math.sqrt(normA2)
    normar = alpha * beta
    if normar == 0 or normb == 0:
        return x
    while itn < maxiter:
        itn = itn + 1
        u = u * -alpha
        u = u + _op_matvec(indptr, indices, data, d, diag, v, m)
        beta = _norm(ddot, u)
        if beta > 0:
            u = u * (1 / beta)
            v = v * -beta
            v = v + _op_rmatvec(indptr, indices, data, d, diag, u, m)
            alpha = _norm(ddot, v)
            if alpha > 0:
                v = v * (1 / alpha)
        chat, shat, alphahat = _sym_ortho(alphabar, 0.0)
        rhoold = rho
        c, s, rho = _sym_ortho(alphahat, beta)
        thetanew = s * alpha
        alphabar = c * alpha
        rhobarold = rhobar
        zetaold = zeta
        thetabar = sbar * rho
        rhotemp = cbar * rho
        cbar, sbar, rhobar = _sym_ortho(cbar * rho, thetanew)
        zeta = cbar * zetabar
        zetabar = -sbar * zetabar
        hbar = hbar * -(thetabar * rho / (rhoold * rhobarold))
        hbar = hbar + h
        x = x + (zeta / (rho * rhobar)) * hbar
        h = h * -(thetanew / rho)
        h = h + v
        betaacute = chat * betadd
        betacheck = -shat * betadd
        betahat = c * betaacute
        betadd = -s * betaacute
        thetatildeold = thetatilde
        ctildeold, stildeold, rhotildeold = _sym_ortho(rhodold, thetabar)
        thetatilde = stildeold * rhobar
        rhodold = ctildeold * rhobar
        betad = -stildeold * betad + ctildeold * betahat
        tautildeold = (zetaold - thetatildeold * tautildeold) / rhotildeold
        taud = (zeta - thetatilde * tautildeold) / rhodold
        dd = dd + betacheck * betacheck
        normr = math.sqrt(dd + pow_(betad - taud, 2.0) + betadd * betadd)
        normA2 = normA2 + beta * beta
        normA = math.sqrt(normA2)
        normA2 = normA2 + alpha * alpha
        maxrbar = _pymax(maxrbar, rhobarold)
        if itn > 1:
            minrbar = _pymin(minrbar, rhobarold)
        condA = _pymax(maxrbar, rhotemp) / _pymin(minrbar, rhotemp)
        normar = abs(zetabar)
        normx = _norm(ddot, x)
        test1 = normr / normb
        test2 = normar / (normA * normr) if (normA * normr) != 0 else np.inf
        test3 = 1 / condA
        t1 = test1 / (1 + normA * normx / normb)
        rtol = btol + atol * normA * normx / normb
        istop = 7 if itn >= maxiter else 0
        if 1 + test3 <= 1:
            istop = 6
        if 1 + test2 <= 1:
            istop = 5
        if 1 + t1 <= 1:
            istop = 4
        if test3 <= ctol:
            istop = 3
        if test2 <= atol:
            istop = 2
        if test1 <= rtol:
            istop = 1
        if istop > 0:
            break
    return x


# ---------------------------------------------------------------------------- trust region reflective

_POTRF, _POTRS = get_lapack_funcs(("potrf", "potrs"), (np.zeros((2, 2)),))


def _trust_region_2d(B: np.ndarray, g: np.ndarray, Delta: float) -> np.ndarray:
    """scipy's ``solve_trust_region_2d(B, g, Delta)[0]`` with the same LAPACK and numpy calls, without
    scipy's wrappers: the Newton step if ``B`` is positive definite and the step within the region,
    else the best boundary point from the roots of scipy's quartic. A non-finite ``B`` or ``g`` goes
    to scipy's function (which raises as it always did)."""
    if not (np.isfinite(B).all() and np.isfinite(g).all()):
        return solve_trust_region_2d(B, g, Delta)[0]
    c, info = _POTRF(B, lower=False, overwrite_a=False, clean=False)
    if info < 0 or (info == 0 and not np.isfinite(c).all()):
        return solve_trust_region_2d(B, g, Delta)[0]
    if info == 0:
        x, info = _POTRS(c, g, lower=False, overwrite_b=False)
        if info != 0:
            return solve_trust_region_2d(B, g, Delta)[0]
        p = -x
        if np.dot(p, p) <= Delta**2:
            return p
    a, b, c = B[0, 0] * Delta**2, B[0, 1] * Delta**2, B[1, 1] * Delta**2
    d, f = g[0] * Delta, g[1] * Delta
    t = np.roots(np.array([-b + d, 2 * (a - c + f), 6 * b, 2 * (-a + c + f), -b - d]))
    t = np.real(t[np.isreal(t)])
    p = Delta * np.vstack((2 * t / (1 + t**2), (1 - t**2) / (1 + t**2)))
    value = 0.5 * np.sum(p * B.dot(p), axis=0) + np.dot(g, p)
    return p[:, np.argmin(value)]


class _Problem:
    """One call's residual function and Jacobian (scipy's ``VectorFunction`` with finite differences)."""

    def __init__(self, n: int, goal: np.ndarray, v_start: np.ndarray, assoc: np.ndarray, terms: BandTerms,
                 w_obs: float, lower: np.ndarray, st: Structure) -> None:
        self.n, self.lower, self.st = n, lower, st
        self.args = (n, np.asarray(goal, np.float64), np.asarray(v_start, np.float64),
                     np.ascontiguousarray(assoc, dtype=np.float64), tuple(map(float, terms)), math.sqrt(w_obs))
        self.m = 3 * n + 2 * (n - 1) * assoc.shape[1]
        self.rstep = float(_eps_for_method(np.float64, np.float64, "2-point"))

    def fun(self, x: np.ndarray) -> np.ndarray:
        """Residuals at ``x``."""
        out = np.empty(self.m)
        _residuals(x, *self.args, out)
        return out

    def jac(self, x: np.ndarray, f: np.ndarray) -> _Jacobian:
        """Two-point Jacobian at ``x`` (residuals ``f``), steps as scipy's ``approx_derivative``."""
        sign = (x >= 0).astype(float) * 2 - 1
        h = self.rstep * sign * np.maximum(1.0, np.abs(x))
        h[(x + h) < self.lower] *= -1  # _adjust_scheme_to_bounds, one-sided; the upper bound is inf
        data = np.empty(len(self.st.indices))
        _jacobian(x, f, h, *self.args, self.st.indptr, self.st.indices, self.st.groups, data)
        return _Jacobian(self.st, data)


def solve_band(z: np.ndarray, n: int, goal: np.ndarray, v_start: np.ndarray, assoc: np.ndarray, terms: BandTerms,
               w_obs: float, lower: np.ndarray, max_nfev: int, st: Structure) -> np.ndarray:
    """``least_squares(residuals, z, jac_sparsity=..., bounds=(lower, inf), max_nfev=..., x_scale=1.0,
    method="trf").x`` for TEB's band, bit for bit (see the module docstring).

    Args:
        z: (nv,) initial band variables (see :func:`residuals`); metres and seconds.
        n: Number of intervals.
        goal: (2,) fixed last pose, metres.
        v_start: (2,) robot velocity, m/s.
        assoc: (n−1, k, 2) obstacle points per interior pose, metres.
        terms: Constants of the penalties.
        w_obs: Obstacle weight of this outer iteration.
        lower: (nv,) lower bounds (upper bounds are +inf).
        max_nfev: Function evaluations allowed (scipy's count).
        st: :func:`structure` of the residuals' Jacobian pattern (``jac_sparsity``).

    Returns:
        (nv,) optimised variables.

    Raises:
        ValueError: As ``least_squares``: ``z`` outside the bounds or non-finite initial residuals.
    """
    upper = np.full_like(lower, np.inf)
    if not in_bounds(z, lower, upper):
        raise ValueError("Initial guess is outside of provided bounds")
    prob = _Problem(n, goal, v_start, assoc, terms, w_obs, lower, st)
    x0 = make_strictly_feasible(z, lower, upper)
    f0 = prob.fun(x0)
    if not np.all(np.isfinite(f0)):
        raise ValueError("Residuals are not finite in the initial point.")
    return _trf_bounds(prob, x0, f0, upper, max_nfev)


def _trf_bounds(prob: _Problem, x0: np.ndarray, f0: np.ndarray, ub: np.ndarray, max_nfev: int) -> np.ndarray:
    """scipy's ``trf_bounds`` with ``tr_solver="lsmr"``, no loss, ``x_scale`` 1, tolerances 1e-8."""
    ftol = xtol = gtol = 1e-8
    lb, m = prob.lower, prob.m
    ddot, pow_ = blas_ddot(), _libm_pow()
    x, f, nfev = x0.copy(), f0, 1
    J = prob.jac(x, f)
    scale = np.resize(np.asarray(1.0, dtype=float), x0.shape)
    scale_inv = 1 / scale
    cost = 0.5 * np.dot(f, f)
    g = J.grad(f)
    v, dv = CL_scaling_vector(x, g, lb, ub)
    v[dv != 0] *= scale_inv[dv != 0]
    Delta = np.linalg.norm(x0 * scale_inv / v**0.5)
    if Delta == 0:
        Delta = 1.0
    f_augmented = np.zeros(m + x.size)
    termination_status = None
    while True:
        v, dv = CL_scaling_vector(x, g, lb, ub)
        g_norm = np.linalg.norm(g * v, ord=np.inf)
        if g_norm < gtol:
            termination_status = 1
        if termination_status is not None or nfev == max_nfev:
            break
        v[dv != 0] *= scale_inv[dv != 0]
        d = v**0.5 * scale
        diag_h = g * dv * scale
        g_h = d * g
        f_augmented[:m] = f
        J_h = _Jacobian(J.st, J.data, d)
        a, b = build_quadratic_1d(J_h, g_h, -g_h, diag=diag_h)
        to_tr = Delta / np.linalg.norm(g_h)
        ag_value = minimize_quadratic_1d(a, b, 0, to_tr)[1]
        reg_term = -ag_value / Delta**2
        diag = (diag_h + reg_term) ** 0.5
        gn_h = _lsmr(ddot, pow_, J.st.indptr, J.st.indices, J.data, d, np.ascontiguousarray(diag),
                     f_augmented.copy(), m)
        S, _ = qr(np.vstack((g_h, gn_h)).T, mode="economic")
        JS = J_h.dot(S)
        B_S = np.dot(JS.T, JS) + np.dot(S.T * diag_h, S)
        g_S = S.T.dot(g_h)
        theta = max(0.995, 1 - g_norm)
        actual_reduction = -1
        while actual_reduction <= 0 and nfev < max_nfev:
            p_S = _trust_region_2d(B_S, g_S, Delta)
            p_h = S.dot(p_S)
            p = d * p_h
            step, step_h, predicted_reduction = select_step(x, J_h, diag_h, g_h, p, p_h, d, Delta, lb, ub, theta)
            x_new = make_strictly_feasible(x + step, lb, ub, rstep=0)
            f_new = prob.fun(x_new)
            nfev += 1
            step_h_norm = np.linalg.norm(step_h)
            if not np.all(np.isfinite(f_new)):
                Delta = 0.25 * step_h_norm
                continue
            cost_new = 0.5 * np.dot(f_new, f_new)
            actual_reduction = cost - cost_new
            Delta_new, ratio = update_tr_radius(Delta, actual_reduction, predicted_reduction,
                                                step_h_norm, step_h_norm > 0.95 * Delta)
            step_norm = np.linalg.norm(step)
            termination_status = check_termination(actual_reduction, cost, step_norm, np.linalg.norm(x),
                                                   ratio, ftol, xtol)
            if termination_status is not None:
                break
            Delta = Delta_new
        if actual_reduction > 0:
            x, f, cost = x_new, f_new, cost_new
            J = prob.jac(x, f)
            g = J.grad(f)
    return x
