"""Social-navigation metrics: hand-made traces with hand-computed values, the summary's intervals,
and the fields a real evaluation writes."""

from __future__ import annotations

import dataclasses
import json
import math

import numpy as np
import pytest

from mjnav.eval import social
from mjnav.eval.intervals import wilson
from mjnav.eval.runner import EpisodeTrace, EvalSpec, evaluate, read_jsonl
from mjnav.eval.social import SocialMetrics, SocialThresholds, aggregate_social, social_metrics, time_to_collision

DT = 0.1  # s


def _static_peds(steps: int, *circles: tuple[float, float, float]) -> np.ndarray:
    """(steps+1, P, 3) pedestrians standing still."""
    return np.tile(np.array(circles, dtype=float)[None], (steps + 1, 1, 1))


def test_passing_a_standing_pedestrian_at_a_known_distance() -> None:
    """The robot (r = 0.3 m) drives along y = 0 at 1 m/s past a pedestrian (r = 0.3 m) standing at
    (0, 1): the smallest gap is 1 − 0.6 = 0.4 m; the gap is below 0.45 m for |x| < √(1.05² − 1) =
    0.320 m (7 instants), below 1.2 m for |x| < √(1.8² − 1) = 1.497 m (29 instants), never below 0.2 m;
    a standing pedestrian is never on a collision course with a robot passing 1 m to its side."""
    x = np.linspace(-5.0, 5.0, 101)
    pos = np.stack([x, np.zeros_like(x)], axis=1)
    vel = np.tile([1.0, 0.0], (101, 1))
    m = social_metrics(pos, vel, _static_peds(100, (0.0, 1.0, 0.3)), DT, 0.3, (-5, 0), (5, 0), "success")
    assert m.min_ped_distance_m == pytest.approx(0.4)
    assert (m.intrusion_steps, m.personal_steps, m.social_steps) == (0, 7, 29)
    assert m.personal_time_s == pytest.approx(0.7) and m.personal_share == pytest.approx(0.07)
    assert m.social_time_s == pytest.approx(2.9) and m.social_share == pytest.approx(0.29)
    assert m.near_misses == 0 and math.isnan(m.min_ttc_s)
    assert (m.straight_line_m, m.path_length_m) == pytest.approx((10.0, 10.0))
    assert m.path_efficiency == pytest.approx(1.0) and m.spl == pytest.approx(1.0)
    assert m.stopped_steps == 0 and m.ped_speed_near == 0.0 and m.ped_speed_far == 0.0
    assert m.to_dict()["min_ttc_s"] is None
    back = SocialMetrics.from_dict(json.loads(json.dumps(m.to_dict())))  # NaN -> null -> NaN
    assert dataclasses.replace(back, min_ttc_s=0.0) == dataclasses.replace(m, min_ttc_s=0.0)


def test_head_on_approach_has_the_known_time_to_collision() -> None:
    """Robot (r = 0.3) at 1 m/s towards a pedestrian (r = 0.2) 5 m ahead walking at 0.5 m/s towards it:
    at k = 0 the gap is 4.5 m closing at 1.5 m/s, TTC 3 s; after 10 steps 1.5 m less, TTC 2 s (the
    episode's minimum). The pedestrian's velocity comes from its positions alone."""
    k = np.arange(11)
    pos = np.stack([0.1 * k, np.zeros(11)], axis=1)
    vel = np.tile([1.0, 0.0], (11, 1))
    peds = np.stack([5.0 - 0.05 * k, np.zeros(11), np.full(11, 0.2)], axis=1)[:, None, :]
    m = social_metrics(pos, vel, peds, DT, 0.3, (0, 0), (1, 0), "timeout")
    assert m.min_ttc_s == pytest.approx(2.0)
    assert social.pedestrian_velocities(peds, DT)[:, 0] == pytest.approx(np.tile([-0.5, 0.0], (11, 1)))
    assert time_to_collision(np.array([5.0, 0.0]), np.array([-1.5, 0.0]), np.array(0.5)) == pytest.approx(3.0)
    assert time_to_collision(np.array([0.4, 0.0]), np.array([1.0, 0.0]), np.array(0.5)) == 0.0  # overlapping
    assert time_to_collision(np.array([5.0, 0.0]), np.array([1.0, 0.0]), np.array(0.5)) == np.inf  # receding
    short = social_metrics(pos, vel, peds, DT, 0.3, (0, 0), (1, 0), "timeout", thresholds=SocialThresholds(
        ttc_horizon_s=1.5))
    assert math.isnan(short.min_ttc_s)  # beyond the horizon


