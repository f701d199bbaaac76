"""The MPC under the region layer's failure modes (:class:`mjnav.control.guarded.GuardedMpc`)."""

from __future__ import annotations

import numpy as np

from mjnav.control.guarded import GuardedMpc
from mjnav.control.mpc import MpcConfig
from mjnav.geometry.region import RegionConfig, compute_region
from tests.geometry.scans import ANGLES, wall_ahead


def test_recovered_region_plans_slowly_inside_it():
    """In a recovered region the plan stays inside it and under recover_speed per axis."""
    guard = GuardedMpc(MpcConfig(), RegionConfig())
    region = compute_region(wall_ahead(0.30), ANGLES)
    assert region.recovered
    state = np.array([[0.0, 0.0], [0.0, 0.2], [0.0, 0.0]])
    res = guard.solve(state, np.array([0.0, 0.3]), np.array([0.0, 3.0]), region)
    assert res.ok and np.abs(res.velocities).max() <= 0.5 + 1e-6
    assert (region.normals @ res.positions.T <= region.offsets[:, None] + 1e-5).all()


def test_escape_is_required_only_without_a_polygon_in_recover_mode():
    """must_escape: recover mode without any polygon; never in paper mode or for unconstrained designs."""
    none = compute_region(wall_ahead(0.20), ANGLES)
    assert not none.has_polygon
    assert GuardedMpc(MpcConfig(), RegionConfig()).must_escape(none)
    assert not GuardedMpc(MpcConfig(), RegionConfig(on_failure="paper")).must_escape(none)
    assert not GuardedMpc(MpcConfig(), RegionConfig(), constrained=False).must_escape(none)
