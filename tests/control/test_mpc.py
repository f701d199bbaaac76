"""Tests for the condensed jerk MPC (spec §5)."""

from __future__ import annotations

import threading

import numpy as np
import pytest

from mjnav.control.mpc import Mpc, MpcConfig, _scratch, _shared, prediction_matrices, simulate_triple_integrator
from mjnav.control.qp import INF, fill_daqp
from mjnav.geometry.polygon import halfplanes, orient_clockwise, points_in_convex
from mjnav.geometry.region import compute_region
from tests.geometry.scans import ANGLES, random_scan

CFG = MpcConfig()
SQUARE = orient_clockwise(np.array([[1.0, -1.0], [1.0, 1.0], [-1.0, 1.0], [-1.0, -1.0]]))
TOL = 1e-4


def _rollout(state, jerks, dt=CFG.t_c):
    out, s = [], np.asarray(state, dtype=float)
    for u in jerks:
        s = simulate_triple_integrator(s, u, dt)
        out.append(s)
    return np.array(out)


def _cost(state, jerks, q_s, q_l, cfg=CFG):
    traj = _rollout(state, jerks.reshape(2, -1).T, cfg.t_c)
    p, v, a = traj[:, 0], traj[:, 1], traj[:, 2]
    track = np.sum((p[0] - q_s) ** 2) + np.sum((p[-1] - q_l) ** 2)
    return (
        cfg.w_track * track
        + cfg.w_jerk * np.sum(jerks**2)
        + cfg.w_vel * np.sum(v[-1] ** 2)
        + cfg.w_acc * np.sum(a**2)
    )


def _assert_feasible(res, state, polygon, cfg=CFG):
    traj = _rollout(state, res.jerks, cfg.t_c)
    assert np.allclose(traj[:, 0], res.positions, atol=1e-9)
    assert np.max(np.abs(res.jerks)) <= cfg.j_max + TOL
    assert np.max(np.abs(traj[:, 1])) <= cfg.v_max + TOL
    assert np.max(np.abs(traj[:, 2])) <= cfg.a_max + TOL
    if polygon is not None:
        assert points_in_convex(traj[:, 0], polygon, tol=TOL).all()


def _random_case(rng):
    while True:
        region = compute_region(random_scan(rng), ANGLES)
        if region.success:
            break
    state = np.array([[0.0, 0.0], rng.uniform(-2.5, 2.5, 2), rng.uniform(-4, 4, 2)])
    q_s, q_l = rng.uniform(-1, 1, 2), rng.uniform(-8, 8, 2)
    return state, q_s, q_l, region.vertices


def test_simulate_triple_integrator_is_exact():
    """One step equals the closed-form constant-jerk motion."""
    s = np.array([[1.0, -2.0], [0.5, 0.1], [-1.0, 2.0]])
    j, t = np.array([3.0, -8.0]), 0.3
    out = simulate_triple_integrator(s, j, t)
    assert np.allclose(out[0], s[0] + s[1] * t + s[2] * t**2 / 2 + j * t**3 / 6)
    assert np.allclose(out[1], s[1] + s[2] * t + j * t**2 / 2)
    assert np.allclose(out[2], s[2] + j * t)
    half = simulate_triple_integrator(simulate_triple_integrator(s, j, t / 2), j, t / 2)
    assert np.allclose(half, out)


def test_prediction_matrices_match_simulation():
    """Condensed Φ, Γ reproduce step-by-step simulation."""
    rng = np.random.default_rng(0)
    phi, gamma = prediction_matrices(7, 0.1)
    s0, u = rng.normal(size=3), rng.normal(size=7)
    state = np.stack([s0, np.zeros(3)], axis=1)
    traj = _rollout(state, np.stack([u, np.zeros(7)], axis=1))
    for k in range(7):
        assert np.allclose(phi[k] @ s0 + gamma[:, k] @ u, traj[k, :, 0])