def test_detour_has_the_known_path_efficiency() -> None:
    """A detour (0,0) → (2,2) → (4,0) to a goal 4 m away is 4√2 m long: efficiency 1/√2; SPL is that on
    success and 0 otherwise; the goal tolerance shortens the straight line (4 − 0.5 m)."""
    pos = np.array([[0, 0], [1, 1], [2, 2], [3, 1], [4, 0]], dtype=float)
    vel = np.zeros_like(pos)
    empty = np.zeros((5, 0, 3))
    win = social_metrics(pos, vel, empty, DT, 0.3, (0, 0), (4, 0), "success")
    assert win.path_length_m == pytest.approx(4 * math.sqrt(2))
    assert win.path_efficiency == pytest.approx(1 / math.sqrt(2)) and win.spl == pytest.approx(1 / math.sqrt(2))
    assert social_metrics(pos, vel, empty, DT, 0.3, (0, 0), (4, 0), "collision").spl == 0.0
    tol = social_metrics(pos, vel, empty, DT, 0.3, (0, 0), (4, 0), "success", goal_tolerance=0.5)
    assert tol.straight_line_m == pytest.approx(3.5) and tol.path_efficiency == pytest.approx(3.5 / (4 * math.sqrt(2)))
    assert win.stopped_steps == 4 and win.stopped_time_s == pytest.approx(0.4) and win.stopped_share == 1.0
    assert math.isnan(win.min_ped_distance_m) and win.social_steps == 0 and math.isnan(win.min_ttc_s)


def test_near_misses_are_distinct_approaches_without_contact() -> None:
    """Gaps 1, .15, .25, .15, 1, .1, 1, −.05, 1 m (threshold 0.2 m, release above 0.3 m): the jitter
    inside the first approach is one event, the second approach another, the contact none."""
    gaps = [1.0, 0.15, 0.25, 0.15, 1.0, 0.1, 1.0, -0.05, 1.0]
    n = len(gaps)
    peds = np.stack([np.array(gaps) + 0.5, np.zeros(n), np.full(n, 0.2)], axis=1)[:, None, :]
    still = np.zeros((n, 2))
    m = social_metrics(still, still, peds, DT, 0.3, (0, 0), (1, 0), "collision")
    assert m.near_misses == 2 and m.min_ped_distance_m == pytest.approx(-0.05)
    assert json.loads(json.dumps(m.to_dict()))["near_misses"] == 2  # plain Python numbers, JSON-ready
    assert m.intrusion_steps == 4  # instants 1..T below 0.2 m: .15, .15, .1, −.05
    assert m.ped_accel_near > 0  # the pedestrian moves back and forth


def test_absent_pedestrians_and_the_robots_influence() -> None:
    """NaN rows (an absent pedestrian) are ignored; a pedestrian near the robot walking at 0.2 m/s and one
    far away at 1 m/s give speed near 0.2 and far 1.0 m/s, acceleration 0."""
    k = np.arange(21)
    still = np.zeros((21, 2))
    near = np.stack([1.0 + 0.02 * k, np.zeros(21), np.full(21, 0.2)], axis=1)
    far = np.stack([np.full(21, -8.0), -5.0 + 0.1 * k, np.full(21, 0.2)], axis=1)
    absent = np.full((21, 3), np.nan)
    m = social_metrics(still, still, np.stack([near, far, absent], axis=1), DT, 0.3, (0, 0), (1, 0), "timeout")
    assert m.ped_speed_near == pytest.approx(0.2) and m.ped_speed_far == pytest.approx(1.0)
    assert m.ped_accel_near == pytest.approx(0.0, abs=1e-9) and m.ped_accel_far == pytest.approx(0.0, abs=1e-9)
    assert m.min_ped_distance_m == pytest.approx(0.5)


def _circling(steps: int, radius: float, rate: float, r: float = 0.2) -> np.ndarray:
    """(steps+1, 3) a pedestrian walking round the origin at ``radius`` m, ``rate`` rad/s (several turns)."""
    angle = rate * DT * np.arange(steps + 1)
    return np.stack([radius * np.cos(angle), radius * np.sin(angle), np.full(steps + 1, r)], axis=1)


