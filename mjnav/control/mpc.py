"""Condensed jerk MPC on the triple integrator with the convex-region constraint (spec §5).

Decision variables: the jerks ``u_0..u_{N-1}`` (x block then y block; 2N values, plus one slack
with ``soft=True``). Cost (``cost_stop='always'``, the authors' code)::

    w_track (|p_1 - Q_s|² + |p_N - Q_l|²) + w_jerk Σ|u_k|² + w_vel |v_N|² + w_acc Σ_{k=1..N} |a_k|²

(``cost_stop='goal_inside'``: the last two terms only when the goal is inside the polygon).
Constraints for k = 1..N: per-axis ``|v_k| <= v_max``, ``|a_k| <= a_max``, ``|u| <= j_max`` and
``p_k`` inside the polygon: for each clockwise edge ``(P_j, P_{j+1})``,
``(P_j - p_k) × (P_{j+1} - p_k) <= 0``, used in the equivalent unit-normal form ``n_j·p_k <= c_j``.

Unreachable half-planes (``drop_unreachable``): row (k, j) is dropped when no trajectory that
satisfies the QP's hard jerk, velocity and acceleration limits can reach it. The reach bound per
axis is the intersection of two conservative boxes around ``p_k``: the exact jerk-limited box
``free_k ± j_max Σ_i Γ_p[k, i]`` (``free_k`` = zero-jerk response) and the velocity box
``p_0 ± (|v_0 t + a_0 t²/2| + j_max t³/6 + (k-1)(v_max t + a_max t²/2 + j_max t³/6))``. A dropped
row could never be active, so the solution is unchanged.

Fallback ladder (spec §5) when the QP fails (solver status, or a returned point that violates a
constraint by more than ``feasibility_tol``): (1) ``brake_previous``: brake while the last
successful plan's horizon has not run out; (2) ``no_polygon``: re-solve without the polygon;
(3) ``brake``. Braking = the jerks minimising ``Σ (w_b |v_k|² + |a_k|²) + w_jerk Σ|u_k|²``
(``w_b = brake_velocity_weight``) under ``|u| <= j_max`` only (always feasible; DAQP, else the
clipped unconstrained optimum). Each fallback is counted in :attr:`Mpc.stats`;
:meth:`Mpc.solve` never raises on a QP failure.

The QP assembly kernels and the solver backends live in :mod:`mjnav.control.qp`.
"""

from __future__ import annotations

import dataclasses
import functools
import math
import threading
import time
from typing import Literal

import daqp
import numpy as np

from mjnav.control.dynamics import Limits, integrate, rollout, transition_matrices
from mjnav.control.qp import (
    INF,
    DaqpBackend,
    QpProblem,
    QpSolution,
    assemble,
    fill_daqp,
    make_backend,
    plan_violation,
    polygon_rows,
)
from mjnav.geometry.polygon import halfplanes
from mjnav.schema import check as _check

__all__ = ["Mpc", "MpcConfig", "MpcResult", "prediction_matrices", "simulate_triple_integrator"]

Arr = np.ndarray