def test_config_rejects_bad_values_naming_the_field():
    """Invalid config values raise ValueError naming the field."""
    for field, value in [
        ("horizon", 1),
        ("t_c", 0.0),
        ("w_jerk", 0.0),
        ("solver", "cvx"),
        ("cost_stop", "x"),
    ]:
        with pytest.raises(ValueError, match=field):
            MpcConfig(**{field: value})


def test_unconstrained_solution_is_the_cost_minimum():
    """With inactive constraints the gradient of the spec cost (by finite differences) vanishes."""
    mpc = Mpc()
    state = np.array([[0.0, 0.0], [0.3, -0.2], [0.1, 0.0]])
    q_s, q_l = np.array([0.04, -0.01]), np.array([0.5, -0.3])
    res = mpc.solve(state, q_s, q_l, None)
    assert res.ok and np.max(np.abs(res.jerks)) < CFG.j_max - 0.1
    x = np.concatenate([res.jerks[:, 0], res.jerks[:, 1]])
    grad = [
        (_cost(state, x + e, q_s, q_l) - _cost(state, x - e, q_s, q_l)) / 2e-4 for e in np.eye(x.size) * 1e-4
    ]
    assert np.max(np.abs(grad)) < 1e-5


def test_random_problems_satisfy_constraints_or_report_fallback():
    """Over random states, references and scan polygons, solutions are feasible or flagged."""
    rng = np.random.default_rng(1)
    mpc = Mpc()
    solved = 0
    for _ in range(400):
        state, q_s, q_l, poly = _random_case(rng)
        res = mpc.solve(state, q_s, q_l, poly)
        if res.ok:
            _assert_feasible(res, state, poly)
            solved += 1
        else:
            assert res.fallback in ("brake_previous", "no_polygon", "brake")
    assert solved > 200
    assert mpc.stats["solves"] == 400 and mpc.stats["solved"] == solved


def test_empty_world_receding_horizon_reaches_the_reference():
    """Repeated MPC steps in free space drive the robot to a fixed reachable point and stop it."""
    mpc = Mpc()
    goal = np.array([3.0, -2.0])
    state = np.zeros((3, 2))
    for _ in range(80):
        rel = goal - state[0]
        res = mpc.solve(np.stack([np.zeros(2), state[1], state[2]]), rel, rel, None, goal_inside=True)
        assert res.ok
        state = simulate_triple_integrator(state, res.u0, CFG.t_c)
    assert np.linalg.norm(state[0] - goal) < 0.02 and np.linalg.norm(state[1]) < 0.05


def test_reference_outside_polygon_keeps_trajectory_inside():
    """A far reference outside the region still yields a plan inside the polygon, pressed to its edge."""
    res = Mpc().solve(np.zeros((3, 2)), np.array([5.0, 0.0]), np.array([5.0, 0.0]), SQUARE)
    assert res.ok
    _assert_feasible(res, np.zeros((3, 2)), SQUARE)
    assert res.positions[-1, 0] == pytest.approx(1.0, abs=1e-3)


def test_infeasible_polygon_falls_back_without_raising():
    """Too fast for the region: no previous plan -> re-solve without polygon; with one -> brake."""
    fast = np.array([[0.0, 0.0], [2.5, 0.0], [0.0, 0.0]])
    small = SQUARE * 0.3
    mpc = Mpc()
    res = mpc.solve(fast, np.zeros(2), np.zeros(2), small)
    assert res.fallback == "no_polygon" and res.status == "fallback"
    _assert_feasible(res, fast, None)
    assert mpc.solve(np.zeros((3, 2)), np.zeros(2), np.zeros(2), small).ok
    res = mpc.solve(fast, np.zeros(2), np.zeros(2), small)
    assert res.fallback == "brake_previous" and res.u0[0] < 0
    assert mpc.stats["no_polygon"] == 1 and mpc.stats["brake_previous"] == 1 and mpc.stats["failures"] == 2
    mpc.reset()
    assert mpc.solve(fast, np.zeros(2), np.zeros(2), small).fallback == "no_polygon"


