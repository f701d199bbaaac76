"""The crowd scoring core and the action layer's crowd shield (mjnav.control.crowd)."""

from __future__ import annotations

import numpy as np
import pytest

from mjnav.control.crowd import MpcCrowdConfig, ShieldConfig, crowd_long_point, shield_points
from mjnav.geometry.raycast import beam_angles
from mjnav.geometry.region import RegionConfig, RegionFinder
from mjnav.schema import ConfigError

_CONFIG = ShieldConfig(enabled=True)
_INFLATION, _REACH = 0.325, 1.0
_GOAL = np.array([6.0, 0.0])
_Q_L = np.array([2.0, 0.0])  # the action's long-term point: straight at the goal, 2 m/s


def _open_region():
    """The region of a scan that sees nothing within 8 m (robot frame, metres)."""
    return RegionFinder(beam_angles(360), RegionConfig())(np.full(360, 8.0))


def _shield(pedestrians: np.ndarray, velocities: np.ndarray) -> np.ndarray | None:
    return shield_points(_open_region(), _GOAL, np.zeros(2), _Q_L, pedestrians, velocities, _INFLATION, _REACH,
                         _CONFIG)


def test_the_shield_is_off_by_default_and_checks_like_mpc_crowd():
    assert ShieldConfig().enabled is False
    assert isinstance(ShieldConfig(), MpcCrowdConfig)
    with pytest.raises(ConfigError, match="margin"):
        ShieldConfig(margin=0.0)


def test_no_pedestrians_keeps_the_action():
    assert _shield(np.zeros((0, 3)), np.zeros((0, 2))) is None


def test_a_pedestrian_out_of_the_way_keeps_the_action():
    """Behind the robot and walking away: the action's path stays clear."""
    assert _shield(np.array([[-3.0, 0.0, 0.3]]), np.array([[-1.0, 0.0]])) is None


def test_a_pedestrian_walking_into_the_path_replaces_q_l_with_the_crowd_choice():
    """Crossing the straight path 2 m ahead within the horizon: the shield picks mpc_crowd's point,
    which keeps the margin (its own clearance is checked by shield_points returning None for it)."""
    peds, vels = np.array([[2.0, -1.5, 0.3]]), np.array([[0.0, 1.0]])
    q_l = _shield(peds, vels)
    assert q_l is not None
    expected = crowd_long_point(_open_region(), _GOAL, np.zeros(2), peds, vels, _INFLATION, _REACH, _CONFIG)
    np.testing.assert_array_equal(q_l, expected)
    assert not np.allclose(q_l / np.linalg.norm(q_l), [1.0, 0.0])
    kept = shield_points(_open_region(), _GOAL, np.zeros(2), q_l, peds, vels, _INFLATION, _REACH, _CONFIG)
    assert kept is None


def test_a_far_long_point_is_read_at_the_top_candidate_speed():
    """A 10 m Q_l is not a 10 m/s motion: it is judged at max(speeds), so a pedestrian that only a
    10 m/s robot would reach does not trigger the shield."""
    far = np.array([10.0, 0.0])
    peds, vels = np.array([[9.0, 0.0, 0.3]]), np.array([[0.0, 0.0]])
    assert shield_points(_open_region(), _GOAL, np.zeros(2), far, peds, vels, _INFLATION, _REACH, _CONFIG) is None