@dataclasses.dataclass(frozen=True)
class MpcConfig:
    """MPC parameters (spec §5; SI units).

    Attributes:
        horizon: Prediction steps N.
        t_c: Control period, s.
        w_track: Weight of the two tracking terms, 1/m².
        w_jerk: Weight of Σ|u_k|².
        w_vel: Weight of |v_N|².
        w_acc: Weight of Σ|a_k|².
        cost_stop: ``always`` (code) or ``goal_inside`` (paper: stop terms only then).
        v_max: Per-axis velocity bound, m/s.
        a_max: Per-axis acceleration bound, m/s².
        j_max: Per-axis jerk bound, m/s³.
        solver: QP backend: ``daqp`` (fastest here), ``osqp`` or ``quadprog`` (authors').
        max_halfplanes: Polygon slots per step in the OSQP pattern (grown on demand).
        drop_unreachable: Drop half-planes no feasible trajectory can reach (see module doc).
        soft: Soften the polygon rows with one slack ``σ >= 0`` (cost ``soft_weight·(σ² + σ)``).
        soft_weight: Slack weight.
        warm_start: Hand the solver the shifted previous solution (OSQP: its starting iterate;
            DAQP: ``primal_start``, from which it derives the initial active set). None: the
            solver's own default: warm for OSQP (spec §5), cold for DAQP, which solved recorded
            stage-7 problem sequences faster cold, with the same jerks (the results page).
        feasibility_tol: Largest accepted constraint violation of a returned solution (SI).
        brake_velocity_weight: Weight of Σ|v_k|² (vs 1 on Σ|a_k|²) in the braking fallback.
        track_short: Keep the ``|p_1 - Q_s|²`` term (False: track ``Q_l`` only, Design 3).
    """

    horizon: int = 10
    t_c: float = Limits.control_period
    w_track: float = 350.0
    w_jerk: float = 1.0
    w_vel: float = 1.0
    w_acc: float = 1.0
    cost_stop: Literal["always", "goal_inside"] = "always"
    v_max: float = Limits.v_max
    a_max: float = Limits.a_max
    j_max: float = Limits.j_max
    solver: Literal["daqp", "osqp", "quadprog"] = "daqp"
    max_halfplanes: int = 64
    drop_unreachable: bool = True
    soft: bool = False
    soft_weight: float = 1e5
    warm_start: bool | None = None
    feasibility_tol: float = 1e-5
    brake_velocity_weight: float = 10.0
    track_short: bool = True

    def __post_init__(self) -> None:
        _check(self.horizon >= 2, "horizon", "must be >= 2")
        for name in ("t_c", "w_track", "v_max", "a_max", "j_max", "soft_weight", "feasibility_tol"):
            value = getattr(self, name)
            _check(math.isfinite(value) and value > 0.0, name, "must be finite and > 0")
        for name in ("w_jerk", "w_vel", "w_acc", "brake_velocity_weight"):
            value = getattr(self, name)
            _check(math.isfinite(value) and value >= 0.0, name, "must be finite and >= 0")
        _check(self.w_jerk > 0.0, "w_jerk", "must be > 0 (keeps the Hessian positive definite)")
        _check(self.cost_stop in ("always", "goal_inside"), "cost_stop", "must be 'always' or 'goal_inside'")
        _check(self.solver in ("daqp", "osqp", "quadprog"), "solver", "must be 'daqp', 'osqp' or 'quadprog'")
        _check(self.max_halfplanes >= 3, "max_halfplanes", "must be >= 3")

    @property
    def limits(self) -> Limits:
        """The motion limits the MPC plans within (``t_c``, ``v_max``, ``a_max``, ``j_max``; in a task
        config these follow ``timing`` and ``robot``). Sizes and range keep their defaults: unused here."""
        return Limits(control_period=self.t_c, v_max=self.v_max, a_max=self.a_max, j_max=self.j_max)


@dataclasses.dataclass(eq=False, slots=True)
class MpcResult:
    """One MPC step (robot frame, SI units; made every step, so not frozen: treat as read-only).

    Attributes:
        u0: ``(2,)`` jerk to apply for one period, m/s³.
        jerks: ``(N, 2)`` planned jerks u_0..u_{N-1}.
        positions: ``(N, 2)`` predicted p_1..p_N, metres (Q*_1 = positions[0], Q*_N = positions[-1]).
        velocities: ``(N, 2)`` predicted v_1..v_N, m/s.
        accelerations: ``(N, 2)`` predicted a_1..a_N, m/s².
        status: ``solved`` or ``fallback``.
        solver_status: Backend status of the first attempt (``daqp:1``, ``osqp:solved``, ...).
        fallback: ``None``, ``brake_previous``, ``no_polygon`` or ``brake``.
        solve_time_s: Wall time of :meth:`Mpc.solve`, s.
        iterations: Solver iterations of the first attempt.
        slack: Polygon slack σ (0 unless ``soft``), metres.
        rows: Polygon rows handed to the solver (after dropping unreachable ones).
    """

    u0: np.ndarray
    jerks: np.ndarray
    positions: np.ndarray
    velocities: np.ndarray
    accelerations: np.ndarray
    status: str
    solver_status: str
    fallback: str | None
    solve_time_s: float
    iterations: int
    slack: float
    rows: int

    @property
    def ok(self) -> bool:
        """Whether the requested QP was solved (no fallback)."""
        return self.fallback is None