def test_infeasible_limits_brake():
    """Speed beyond the limits (infeasible even without polygon) brakes: v and a driven towards 0."""
    mpc = Mpc()
    state = np.array([[0.0, 0.0], [3.0, -0.5], [0.0, 0.0]])
    res = mpc.solve(state, np.ones(2), np.ones(2), SQUARE * 5)
    assert res.fallback == "brake" and mpc.stats["brake"] == 1
    assert res.u0[0] < -1.0 and np.max(np.abs(res.jerks)) <= CFG.j_max
    assert np.linalg.norm(res.velocities[-1]) < 0.5 * np.linalg.norm(state[1])
    assert np.max(np.abs(res.accelerations)) <= CFG.a_max


@pytest.mark.parametrize("solver", ["daqp", "osqp", "quadprog"])
def test_soft_constraint_absorbs_infeasibility(solver):
    """With soft=True the too-fast case is solved with a positive slack instead of a fallback."""
    fast = np.array([[0.0, 0.0], [2.5, 0.0], [0.0, 0.0]])
    cfg = MpcConfig(soft=True, solver=solver)
    res = Mpc(cfg).solve(fast, np.zeros(2), np.zeros(2), SQUARE * 0.3)
    assert res.ok and res.slack > 0.1
    feasible = Mpc(cfg).solve(np.zeros((3, 2)), np.array([5.0, 0]), np.array([5.0, 0]), SQUARE)
    assert feasible.ok and feasible.slack < 1e-5
    _assert_feasible(feasible, np.zeros((3, 2)), SQUARE)


@pytest.mark.parametrize("other", ["osqp", "quadprog"])
def test_backends_agree_with_daqp(other):
    """OSQP and quadprog give DAQP's solution on the same QPs."""
    rng = np.random.default_rng(2)
    daqp_mpc, other_mpc = Mpc(), Mpc(MpcConfig(solver=other))
    compared = 0
    for _ in range(40):
        state, q_s, q_l, poly = _random_case(rng)
        a, b = daqp_mpc.solve(state, q_s, q_l, poly), other_mpc.solve(state, q_s, q_l, poly)
        assert a.fallback == b.fallback
        if a.ok:
            assert np.allclose(a.jerks, b.jerks, atol=2e-3)
            assert np.allclose(a.positions, b.positions, atol=1e-4)
            compared += 1
    assert compared > 20


def test_dropping_unreachable_halfplanes_keeps_the_solution():
    """drop_unreachable removes rows but returns the same plan as the full QP."""
    rng = np.random.default_rng(3)
    full, dropped = Mpc(MpcConfig(drop_unreachable=False)), Mpc()
    for _ in range(100):
        state, q_s, q_l, poly = _random_case(rng)
        a, b = full.solve(state, q_s, q_l, poly), dropped.solve(state, q_s, q_l, poly)
        assert a.fallback == b.fallback and b.rows <= a.rows
        if a.ok:
            assert np.allclose(a.jerks, b.jerks, atol=1e-5)


def test_warm_start_gives_the_cold_solution():
    """Warm-started DAQP returns the same plans as cold solves along a random sequence."""
    rng = np.random.default_rng(4)
    warm, cold = Mpc(MpcConfig(warm_start=True)), Mpc(MpcConfig(warm_start=False))
    assert warm.warm_start and not cold.warm_start
    for _ in range(100):
        state, q_s, q_l, poly = _random_case(rng)
        a, b = warm.solve(state, q_s, q_l, poly), cold.solve(state, q_s, q_l, poly)
        if a.ok and b.ok:
            assert np.allclose(a.jerks, b.jerks, atol=1e-5)


def test_warm_start_default_follows_the_solver():
    """Unset, warm_start is on for OSQP (spec §5) and off for DAQP; an explicit value wins."""
    assert Mpc(MpcConfig(solver="osqp")).warm_start
    assert not Mpc().warm_start
    assert Mpc(MpcConfig(warm_start=True)).warm_start
    assert not Mpc(MpcConfig(solver="osqp", warm_start=False)).warm_start


