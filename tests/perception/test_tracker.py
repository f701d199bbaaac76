"""The LiDAR pedestrian tracker on analytic scans (circles and wall segments, 360 beams, σ = 0.05 m)."""

from __future__ import annotations

import numpy as np
import pytest

from mjnav.geometry.raycast import add_noise, beam_angles, cast_rays
from mjnav.perception import Tracker, TrackerConfig, nearest_tracks
from mjnav.perception.scoring import TrackingScore, line_of_sight, match_tracks

ANGLES = beam_angles(360)
DT = 0.1
NO_SEGMENTS = np.zeros((0, 4))


def _scan(circles: np.ndarray, segments: np.ndarray, rng: np.random.Generator,
          origin: np.ndarray | None = None) -> np.ndarray:
    """A noisy 360-beam scan from ``origin`` (default the world origin)."""
    origin = np.zeros(2) if origin is None else origin
    ranges = cast_rays(origin, ANGLES, segments, circles if len(circles) else None, 10.0)
    return add_noise(ranges, 0.05, 10.0, rng)


def _walk(tracker: Tracker, circles: np.ndarray, velocity: np.ndarray, segments: np.ndarray, steps: int,
          seed: int = 0) -> np.ndarray:
    """Move ``circles`` at ``velocity`` (m/s) for ``steps`` control steps, tracking each scan; final circles."""
    rng = np.random.default_rng(seed)
    circles = circles.copy()
    for _ in range(steps):
        circles[:, :2] += DT * velocity
        tracker.step(_scan(circles, segments, rng), np.zeros(2), DT)
    return circles


def test_single_walking_pedestrian_velocity_converges() -> None:
    """One pedestrian walking across the scan gives one track whose velocity converges to the truth."""
    tracker = Tracker()
    velocity = np.array([[0.0, 0.4]])
    final = _walk(tracker, np.array([[3.0, -1.0, 0.25]]), velocity, NO_SEGMENTS, 50)
    tracks = tracker.tracks()
    assert len(tracks) == 1
    assert np.linalg.norm(tracks[0].position - final[0, :2]) < 0.1
    assert np.linalg.norm(tracks[0].velocity - velocity[0]) < 0.15
    assert tracks[0].covariance.shape == (4, 4) and 0.1 <= tracks[0].radius <= 0.4


def test_two_touching_pedestrians_give_two_tracks() -> None:
    """Two pedestrians walking side by side, touching, are split at their notch into two tracks."""
    tracker = Tracker()
    circles = np.array([[2.5, -0.25, 0.25], [2.5, 0.25, 0.25]])
    final = _walk(tracker, circles, np.array([[0.3, 0.0], [0.3, 0.0]]), NO_SEGMENTS, 30)
    tracks = tracker.track_array()
    assert len(tracks) == 2
    assert (match_tracks(tracks, final, 0.2) >= 0).all()
    assert len(set(tracks[:, 5])) == 2


def test_pedestrian_by_a_wall_and_the_wall_is_not_tracked() -> None:
    """A pedestrian walking along a wall, touching it, is tracked; the wall gives no track."""
    wall = np.array([[4.0, -4.0, 4.0, 4.0]])
    tracker = Tracker()
    final = _walk(tracker, np.array([[3.75, -1.0, 0.25]]), np.array([[0.0, 0.3]]), wall, 40)
    tracks = tracker.track_array()
    assert len(tracks) == 1
    # wall points beside the bulge widen the fitted circle and push it towards the wall: within the
    # scoring's 0.3 m match distance, not the 0.1 m of a free-standing pedestrian
    assert np.hypot(*(tracks[0, :2] - final[0, :2])) < 0.3


def test_walls_alone_give_no_tracks() -> None:
    """A closed room and a box obstacle, seen from a moving robot, are never reported as pedestrians."""
    room = np.array([[-5, -5, 5, -5], [5, -5, 5, 5], [5, 5, -5, 5], [-5, 5, -5, -5],
                     [2, 1, 3, 1], [3, 1, 3, 2], [3, 2, 2, 2], [2, 2, 2, 1]], dtype=float)
    tracker, rng = Tracker(), np.random.default_rng(1)
    reported = 0
    for k in range(60):
        robot = np.array([-2.0 + 0.05 * k, -1.0])
        tracker.step(_scan(np.zeros((0, 3)), room, rng, robot), robot, DT)
        reported += len(tracker.track_array())
    assert reported == 0