def simulate_triple_integrator(state: np.ndarray, jerk: np.ndarray, dt: float) -> np.ndarray:
    """Exact update of the per-axis triple integrator under constant jerk.

    ``p⁺ = p + v t + a t²/2 + j t³/6``, ``v⁺ = v + a t + j t²/2``, ``a⁺ = a + j t``.

    Args:
        state: ``(3, 2)`` rows p [m], v [m/s], a [m/s²].
        jerk: ``(2,)`` jerk, m/s³.
        dt: Duration, s.

    Returns:
        The ``(3, 2)`` state after ``dt``.
    """
    s = np.asarray(state, dtype=float)
    return np.stack(integrate(s[0], s[1], s[2], np.asarray(jerk, dtype=float), float(dt)))


def prediction_matrices(horizon: int, dt: float) -> tuple[np.ndarray, np.ndarray]:
    """Condensed per-axis prediction: ``x_k = Φ[k-1] x_0 + Γ[:, k-1] u`` for k = 1..N.

    Args:
        horizon: Steps N.
        dt: Step, s.

    Returns:
        ``phi`` ``(N, 3, 3)`` and ``gamma`` ``(3, N, N)`` (rows p, v, a; lower triangular).
    """
    f, g = transition_matrices(dt)
    phi, gamma = np.empty((horizon, 3, 3)), np.zeros((3, horizon, horizon))
    power = np.eye(3)
    for k in range(horizon):
        power = f @ power
        phi[k] = power
        for i in range(k + 1):
            gamma[:, k, i] = np.linalg.matrix_power(f, k - i) @ g
    return phi, gamma