def test_cost_stop_goal_inside_option():
    """cost_stop='goal_inside' matches 'always' when the goal is inside, differs otherwise."""
    state = np.array([[0.0, 0.0], [1.0, 0.5], [0.5, 0.0]])
    args = (state, np.array([0.1, 0.05]), np.array([1.0, 0.4]), SQUARE * 3)
    always = Mpc().solve(*args)
    paper = Mpc(MpcConfig(cost_stop="goal_inside"))
    assert np.allclose(paper.solve(*args, goal_inside=True).jerks, always.jerks, atol=1e-8)
    assert not np.allclose(paper.solve(*args, goal_inside=False).jerks, always.jerks, atol=1e-3)


def test_osqp_pattern_grows_for_large_polygons():
    """A polygon with more edges than the OSQP slots rebuilds the pattern once and still agrees."""
    ang = -np.linspace(0, 2 * np.pi, 24, endpoint=False)
    poly = 0.8 * np.stack([np.cos(ang), np.sin(ang)], axis=1)
    state = np.array([[0.0, 0.0], [1.5, 0.5], [0.0, 0.0]])
    osqp_mpc = Mpc(MpcConfig(solver="osqp", max_halfplanes=8, drop_unreachable=False))
    a = osqp_mpc.solve(state, np.array([2.0, 0]), np.array([2.0, 0.0]), poly)
    b = Mpc().solve(state, np.array([2.0, 0]), np.array([2.0, 0.0]), poly)
    assert osqp_mpc.stats["osqp_rebuilds"] == 1 and a.ok and b.ok
    assert np.allclose(a.positions, b.positions, atol=1e-4)


def test_invalid_inputs_raise_value_error():
    """NaN/inf or badly shaped inputs raise ValueError at the API boundary."""
    mpc = Mpc()
    with pytest.raises(ValueError, match="non-finite"):
        mpc.solve(np.full((3, 2), np.nan), np.zeros(2), np.zeros(2))
    with pytest.raises(ValueError, match="non-finite"):
        mpc.solve(np.zeros((3, 2)), np.array([np.inf, 0.0]), np.zeros(2))
    with pytest.raises(ValueError, match="state"):
        mpc.solve(np.zeros(6), np.zeros(2), np.zeros(2))
    with pytest.raises(ValueError, match="polygon"):
        mpc.solve(
            np.zeros((3, 2)), np.zeros(2), np.zeros(2), np.array([[0.0, 1.0], [np.nan, 0.0], [1.0, 1.0]])
        )


def test_region_halfplanes_give_the_same_plan():
    """Passing the region's own half-planes plans exactly as computing them from the vertices."""
    rng = np.random.default_rng(4)
    for _ in range(5):
        while not (region := compute_region(random_scan(rng), ANGLES)).success:
            pass
        state = np.array([[0.0, 0.0], rng.uniform(-2, 2, 2), rng.uniform(-3, 3, 2)])
        q_s, q_l = rng.uniform(-1, 1, 2), rng.uniform(-6, 6, 2)
        plain = Mpc().solve(state, q_s, q_l, region.vertices)
        given = Mpc().solve(state, q_s, q_l, region.vertices, halfplanes=(region.normals, region.offsets))
        np.testing.assert_array_equal(plain.jerks, given.jerks)
        assert plain.fallback == given.fallback


def test_unchecked_solve_is_solve():
    """solve_unchecked with the region's half-planes (or none) plans exactly as solve, fallbacks included."""
    rng = np.random.default_rng(9)
    fallbacks = set()
    for k in range(40):
        state, q_s, q_l, polygon = _random_case(rng)
        if k % 4 == 0:
            state[1] = rng.uniform(-9, 9, 2)  # often beyond the limits: the fallback ladder
        planes = halfplanes(polygon) if k % 5 else None
        a, b = Mpc(), Mpc()
        checked = a.solve(state, q_s, q_l, polygon if planes is not None else None, halfplanes=planes)
        unchecked = b.solve_unchecked(state, q_s, q_l, planes)
        np.testing.assert_array_equal(unchecked.jerks, checked.jerks)
        np.testing.assert_array_equal(unchecked.positions, checked.positions)
        assert unchecked.fallback == checked.fallback and a.stats == b.stats
        fallbacks.add(checked.fallback)
    assert None in fallbacks and len(fallbacks) > 1