@pytest.mark.parametrize("misses", [4, 5])
def test_occluded_track_survives_k_minus_one_misses_and_dies_after_k(misses: int) -> None:
    """With max_misses = 5, a track coasts through 4 empty scans and is gone after the 5th."""
    tracker = Tracker(TrackerConfig(max_misses=5))
    _walk(tracker, np.array([[2.0, 0.0, 0.3]]), np.array([[0.0, 0.3]]), NO_SEGMENTS, 10)
    (before,) = tracker.tracks()
    empty = np.full(360, 10.0)
    for _ in range(misses):
        tracker.step(empty, np.zeros(2), DT)
    after = tracker.tracks()
    if misses < 5:
        assert [t.id for t in after] == [before.id]
    else:
        assert after == []


def test_tracker_is_deterministic() -> None:
    """The same scans give the same tracks, bit for bit, and reset() starts over identically."""
    circles = np.array([[2.0, 1.0, 0.2], [-3.0, 0.5, 0.35], [1.0, -2.5, 0.3]])
    velocity = np.array([[0.3, 0.1], [0.0, -0.5], [-0.4, 0.2]])
    a, b = Tracker(), Tracker()
    _walk(a, circles, velocity, NO_SEGMENTS, 25, seed=3)
    _walk(b, circles, velocity, NO_SEGMENTS, 25, seed=3)
    first = a.track_array()
    assert np.array_equal(first, b.track_array()) and len(first) == 3
    a.reset()
    _walk(a, circles, velocity, NO_SEGMENTS, 25, seed=3)
    assert np.array_equal(first, a.track_array())


@pytest.mark.parametrize("bad", [{"gate": -1.0}, {"radius": (0.3, 0.1)}, {"confirm_hits": 6},
                                 {"max_misses": 0}, {"notch_depth": -0.1}])
def test_bad_config_is_refused(bad: dict) -> None:
    """A non-positive distance, an inverted radius range or an impossible confirmation rule raises."""
    with pytest.raises(ValueError, match="tracker"):
        TrackerConfig(**bad)


def test_bad_scan_shape_is_refused() -> None:
    """A scan of the wrong length raises instead of being misread."""
    with pytest.raises(ValueError, match="scan of shape"):
        Tracker().step(np.ones(180), np.zeros(2), DT)


def test_nearest_tracks_pads_and_orders() -> None:
    """The planner array holds the K nearest tracks first, then zero rows marked invalid."""
    tracks = np.array([[3.0, 0, 0, 0, 0.2, 0], [1.0, 0, 0, 0, 0.3, 1], [5.0, 0, 0, 0, 0.2, 2]])
    out = nearest_tracks(tracks, np.zeros(2), 4)
    assert out.shape == (4, 6)
    assert out[:3, 0].tolist() == [1.0, 3.0, 5.0] and out[:, 5].tolist() == [1, 1, 1, 0]


def test_line_of_sight_hides_a_pedestrian_behind_another() -> None:
    """A pedestrian fully behind a nearer, wider one is not in line of sight; one behind a wall neither."""
    circles = np.array([[2.0, 0.0, 0.4], [4.0, 0.0, 0.2], [-2.0, 0.0, 0.3]])
    wall = np.array([[-1.0, -2.0, -1.0, 2.0]])
    assert line_of_sight(np.zeros(2), ANGLES, wall, circles, 10.0).tolist() == [True, False, False]


def test_score_counts_switches() -> None:
    """A pedestrian matched to a new identity counts one identity switch."""
    score, truth = TrackingScore(), np.array([[1.0, 0.0, 0.2]])
    for track_id in (0, 0, 7):
        score.add(np.array([[1.05, 0, 0, 0, 0.2, track_id]]), truth, None, np.zeros(2), np.array([True]))
    summary = score.summary()
    assert summary["id_switches"] == 1 and summary["precision"] == 1.0 and summary["recall_near_los"] == 1.0