class Mpc:
    """Receding-horizon MPC (see the module docstring); one instance per robot/environment."""

    def __init__(self, config: MpcConfig | None = None) -> None:
        """Take the condensed matrices (built once per process and config) and the QP backend."""
        self.config = cfg = config if config is not None else MpcConfig()
        shared = _shared(cfg)
        self._phi, self._gamma, self._n = shared.phi, shared.gamma, shared.n
        self._h_on, self._h_off, self._brake_h = shared.h_on, shared.h_off, shared.brake_h
        self._weights, self._limits, self._a_fixed = shared.weights, shared.limits, shared.a_fixed
        self._lb, self._ub = shared.lb, shared.ub
        #: The motion limits planned within (:attr:`MpcConfig.limits`).
        self.limits = cfg.limits
        # DAQP: the assembly scratch and the solver's buffers are the calling thread's (:func:`_scratch`)
        self._backend = None if cfg.solver == "daqp" else make_backend(
            cfg.solver, self._a_fixed, self._gamma[0], cfg.max_halfplanes, cfg.soft)
        #: Whether solves are warm-started (``config.warm_start``, resolved for the solver).
        self.warm_start = cfg.solver == "osqp" if cfg.warm_start is None else cfg.warm_start
        self.stats: dict[str, int] = {}
        self.reset()

    def reset(self) -> None:
        """Forget the previous plan and the warm start (call at every episode start).

        OSQP keeps its own iterate (and may have been grown for a large polygon): it is rebuilt so
        an episode's solves do not depend on earlier episodes.
        """
        cfg = self.config
        if cfg.solver == "osqp" and self.stats.get("solves", 0):
            self._backend = make_backend("osqp", self._a_fixed, self._gamma[0], cfg.max_halfplanes, cfg.soft)
        self._warm: np.ndarray | None = None
        self._plan_age = self.config.horizon  # no previous plan
        for key in ("solves", "solved", "failures", "brake_previous", "no_polygon", "brake"):
            self.stats.setdefault(key, 0)

    def solve(
        self,
        state: np.ndarray,
        q_s: np.ndarray,
        q_l: np.ndarray,
        polygon: np.ndarray | None = None,
        goal_inside: bool = False,
        halfplanes: tuple[np.ndarray, np.ndarray] | None = None,
    ) -> MpcResult:
        """Plan one step.

        Args:
            state: ``(3, 2)`` rows p [m], v [m/s], a [m/s²] in the polygon's frame (p = 0 in the
                robot frame).
            q_s: ``(2,)`` short-term reference Q_s, metres.
            q_l: ``(2,)`` long-term reference Q_l, metres.
            polygon: ``(K, 2)`` convex region vertices (clockwise; either orientation is
                accepted), or ``None`` to plan without the region constraint.
            goal_inside: Whether the goal is inside the polygon (selects the stop cost for
                ``cost_stop='goal_inside'``).
            halfplanes: The polygon's ``(normals (K, 2), offsets (K,))`` if already known (as
                :class:`mjnav.geometry.region.Region` carries them); computed from ``polygon``
                otherwise. Ignored without a polygon.

        Returns:
            The :class:`MpcResult`; on QP failure a fallback result (never raises).

        Raises:
            ValueError: On non-finite or badly shaped inputs.
        """
        start = time.perf_counter()
        s, qs, ql, normals, offsets = _validate(state, q_s, q_l, polygon, halfplanes)
        return self._solve(s, qs, ql, normals, offsets, goal_inside, start)

    def solve_unchecked(
        self,
        state: np.ndarray,
        q_s: np.ndarray,
        q_l: np.ndarray,
        halfplanes: tuple[np.ndarray, np.ndarray] | None,
        goal_inside: bool = False,
        keep_clear: bool = False,
    ) -> MpcResult:
        """:meth:`solve` without its input checks, for callers whose inputs are valid by construction.

        The task uses it: its state comes from the physics (checked once per step), the
        references from the action mapping and the halfplanes from a successful region.

        Args:
            state: ``(3, 2)`` float64 rows p, v, a, all finite.
            q_s: ``(2,)`` float64 short-term reference, finite, metres.
            q_l: ``(2,)`` float64 long-term reference, finite, metres.
            halfplanes: ``(normals (K, 2), offsets (K,))`` of a convex polygon with K >= 3, or
                ``None`` to plan without the region constraint.
            goal_inside: As for :meth:`solve`.
            keep_clear: Never plan without a polygon (the region layer's ``on_failure='recover'``):
                with ``halfplanes=None`` brake at once (fallback ``brake_no_region``), and skip the
                ladder's ``no_polygon`` step when the QP fails.

        Returns:
            The :class:`MpcResult`, exactly as :meth:`solve` gives it for the same inputs.
        """
        start = time.perf_counter()
        if keep_clear and halfplanes is None:
            self.stats["solves"] += 1
            self.stats["brake_no_region"] = self.stats.get("brake_no_region", 0) + 1
            self._warm, self._plan_age = None, self._plan_age + 1
            x = self._brake(state)
            return self._result(state, x, _NO_SOLUTION, "brake_no_region", 0, time.perf_counter() - start)
        normals, offsets = (None, None) if halfplanes is None else halfplanes
        return self._solve(state, q_s, q_l, normals, offsets, goal_inside, start, keep_clear)

    def _solve(
        self, s: Arr, qs: Arr, ql: Arr, normals: Arr | None, offsets: Arr | None, goal_inside: bool, start: float,
        keep_clear: bool = False,
    ) -> MpcResult:
        """:meth:`solve` after its checks; ``start`` is the ``perf_counter`` time the call began."""
        cfg = self.config
        self.stats["solves"] += 1
        self._plan_age += 1
        stop = cfg.cost_stop == "always" or bool(goal_inside)
        sol, x, rows = self._attempt(s, qs, ql, normals, offsets, stop, self._warm)
        fallback = None
        if x is not None:
            self.stats["solved"] += 1
            self._plan_age = 0
        else:
            self.stats["failures"] += 1
            x, fallback = self._fallback(s, qs, ql, None if keep_clear else normals, stop)
        self._warm = _shift(x, cfg.horizon) if (self.warm_start and fallback is None) else None
        return self._result(s, x, sol, fallback, rows, time.perf_counter() - start)

    def _attempt(
        self, s: Arr, qs: Arr, ql: Arr, normals: Arr | None, offsets: Arr | None, stop: bool, warm: Arr | None
    ) -> tuple[QpSolution, Arr | None, int]:
        """One QP solve; returns (backend solution, plan or None if failed/infeasible, rows)."""
        cfg = self.config
        if normals is not None and cfg.solver == "osqp" and normals.shape[0] > self._backend.max_halfplanes:
            self._grow_osqp(normals.shape[0])
        if cfg.solver == "daqp":
            sol, rows = self._solve_daqp(s, qs, ql, normals, offsets, stop, warm)
        else:
            problem = self._problem(s, qs, ql, normals, offsets, stop)
            sol, rows = self._backend.solve(problem, warm), problem.b_poly.shape[0]
        x = sol.x
        if x is not None:
            check = normals is not None and not cfg.soft
            nrm, off = (normals, offsets) if check else (_NO_ROWS, _NO_OFFSETS)
            worst = plan_violation(s, x, cfg.horizon, cfg.t_c, self._limits, nrm, off)
            x = x if worst <= cfg.feasibility_tol else None
        return sol, x, rows

    def _solve_daqp(
        self, s: Arr, qs: Arr, ql: Arr, normals: Arr | None, offsets: Arr | None, stop: bool, warm: Arr | None
    ) -> tuple[QpSolution, int]:
        """The :meth:`_problem` QP assembled straight into DAQP's buffers, then solved; (solution, rows)."""
        cfg = self.config
        nrm = _NO_ROWS if normals is None else normals
        off = _NO_OFFSETS if offsets is None else offsets
        free, backend = _scratch(cfg)
        buffers = backend.reserve(cfg.horizon * nrm.shape[0])
        rows = fill_daqp(
            s, qs, ql, stop, self._phi, self._gamma, self._weights, self._limits, self._lb, self._ub, nrm, off,
            cfg.drop_unreachable, cfg.t_c, free, *buffers,
        )  # fmt: skip
        return backend.solve_rows(self._h_on if stop else self._h_off, rows, warm), rows

    def _fallback(self, s: Arr, qs: Arr, ql: Arr, normals: Arr | None, stop: bool) -> tuple[Arr, str]:
        if self._plan_age < self.config.horizon:
            self.stats["brake_previous"] += 1
            return self._brake(s), "brake_previous"
        if normals is not None:
            _, x, _ = self._attempt(s, qs, ql, None, None, stop, None)
            if x is not None:
                self.stats["no_polygon"] += 1
                return x, "no_polygon"
        self.stats["brake"] += 1
        return self._brake(s), "brake"

    def _problem(
        self, s: Arr, qs: Arr, ql: Arr, normals: Arr | None, offsets: Arr | None, stop: bool
    ) -> QpProblem:
        cfg = self.config
        f, lo, hi, free = assemble(
            s, qs, ql, stop, self._phi, self._gamma, self._weights, self._limits, self._n
        )
        nrm = _NO_ROWS if normals is None else normals
        off = _NO_OFFSETS if offsets is None else offsets
        slots = getattr(self._backend, "max_halfplanes", 0)
        rows, rhs, slot, nx, ny = polygon_rows(
            s, free, nrm, off, cfg.drop_unreachable, self._gamma[0], self._limits, cfg.t_c, slots, self._n
        )
        h = self._h_on if stop else self._h_off
        return QpProblem(h, f, self._lb, self._ub, lo, hi, rows, rhs, slot, nx, ny)

    def _grow_osqp(self, count: int) -> None:
        cfg = self.config
        size = 16 * math.ceil(count / 16)
        self._backend = make_backend("osqp", self._a_fixed, self._gamma[0], size, cfg.soft)
        self.stats["osqp_rebuilds"] = self.stats.get("osqp_rebuilds", 0) + 1

    def _brake(self, s: np.ndarray) -> np.ndarray:
        """Jerks that bring velocity and acceleration to zero (|u| <= j_max only)."""
        cfg, j_max = self.config, self.limits.j_max
        _, gv, ga = self._gamma
        free_v = self._phi[:, 1, :] @ s  # (N, 2)
        free_a = self._phi[:, 2, :] @ s
        f = 2.0 * (cfg.brake_velocity_weight * gv.T @ free_v + ga.T @ free_a).T.ravel()
        bound = np.full(f.size, j_max)
        x, _, flag, _ = daqp.solve(self._brake_h, f, np.zeros((0, f.size)), bound, -bound)
        if flag not in (1, 2):
            x = np.clip(-np.linalg.solve(self._brake_h, f), -j_max, j_max)
        if cfg.soft:
            x = np.append(x, 0.0)
        return np.asarray(x)

    def _result(
        self, s: Arr, x: Arr, sol: QpSolution, fallback: str | None, rows: int, elapsed: float
    ) -> MpcResult:
        n_steps = self.config.horizon
        jerks = np.ascontiguousarray(x[: 2 * n_steps].reshape(2, n_steps).T)
        traj = rollout(s, jerks, self.config.t_c)
        status = "solved" if fallback is None else "fallback"
        slack = float(x[-1]) if self.config.soft else 0.0
        return MpcResult(
            jerks[0].copy(),
            jerks,
            traj[:, 0],
            traj[:, 1],
            traj[:, 2],
            status,
            sol.status,
            fallback,
            elapsed,
            sol.iterations,
            slack,
            rows,
        )


