"""The compiled band solver (:mod:`mjnav.planners.trf`) returns scipy's ``least_squares`` result bit for bit."""

from __future__ import annotations

import numpy as np
import pytest
from scipy.optimize import least_squares

from mjnav.planners import teb, trf

pytestmark = pytest.mark.skipif(not trf.available(), reason="numpy's BLAS not found: the planner uses scipy")


def _problem(rng: np.random.Generator, cfg: teb.TebConfig) -> tuple:
    """A perturbed straight band towards a random goal among random obstacle points."""
    goal = rng.uniform(-3.5, 3.5, 2)
    band = teb.straight_band(goal, cfg)
    n = len(band.dts)
    z = np.concatenate([(band.poses[1:-1] + rng.normal(0, 0.2, (n - 1, 2))).ravel(),
                        np.maximum(band.dts * rng.uniform(0.5, 1.5, n), 0.02)])
    points = rng.uniform(-4, 4, (int(rng.integers(0, 40)), 2))
    poses = np.vstack([np.zeros(2), z[: 2 * (n - 1)].reshape(n - 1, 2), goal])
    assoc = teb._associate(poses, points, cfg.obstacles_per_pose)
    lower = np.concatenate([np.full(2 * (n - 1), -np.inf), np.full(n, 0.01)])
    return z, n, goal, rng.normal(0, 1.0, 2), assoc, lower


@pytest.mark.parametrize("seed", range(40))
def test_solve_band_is_least_squares(seed: int) -> None:
    cfg = teb.TebConfig()
    z, n, goal, v_start, assoc, lower = _problem(np.random.default_rng(seed), cfg)
    w_obs = cfg.w_obstacle * cfg.weight_adapt ** (seed % 3)
    ref = least_squares(teb._residuals, z, jac_sparsity=teb._sparsity(n, cfg.obstacles_per_pose),
                        bounds=(lower, np.inf), args=(n, goal, v_start, assoc, cfg, w_obs),
                        max_nfev=cfg.inner_evaluations, x_scale=1.0, method="trf").x
    got = trf.solve_band(z, n, goal, v_start, assoc, teb._terms(cfg), w_obs, lower, cfg.inner_evaluations,
                         teb._structure(n, cfg.obstacles_per_pose))
    assert got.tobytes() == ref.tobytes()


def test_residuals_match_numpy() -> None:
    cfg = teb.TebConfig()
    rng = np.random.default_rng(7)
    for _ in range(20):
        z, n, goal, v_start, assoc, _ = _problem(rng, cfg)
        ref = teb._residuals(z, n, goal, v_start, assoc, cfg, 200.0)
        assert trf.residuals(z, n, goal, v_start, assoc, teb._terms(cfg), 200.0).tobytes() == ref.tobytes()


def test_bad_start_raises_like_scipy() -> None:
    cfg = teb.TebConfig()
    z, n, goal, v_start, assoc, lower = _problem(np.random.default_rng(0), cfg)
    z[-1] = 0.0  # an interval below its lower bound
    with pytest.raises(ValueError, match="outside of provided bounds"):
        trf.solve_band(z, n, goal, v_start, assoc, teb._terms(cfg), 50.0, lower, 8, teb._structure(n, 2))


def test_trust_region_2d_is_scipys() -> None:
    from scipy.optimize._lsq.common import solve_trust_region_2d

    rng = np.random.default_rng(3)
    for _ in range(2000):
        a = rng.normal(size=(5, 2))
        B = a.T @ a + rng.choice([0.0, -1.0]) * np.eye(2)  # positive definite or not
        g, delta = rng.normal(size=2), float(rng.uniform(0.01, 3.0))
        assert trf._trust_region_2d(B, g, delta).tobytes() == solve_trust_region_2d(B, g, delta)[0].tobytes()


def test_optimize_band_same_with_scipy_fallback(monkeypatch: pytest.MonkeyPatch) -> None:
    cfg = teb.TebConfig()
    rng = np.random.default_rng(11)
    goal, points = np.array([3.0, 1.0]), rng.uniform(-4, 4, (30, 2))
    fast, fast_cost = teb.optimize_band(teb.straight_band(goal, cfg), np.array([0.5, 0.0]), points, cfg)
    monkeypatch.setattr(trf, "available", lambda: False)
    slow, slow_cost = teb.optimize_band(teb.straight_band(goal, cfg), np.array([0.5, 0.0]), points, cfg)
    assert fast.poses.tobytes() == slow.poses.tobytes() and fast.dts.tobytes() == slow.dts.tobytes()
    assert fast_cost == slow_cost