def test_pedestrians_turning_near_the_robot_have_the_known_turn_rate() -> None:
    """The robot (r = 0.3) stands at the origin. A pedestrian circling it 1 m away (gap 0.5 m, near) at 0.5
    rad/s turns its finite-difference velocity by exactly 0.5·t_c per step, also across θ = ±π: 0.5 rad/s
    near; one walking straight 8 m away turns 0 rad/s far. A pedestrian jittering in place (heading flips
    by π each step) is slower than ``turn_min_speed`` and left out. The non-reactive control: the same
    walker going straight past the robot turns 0 rad/s near and far."""
    steps, still = 200, np.zeros((201, 2))
    k = np.arange(201)
    straight_far = np.stack([-10.0 + 0.05 * k, np.full(201, 8.0), np.full(201, 0.2)], axis=1)
    jitter = np.stack([0.9 + 0.001 * (k % 2), np.zeros(201), np.full(201, 0.2)], axis=1)
    peds = np.stack([_circling(steps, 1.0, 0.5), straight_far, jitter], axis=1)
    m = social_metrics(still, still, peds, DT, 0.3, (0, 0), (1, 0), "timeout")
    assert m.ped_turn_near == pytest.approx(0.5) and m.ped_turn_far == pytest.approx(0.0, abs=1e-12)
    assert m.ped_speed_far == pytest.approx(0.5)
    counted = social_metrics(still, still, peds, DT, 0.3, (0, 0), (1, 0), "timeout",
                             thresholds=SocialThresholds(turn_min_speed=0.005))
    assert counted.ped_turn_near > 10  # with the threshold below its 0.01 m/s jitter, its flips count
    passing = np.stack([-5.0 + 0.05 * k, np.full(201, 1.0), np.full(201, 0.2)], axis=1)[:, None, :]
    control = social_metrics(still, still, passing, DT, 0.3, (0, 0), (1, 0), "timeout")
    assert control.ped_turn_near == pytest.approx(0.0, abs=1e-12) and control.ped_turn_far == pytest.approx(
        0.0, abs=1e-12)
    assert math.isnan(social_metrics(still, still, jitter[:, None, :], DT, 0.3, (0, 0), (1, 0),
                                     "timeout").ped_turn_near)  # no moving pedestrian: undefined
    with pytest.raises(ValueError, match="turn_min_speed"):
        SocialThresholds(turn_min_speed=0.0)


def test_records_without_the_turn_rate_still_load() -> None:
    """Records written before the turn rate (no ``ped_turn_*``) read back with NaN there; the summary skips them."""
    old = {k: v for k, v in _blank(10).to_dict().items() if not k.startswith("ped_turn")}
    assert math.isnan(SocialMetrics.from_dict(old).ped_turn_near)
    new = dataclasses.replace(_blank(10), ped_turn_near=0.4, ped_turn_far=0.1).to_dict()
    s = aggregate_social([{"outcome": "success", "social": old}, {"outcome": "success", "social": new}])
    assert (s["ped_turn_near"], s["ped_turn_far"]) == pytest.approx((0.4, 0.1))


def test_trace_input_and_thresholds_in_one_place() -> None:
    """An EpisodeTrace carries its control period; thresholds are validated and named in the columns."""
    x = np.linspace(0, 1, 11)
    pos = np.stack([x, 0 * x], axis=1)
    trace = EpisodeTrace(pos, np.tile([1.0, 0.0], (11, 1)), np.zeros((11, 0, 3)), control_period=0.2)
    assert social.trace_social_metrics(trace, 0.3, (0, 0), (1, 0), "success").stopped_time_s == 0.0
    assert social.trace_social_metrics(trace, 0.3, (0, 0), (1, 0), "success").steps == 10
    with pytest.raises(ValueError, match="intrusion"):
        SocialThresholds(intrusion_m=0.5, personal_space_m=0.45)
    with pytest.raises(dataclasses.FrozenInstanceError):
        social.THRESHOLDS.intrusion_m = 0.1  # type: ignore[misc]
    labels = " ".join(label for _, label, _ in social.SOCIAL_COLUMNS)
    assert "0.2 m" in labels and "0.45 m" in labels and "1.2 m" in labels