@dataclasses.dataclass(frozen=True, eq=False)
class _Shared:
    """What an :class:`Mpc` computes from its config alone; one per process and config (:func:`_shared`).

    Every environment of a process (64 in a training worker) plans with the same matrices, so
    they are built once and kept hot in the cache instead of once per environment. Never written.
    """

    phi: np.ndarray  # (N, 3, 3) prediction_matrices
    gamma: np.ndarray  # (3, N, N)
    n: int  # decision variables
    h_on: np.ndarray  # (n, n) Hessian with the stop terms
    h_off: np.ndarray  # (n, n) without them
    brake_h: np.ndarray  # (2N, 2N) Hessian of the braking fallback
    weights: np.ndarray  # (5,) as the QP kernels read them
    limits: np.ndarray  # (3,) Limits.bounds()
    a_fixed: np.ndarray  # (4N, n) velocity and acceleration rows
    lb: np.ndarray  # (n,) variable bounds
    ub: np.ndarray


@functools.lru_cache(maxsize=64)
def _shared(cfg: MpcConfig) -> _Shared:
    """The :class:`_Shared` matrices of ``cfg`` (cached: a config is frozen and hashable)."""
    phi, gamma = prediction_matrices(cfg.horizon, cfg.t_c)
    n = 2 * cfg.horizon + (1 if cfg.soft else 0)
    lb, ub = np.full(n, -float(cfg.j_max)), np.full(n, float(cfg.j_max))  # float: equal configs may hold ints
    if cfg.soft:
        lb[-1], ub[-1] = 0.0, INF
    weights = np.array([cfg.w_track, cfg.w_vel, cfg.w_acc, cfg.soft_weight, cfg.w_track * cfg.track_short], dtype=float)
    return _Shared(phi, gamma, n, _hessian(cfg, gamma, n, True), _hessian(cfg, gamma, n, False),
                   _brake_hessian(cfg, gamma), weights, cfg.limits.bounds(), _fixed_rows(gamma, n), lb, ub)