def test_halfplanes_must_match_the_polygon():
    """Half-planes with a row count other than the polygon's vertex count are rejected."""
    normals, offsets = np.array([[1.0, 0.0], [0.0, 1.0], [-1.0, 0.0]]), np.ones(3)
    with pytest.raises(ValueError, match="halfplanes"):
        Mpc().solve(np.zeros((3, 2)), np.zeros(2), np.zeros(2), SQUARE, halfplanes=(normals, offsets))


def test_osqp_reset_forgets_earlier_episodes() -> None:
    """After reset(), an OSQP MPC solves exactly like a fresh one (no state carried across episodes)."""
    rng = np.random.default_rng(5)
    square = np.array([[-1.0, 1.0], [1.0, 1.0], [1.0, -1.0], [-1.0, -1.0]])  # clockwise
    inputs = [(np.stack([np.zeros(2), rng.uniform(-1, 1, 2), rng.uniform(-1, 1, 2)]),
               rng.uniform(-0.5, 0.5, 2), rng.uniform(-0.8, 0.8, 2)) for _ in range(4)]
    used = Mpc(MpcConfig(solver="osqp"))
    for state, q_s, q_l in inputs[::-1]:
        used.solve(state, q_s, q_l, square)
    used.reset()
    fresh = Mpc(MpcConfig(solver="osqp"))
    for state, q_s, q_l in inputs:
        a, b = used.solve(state, q_s, q_l, square), fresh.solve(state, q_s, q_l, square)
        np.testing.assert_array_equal(a.jerks, b.jerks)


def test_daqp_buffers_reused_across_row_counts_solve_like_fresh() -> None:
    """One DAQP MPC, fed polygons whose row counts rise and fall, plans exactly as fresh MPCs do."""
    rng = np.random.default_rng(6)
    used = Mpc(MpcConfig(drop_unreachable=False))
    cases = [_random_case(rng) for _ in range(12)]
    cases.sort(key=lambda case: len(case[3]))
    cases = cases[::2] + cases[1::2][::-1]  # row counts rise, then fall
    for state, q_s, q_l, poly in cases:
        again = used.solve(state, q_s, q_l, poly)
        fresh = Mpc(MpcConfig(drop_unreachable=False)).solve(state, q_s, q_l, poly)
        np.testing.assert_array_equal(again.jerks, fresh.jerks)
        assert again.rows == fresh.rows == CFG.horizon * len(poly)


@pytest.mark.parametrize("soft", [False, True])
@pytest.mark.parametrize("drop", [False, True])
def test_daqp_fused_assembly_writes_the_generic_problem(soft, drop) -> None:
    """``fill_daqp`` leaves in DAQP's buffers exactly the QP that ``assemble`` + ``polygon_rows`` build,
    also over stale rows from a larger earlier polygon."""
    rng = np.random.default_rng(11)
    mpc = Mpc(MpcConfig(soft=soft, drop_unreachable=drop))
    (free, backend), (m0, n) = _scratch(mpc.config), mpc._a_fixed.shape
    cases = sorted((_random_case(rng) for _ in range(6)), key=lambda case: -len(case[3]))
    for state, q_s, q_l, poly in cases:  # falling polygon sizes: every fill lands on stale rows
        normals, offsets = halfplanes(poly)
        for stop in (False, True):
            problem = mpc._problem(state, q_s, q_l, normals, offsets, stop)
            a, upper, lower, f = backend.reserve(CFG.horizon * len(poly))
            rows = fill_daqp(state, q_s, q_l, stop, mpc._phi, mpc._gamma, mpc._weights, mpc._limits,
                             mpc._lb, mpc._ub, normals, offsets, drop, CFG.t_c, free, a, upper, lower, f)
            assert rows == len(problem.b_poly)
            np.testing.assert_array_equal(f, problem.f)
            np.testing.assert_array_equal(a[: m0 + rows], np.vstack([mpc._a_fixed, problem.a_poly]))
            np.testing.assert_array_equal(upper[: n + m0 + rows], np.concatenate([problem.ub, problem.hi, problem.b_poly]))
            np.testing.assert_array_equal(lower[: n + m0 + rows],
                                          np.concatenate([problem.lb, problem.lo, np.full(rows, -INF)]))


