"""Episode metrics and aggregation on hand-built episodes with known answers."""

from __future__ import annotations

import csv
import math

import numpy as np
import pytest

from mjnav.eval.metrics import (
    EpisodeMetrics,
    aggregate,
    episode_metrics,
    format_markdown,
    summary_row,
    write_csv,
)


def _straight(steps: int, speed: float, dt: float = 0.1) -> tuple[np.ndarray, np.ndarray]:
    t = np.arange(steps + 1) * dt
    positions = np.column_stack([speed * t, np.zeros_like(t)])
    velocities = np.column_stack([np.full_like(t, speed), np.zeros_like(t)])
    velocities[0] = 0.0
    return positions, velocities


def test_straight_line_time_distance_speed():
    """Constant 1 m/s along x for 10 steps: 1 s, 1 m, mean speed 1 m/s."""
    p, v = _straight(10, 1.0)
    m = episode_metrics(p, v, 0.1, "success")
    assert m.steps == 10
    assert m.time_s == pytest.approx(1.0)
    assert m.distance_m == pytest.approx(1.0)
    assert m.mean_speed == pytest.approx(1.0)
    assert m.heading_change == pytest.approx(0.0)


def test_abs_acc_uses_speed_magnitude_difference():
    """Total Abs Acc is Σ|(‖v_{k+1}‖ − ‖v_k‖)/t_c|: a pure turn at constant speed adds nothing."""
    dt = 0.1
    v = np.array([[0.0, 0.0], [1.0, 0.0], [0.0, 1.0], [0.0, 2.0], [0.0, 1.5]])
    p = np.cumsum(np.vstack([[0.0, 0.0], v[1:] * dt]), axis=0)
    m = episode_metrics(p, v, dt, "success")
    # speeds 0, 1, 1, 2, 1.5 → |Δ| = 1, 0, 1, 0.5 → sum 2.5 / 0.1 = 25
    assert m.abs_acc_sum == pytest.approx(25.0)


def test_jerk_and_heading_change():
    """Second velocity difference gives the jerk; a right-angle turn gives π/2 heading change."""
    dt = 0.1
    v = np.array([[0.0, 0.0], [0.0, 0.0], [0.1, 0.0]])  # Δ²v = 0.1 → jerk 10 m/s³
    p = np.array([[0.0, 0.0], [1.0, 0.0], [1.0, 1.0]])
    m = episode_metrics(p, v, dt, "collision")
    assert m.jerk_rms == pytest.approx(10.0)
    assert m.heading_change == pytest.approx(math.pi / 2)


def test_clearances_and_counts():
    """Minimum clearances ignore non-finite values; NaN when there is nothing of a kind."""
    p, v = _straight(3, 1.0)
    m = episode_metrics(p, v, 0.1, "timeout", obstacle_clearances=[1.0, 0.4, np.inf, 0.7],
                        pedestrian_clearances=[np.nan] * 4, solve_times_ms=[1.0, 2.0, 3.0], fallbacks=1,
                        region_failures=2, scans=4)
    assert m.min_clearance_obstacles == pytest.approx(0.4)
    assert math.isnan(m.min_clearance_pedestrians)
    assert EpisodeMetrics.from_dict(m.to_dict()) == m


def test_bad_shapes_raise():
    """Mismatched arrays or a non-positive period raise ValueError."""
    with pytest.raises(ValueError):
        episode_metrics(np.zeros((3, 2)), np.zeros((4, 2)), 0.1, "success")
    with pytest.raises(ValueError):
        episode_metrics(np.zeros((3, 2)), np.zeros((3, 2)), 0.0, "success")


def test_aggregate_over_successes_only():
    """Rates count all episodes; time/distance/speed/Total Abs Acc use successes only."""
    p1, v1 = _straight(10, 1.0)  # 1 s, 1 m, abs acc 10
    p2, v2 = _straight(20, 2.0)  # 2 s, 4 m, abs acc 20
    p3, v3 = _straight(5, 3.0)  # collision: excluded from the means
    eps = [
        episode_metrics(p1, v1, 0.1, "success", solve_times_ms=[1.0] * 10, fallbacks=1, scans=11),
        episode_metrics(p2, v2, 0.1, "success", solve_times_ms=[3.0] * 20, scans=21),
        episode_metrics(p3, v3, 0.1, "collision", solve_times_ms=[2.0] * 5, scans=6, region_failures=3),
        episode_metrics(p3, v3, 0.1, "timeout", scans=6),
    ]
    s = aggregate(eps)
    assert s["success_rate"] == pytest.approx(0.5)
    assert s["collision_rate"] == pytest.approx(0.25)
    assert s["timeout_rate"] == pytest.approx(0.25)
    assert s["time_s"] == pytest.approx(1.5)
    assert s["distance_m"] == pytest.approx(2.5)
    assert s["speed"] == pytest.approx(1.5)
    assert s["total_abs_acc"] == pytest.approx(30.0)
    assert s["abs_acc_per_episode"] == pytest.approx(15.0)
    assert s["solve_ms_median"] == pytest.approx(3.0)
    assert s["fallback_rate"] == pytest.approx(1 / 40)
    assert s["region_failure_rate"] == pytest.approx(3 / 44)


def test_aggregate_without_successes_is_nan():
    """With no success the success-only means are NaN and the sum is 0."""
    p, v = _straight(3, 1.0)
    s = aggregate([episode_metrics(p, v, 0.1, "collision")])
    assert math.isnan(s["time_s"]) and s["total_abs_acc"] == 0.0


def test_table_writers(tmp_path):
    """Markdown has the paper's columns; CSV round-trips the numbers."""
    p, v = _straight(10, 1.0)
    row = summary_row(aggregate([episode_metrics(p, v, 0.1, "success")]), "stage5", "teb")
    text = format_markdown([row])
    assert "| Success (%) |" in text and "| stage5 | teb | 100.0 |" in text
    write_csv([row], tmp_path / "s.csv")
    with open(tmp_path / "s.csv", encoding="utf-8") as f:
        rows = list(csv.DictReader(f))
    assert rows[0]["policy"] == "teb" and float(rows[0]["time_s"]) == pytest.approx(1.0)