def _hessian(cfg: MpcConfig, gamma: np.ndarray, n: int, stop: bool) -> np.ndarray:
    """(n, n) QP Hessian of the module docstring's cost (``stop``: with the |v_N|², Σ|a_k|² terms)."""
    gp, gv, ga = gamma
    h1 = cfg.w_track * (cfg.track_short * np.outer(gp[0], gp[0]) + np.outer(gp[-1], gp[-1])) + cfg.w_jerk * np.eye(
        cfg.horizon
    )
    if stop:
        h1 += cfg.w_vel * np.outer(gv[-1], gv[-1]) + cfg.w_acc * ga.T @ ga
    h = np.zeros((n, n))
    h[: 2 * cfg.horizon, : 2 * cfg.horizon] = 2.0 * np.kron(np.eye(2), h1)
    if cfg.soft:
        h[-1, -1] = 2.0 * cfg.soft_weight
    return h


def _fixed_rows(gamma: np.ndarray, n: int) -> np.ndarray:
    """(4N, n) rows of v_k (x, y) and a_k (x, y) in the jerks, k = 1..N."""
    n_steps = gamma.shape[1]
    _, gv, ga = gamma
    rows = np.zeros((4 * n_steps, n))
    for block, g in enumerate((gv, gv, ga, ga)):
        axis = block % 2
        rows[block * n_steps : (block + 1) * n_steps, axis * n_steps : (axis + 1) * n_steps] = g
    return rows