def test_keep_clear_brakes_without_a_region():
    """``keep_clear`` with no polygon brakes (counted) instead of planning unconstrained."""
    mpc = Mpc()
    state = np.array([[0.0, 0.0], [1.5, 0.0], [0.0, 0.0]])
    res = mpc.solve_unchecked(state, np.array([0.3, 0.0]), np.array([3.0, 0.0]), None, False, True)
    assert res.fallback == "brake_no_region" and mpc.stats["brake_no_region"] == 1
    assert res.u0[0] < 0.0  # decelerates


def test_keep_clear_skips_the_unconstrained_rung():
    """With ``keep_clear`` an infeasible polygon QP never falls back to planning without it."""
    mpc = Mpc()
    tiny = orient_clockwise(0.01 * SQUARE)
    state = np.array([[0.0, 0.0], [2.5, 0.0], [0.0, 0.0]])
    res = mpc.solve_unchecked(state, np.array([0.3, 0.0]), np.array([3.0, 0.0]), halfplanes(tiny), False, True)
    assert res.fallback == "brake"


def test_track_short_false_ignores_the_short_term_point():
    """Design 3's MPC (``track_short=False``) gives the same plan whatever Q_s is."""
    mpc = Mpc(MpcConfig(track_short=False))
    state = np.array([[0.0, 0.0], [0.5, 0.2], [0.0, 0.0]])
    a = mpc.solve(state, np.array([0.0, 0.0]), np.array([2.0, 1.0]), SQUARE * 3)
    b = mpc.solve(state, np.array([0.2, -0.2]), np.array([2.0, 1.0]), SQUARE * 3)
    assert a.ok and b.ok and np.allclose(a.jerks, b.jerks, atol=1e-8)
    c = Mpc().solve(state, np.array([0.2, -0.2]), np.array([2.0, 1.0]), SQUARE * 3)
    assert not np.allclose(a.jerks, c.jerks, atol=1e-6)


def test_instances_of_one_config_share_matrices_and_the_thread_scratch() -> None:
    """Equal configs take one set of matrices; instances taking turns on one thread's DAQP buffers
    plan exactly as each does alone, and a solve on another thread uses that thread's buffers."""
    first, second = Mpc(MpcConfig()), Mpc(MpcConfig())
    assert first._h_on is second._h_on and first._a_fixed is _shared(MpcConfig()).a_fixed
    assert Mpc(MpcConfig(horizon=12))._h_on.shape == (24, 24)  # another config: its own
    rng = np.random.default_rng(5)
    cases = [_random_case(rng) for _ in range(8)]
    alone = [Mpc(MpcConfig()).solve(*case).jerks for case in cases]  # a fresh instance per case
    turns = [(first if i % 2 else second).solve(*case).jerks for i, case in enumerate(cases)]
    for a, b in zip(alone, turns, strict=True):
        np.testing.assert_array_equal(a, b)
    seen, results, made_here = [], [], [Mpc(MpcConfig()) for _ in cases]  # fresh: no plan history

    def other_thread() -> None:
        seen.append(_scratch(MpcConfig())[1])
        results.extend(mpc.solve(*case).jerks for mpc, case in zip(made_here, cases, strict=True))

    thread = threading.Thread(target=other_thread)
    thread.start()
    thread.join()
    assert seen[0] is not _scratch(MpcConfig())[1]
    for a, b in zip(alone, results, strict=True):
        np.testing.assert_array_equal(a, b)