def test_summary_gives_every_rate_a_wilson_interval() -> None:
    """Pooled step shares and episode rates carry their 95 % Wilson intervals; collision kinds count over the
    records that carry one; records without social metrics (older files) are left out."""
    def record(outcome: str, kind: str | None, intrusion: int, steps: int = 10) -> dict:
        m = dataclasses.replace(_blank(steps), intrusion_steps=intrusion, near_misses=int(intrusion > 0))
        return {"outcome": outcome, "collision_kind": kind, "social": m.to_dict()}

    records = [record("success", None, 0), record("collision", "pedestrian", 3), record("collision", "wall", 1),
               record("timeout", None, 0), {"outcome": "success", "metrics": {}}]
    s = aggregate_social(records)
    assert s["social_episodes"] == 4
    assert s["intrusion_share"] == pytest.approx(4 / 40)
    assert (s["intrusion_share_lo"], s["intrusion_share_hi"]) == pytest.approx(wilson(4, 40))
    assert s["intrusion_episode_rate"] == 0.5 and s["near_miss_episode_rate"] == 0.5
    assert s["collision_pedestrian_rate"] == 0.25 and s["collision_wall_rate"] == 0.25
    assert s["collision_obstacle_rate"] == 0 and (s["collision_obstacle_rate_lo"], s["collision_obstacle_rate_hi"]) \
        == pytest.approx(wilson(0, 4))
    rates = [k for k in s if k.endswith("_rate") or k.endswith("_share")]
    assert rates and all(f"{k}_lo" in s and f"{k}_hi" in s for k in rates)


def _blank(steps: int) -> SocialMetrics:
    names = [f.name for f in dataclasses.fields(SocialMetrics)]
    values = {n: (0 if n.endswith(("_steps", "near_misses")) else 0.0) for n in names}
    return SocialMetrics(**{**values, "steps": steps, "min_ttc_s": math.nan})


def test_a_real_evaluation_writes_the_social_fields(tmp_path) -> None:
    """Each JSONL record has the social metrics and the collision kind (also under the paper's rule), the
    summary has them with intervals, and summary.md shows the social columns."""
    from mjnav.eval.runner import evaluate_tasks

    spec = EvalSpec("stage5", "mpc_goal", 2, 0, ("timing.episode_steps=20", "collision=contact"), 1)
    rows = evaluate_tasks([spec], tmp_path, progress=False)
    records = read_jsonl(tmp_path / "stage5.jsonl")
    fields = {f.name for f in dataclasses.fields(SocialMetrics)}
    for r in records:
        assert set(r["social"]) == fields and "collision_kind" in r
        assert r["collision_kind"] in (None, *social.COLLISION_KINDS)
        assert r["paper_rule"] is None or {"social", "collision_kind"} <= set(r["paper_rule"])
        assert r["social"]["steps"] == r["metrics"]["steps"]
    assert rows[0]["social_episodes"] == 2 and "intrusion_share_lo" in rows[0] and "success_rate_hi" in rows[0]
    assert {"ped_turn_near", "ped_turn_far", "ped_speed_near", "ped_accel_far"} <= set(rows[0])
    assert "Near misses / ep." in (tmp_path / "summary.md").read_text()
    assert "intrusion_share_hi" in (tmp_path / "summary.csv").read_text().splitlines()[0]
    again = evaluate(spec, tmp_path, progress=False)  # a resumed summary reads the fields back
    assert again["social_share"] == rows[0]["social_share"]


def test_tables_show_the_social_metrics_on_request() -> None:
    """format_table(social=True) adds the social table (rates with their interval); records that predate
    the social metrics show "–"."""
    from mjnav.eval import tables

    metrics = {"time_s": 5.0, "distance_m": 4.0, "mean_speed": 1.0}
    new = [{"outcome": "success", "metrics": metrics, "collision_kind": None,
            "social": dataclasses.replace(_blank(10), intrusion_steps=2).to_dict()}] * 3
    old = [{"outcome": "success", "metrics": metrics}] * 3
    rows = [{"stage": "stage5", "method": m, "paper": (), "status": "ok", "scan": tables._stats(r)}
            for m, r in (("new", new), ("old", old))]
    text = tables.format_table(rows, social=True)
    assert text.startswith(tables.format_table(rows)) and "intrusion % steps" in text
    lo, hi = wilson(6, 30)
    assert f"20.0 [{100 * lo:.1f}, {100 * hi:.1f}]" in text
    assert "ped. turn rate near / far rad/s" in text and "| 0.000 / 0.000 |" in text  # near / far in one cell
    assert text.splitlines()[-1].startswith("| stage5 | old | – |")