def _brake_hessian(cfg: MpcConfig, gamma: np.ndarray) -> np.ndarray:
    """(2N, 2N) Hessian of the braking fallback."""
    _, gv, ga = gamma
    h1 = cfg.brake_velocity_weight * gv.T @ gv + ga.T @ ga + cfg.w_jerk * np.eye(cfg.horizon)
    return 2.0 * np.kron(np.eye(2), h1)


_THREAD = threading.local()


def _scratch(cfg: MpcConfig) -> tuple[np.ndarray, DaqpBackend]:
    """The calling thread's DAQP assembly scratch ``(N, 3, 2)`` and backend buffers for ``cfg``.

    Each solve fills them completely before DAQP reads them, so the instances of one thread can
    take turns with one set; another thread gets its own. Looked up at every solve, so an
    instance may move between threads.
    """
    table = getattr(_THREAD, "table", None)
    if table is None:
        table = _THREAD.table = {}
    entry = table.get(cfg)
    if entry is None:
        if len(table) >= 64:  # many configs in one thread: start over (instances keep nothing of it)
            table.clear()
        shared = _shared(cfg)
        entry = table[cfg] = (np.empty((cfg.horizon, 3, 2)), DaqpBackend(shared.a_fixed))
    return entry


def _validate(
    state: Arr, q_s: Arr, q_l: Arr, polygon: Arr | None, known: tuple[Arr, Arr] | None = None
) -> tuple[Arr, Arr, Arr, Arr | None, Arr | None]:
    s = np.asarray(state, dtype=np.float64)
    if s.shape != (3, 2):
        raise ValueError(f"state: expected shape (3, 2) rows p, v, a; got {s.shape}")
    qs, ql = np.asarray(q_s, dtype=np.float64), np.asarray(q_l, dtype=np.float64)
    for name, arr in (("q_s", qs), ("q_l", ql)):
        if arr.shape != (2,):
            raise ValueError(f"{name}: expected shape (2,), got {arr.shape}")
    values = s.ravel().tolist() + qs.tolist() + ql.tolist()  # 10 floats: cheaper than 3 ufunc reductions
    if not all(map(math.isfinite, values)):
        raise ValueError(f"state/q_s/q_l: non-finite values (state={s.tolist()}, q_s={qs}, q_l={ql})")
    if polygon is None:
        return s, qs, ql, None, None
    poly = np.asarray(polygon, dtype=np.float64)
    finite = poly.size > 0 and (math.isfinite(poly.sum()) or bool(np.isfinite(poly).all()))  # sum: fast path
    if poly.ndim != 2 or poly.shape[1] != 2 or poly.shape[0] < 3 or not finite:
        raise ValueError(f"polygon: expected finite (K >= 3, 2) vertices, got shape {poly.shape}")
    if known is None:
        return s, qs, ql, *halfplanes(poly)
    normals, offsets = known
    if normals.shape != poly.shape or offsets.shape != poly.shape[:1]:
        raise ValueError(f"halfplanes: shapes {normals.shape}, {offsets.shape} do not match polygon {poly.shape}")
    return s, qs, ql, normals, offsets


def _shift(x: np.ndarray, n_steps: int) -> np.ndarray:
    out = x.copy()
    for axis in (0, 1):
        block = out[axis * n_steps : (axis + 1) * n_steps]
        block[:-1] = x[axis * n_steps + 1 : (axis + 1) * n_steps]
    if out.size > 2 * n_steps:
        out[-1] = 0.0
    return out


_NO_ROWS, _NO_OFFSETS = np.zeros((0, 2)), np.zeros(0)
_NO_SOLUTION = QpSolution(None, False, "not_solved", 0)
