"""DWA's compiled clearance kernel gives numpy's numbers bit for bit."""

from __future__ import annotations

import numpy as np
import pytest

from mjnav.planners.dwa import _nearest_distance


@pytest.mark.parametrize("seed", range(5))
def test_nearest_distance_matches_numpy(seed: int) -> None:
    rng = np.random.default_rng(seed)
    path = rng.uniform(-2.5, 2.5, (122, 1, 2)) * (np.arange(1, 16) * 0.1)[None, :, None]
    points = rng.uniform(-6, 6, (int(rng.integers(1, 180)), 2))
    diff = path[:, :, None, :] - points[None, None, :, :]
    ref = np.hypot(diff[..., 0], diff[..., 1]).min(axis=2)
    assert _nearest_distance(path, points).tobytes() == ref.tobytes()


def test_nearest_distance_propagates_nan() -> None:
    path = np.array([[[np.nan, 0.0], [1.0, 0.0]]])
    points = np.array([[0.0, 0.0], [2.0, 0.0]])
    out = _nearest_distance(path, points)
    assert np.isnan(out[0, 0]) and out[0, 1] == 1.0
