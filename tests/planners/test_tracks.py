"""Planners with the LiDAR tracks: ``planner.tracks=true`` for teb, dwa and mpc_goal, and
``mpc_tracked``; they declare ``uses_tracks`` (and nothing privileged), their records say so, they
keep clear of predicted discs, and tables list them with and without tracks."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest

from mjnav import cli
from mjnav.config import load_task
from mjnav.eval.tables import planner_method, table_rows
from mjnav.geometry.raycast import beam_angles
from mjnav.geometry.region import compute_region
from mjnav.planners import make_planner, resolve_planner
from mjnav.planners.base import PlannerInput, declared_privileged, declared_tracks
from mjnav.planners.dwa import DwaConfig, rollout_times, score_velocities
from mjnav.planners.teb import Band, TebConfig, optimize_band
from mjnav.planners.tracks import predicted_discs, scan_with_discs, untracked_points
from mjnav.schema import ConfigError

TRACKING = [("teb", ("tracks=true",)), ("dwa", ("tracks=true",)), ("mpc_goal", ("tracks=true",)),
            ("mpc_tracked", ()), ("mpc_tracked", ("track_region=true",))]


@pytest.mark.parametrize("name", ["teb", "dwa", "mpc_goal"])
def test_tracks_are_off_by_default_and_declared_when_on(name):
    """Default: no uses_tracks (the task runs no tracker); tracks=true: uses_tracks, not privileged."""
    assert not declared_tracks(make_planner(name))
    planner = make_planner(name, ["tracks=true"])
    assert declared_tracks(planner) and declared_privileged(planner) == frozenset()


def test_mpc_tracked_is_registered_not_privileged_and_reads_tracks():
    """mpc_tracked: registered, privileged nothing, uses_tracks, mpc_crowd's parameters."""
    found = resolve_planner("mpc_tracked")
    assert found.privileged == frozenset() and declared_tracks(found.make())
    assert {"margin", "horizon", "track_region"} <= set(found.params())


def test_prediction_and_discs_in_the_scan():
    """Constant-velocity discs; the beams they stop read shorter, the rest are unchanged; discs
    within the keep-out distance of the robot are left out."""
    tracks = np.array([[2.0, 0.0, 1.0, 0.0, 0.3], [0.5, 0.0, 0.0, 0.0, 0.3]])
    discs = predicted_discs(tracks, np.array([0.0, 1.0]))
    np.testing.assert_allclose(discs[1, 0], [3.0, 0.0, 0.3])
    angles = beam_angles(360)
    scan = np.full(360, 10.0)
    out = scan_with_discs(scan, angles, discs[:, :1], 10.0, 0.5)
    assert out[0] == pytest.approx(1.7) and out[180] == 10.0
    assert np.all(scan_with_discs(scan, angles, discs[:, 1:], 10.0, 0.5) == scan)  # too close: left out


def test_untracked_points_leave_the_tracked_pedestrians_to_the_prediction():
    """Points within a track's radius + pad of its centre go; the others stay, in order."""
    points = np.array([[1.0, 0.0], [2.1, 0.0], [2.0, 0.45], [3.0, 3.0]])
    tracks = np.array([[2.0, 0.0, 1.0, 0.0, 0.3]])
    np.testing.assert_array_equal(untracked_points(points, tracks, 0.1), points[[0, 2, 3]])
    np.testing.assert_array_equal(untracked_points(points, np.zeros((0, 5)), 0.1), points)


def test_dwa_rollouts_meet_a_predicted_disc_at_its_time():
    """A pedestrian coming head-on: with tracks, the straight-ahead velocity's clearance drops below
    zero (its score below the sideways one's); the sideways one is unchanged."""
    cfg, from_limits = DwaConfig(), load_task("stage5")
    from mjnav.control.dynamics import Limits

    limits = Limits.from_task(from_limits)
    cand = np.array([[1.5, 0.0], [0.0, 1.5]])
    walker = np.array([[4.0, 0.0, -1.5, 0.0, 0.3]])  # meets the robot at x = 2 m after 1.33 s
    discs = predicted_discs(walker, rollout_times(cfg))
    goal = np.array([8.0, 0.0])
    static, ok_static = score_velocities(cand, goal, np.zeros((0, 2)), limits, cfg)
    score, ok = score_velocities(cand, goal, np.zeros((0, 2)), limits, cfg, discs)
    assert ok_static.all() and ok.all()
    assert static[0] > static[1] and score[0] < score[1] and score[1] == static[1]


def test_teb_band_keeps_clear_of_a_predicted_disc():
    """A pedestrian crossing the band's straight line pushes the band's pose at that time away."""
    cfg = TebConfig()
    poses = np.column_stack([np.linspace(0.0, 3.0, 16), np.zeros(16)])
    band = Band(poses, np.full(15, 0.1))
    crossing = np.array([[1.6, -0.75, 0.0, 1.0, 0.3]])  # at y = 0 when the band is at x = 1.6 (0.75 s)
    plain, _ = optimize_band(band, np.array([2.0, 0.0]), np.zeros((0, 2)), cfg)
    tracked, _ = optimize_band(band, np.array([2.0, 0.0]), np.zeros((0, 2)), cfg, crossing)
    times = tracked.times()
    walker = crossing[0, :2] + crossing[0, 2:4] * times[:, None]
    gap = np.hypot(*(tracked.poses - walker).T) - 0.3
    plain_gap = np.hypot(*(plain.poses - (crossing[0, :2] + crossing[0, 2:4] * plain.times()[:, None])).T) - 0.3
    assert gap.min() > plain_gap.min() + 0.1


@pytest.mark.parametrize("name,overrides", TRACKING, ids=[" ".join((n, *o)) for n, o in TRACKING])
def test_evaluate_runs_planners_with_tracks_and_records_them(tmp_path, name, overrides):
    """``mjnav evaluate policy=NAME planner.tracks=true``: episodes run, the record's planner
    parameters say tracks (mpc_tracked: not privileged) and the summary reads "NAME + tracks"."""
    out = tmp_path / "evals"
    argv = ["evaluate", "task=stage6", f"policy={name}", "episodes=2", "workers=0", f"out={out}",
            "task.timing.episode_steps=40", *(f"planner.{o}" for o in overrides)]
    assert cli.main(argv) == 0
    records = [json.loads(line) for line in (out / "stage6.jsonl").read_text().splitlines()]
    assert len(records) == 2 and records[0]["planner_privileged"] == []
    params = records[0]["planner_params"]
    assert params.get("tracks", True) and params.get("track_region", "track_region=true" in overrides) == (
        "track_region=true" in overrides)
    label = f"| {name} + tracks |" if "tracks=true" in overrides else f"| {name} |"
    assert label in (out / "summary.md").read_text()


def test_tables_list_planners_with_and_without_tracks(tmp_path):
    """``planners=teb,teb+tracks``: two methods, the second labelled "teb + tracks" with its own
    folder and planner.tracks=true; +tracks on a planner without the parameter is an error."""
    method = planner_method("teb+tracks")
    assert (method.name, method.policy, method.slug, method.planner) == (
        "teb + tracks", "teb", "planner_teb_tracks", ("tracks=true",))
    rows = table_rows(4, Path(tmp_path), 5, run_missing=False, methods=["TEB", "teb", "teb + tracks"],
                      planners=["teb", "teb+tracks"])
    assert [r["method"] for r in rows[:3]] == ["TEB", "teb", "teb + tracks"]
    with pytest.raises(ConfigError, match="tracks"):
        planner_method("mpc_gap+tracks")


def test_planner_input_without_tracks_is_none():
    """A PlannerInput built without tracks (every planner's degenerate-input tests) has None."""
    angles = beam_angles(360)
    inp = PlannerInput(np.full(360, 10.0), angles, np.zeros(2), np.zeros(2), np.zeros(2), np.ones(2),
                       compute_region(np.full(360, 10.0), angles), 0.0)
    assert inp.tracks is None
    for name, overrides in TRACKING:
        planner = make_planner(name, list(overrides))
        planner.reset(load_task("stage6"), np.random.default_rng(0))
        assert np.all(np.isfinite(planner.act(inp)))


@pytest.mark.parametrize("name,overrides", [("teb", ("tracks=true",)), ("mpc_tracked", ()), ("teb", ())])
def test_evaluation_agents_turn_the_tracker_on_only_for_planners_with_tracks(name, overrides):
    """The evaluation's timed wrapper forwards uses_tracks: the task runs its tracker for it."""
    from mjnav.envs.gym_env import NavGymEnv
    from mjnav.eval.policies import load_policy

    agent = load_policy(name, planner=overrides)
    env = NavGymEnv("stage6", seed=0)
    agent.begin(env.task, 0)
    env.reset(options={"episode_seed": 0})
    wanted = bool(overrides) or name == "mpc_tracked"
    assert env.task.tracks_enabled is wanted and (env.task.tracks is not None) is wanted
    env.close()
