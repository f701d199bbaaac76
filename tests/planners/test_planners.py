"""Baselines: reach the goal in an empty room, never raise on degenerate inputs."""

from __future__ import annotations

import numpy as np
import pytest

from mjnav.config import load_task
from mjnav.control.dynamics import Limits, brake, track_velocity
from mjnav.geometry.raycast import beam_angles
from mjnav.geometry.region import compute_region
from mjnav.planners import PLANNERS, make_planner
from mjnav.planners.base import PlannerInput

GOAL_PLANNERS = ("mpc_goal", "mpc_gap", "mpc_crowd", "mpc_tracked", "teb", "dwa")


@pytest.fixture(scope="module")
def empty_env():
    from mjnav.envs.gym_env import NavGymEnv

    env = NavGymEnv("stage1", overrides=["layout.start_goal_max_distance=6.0"], seed=0)
    yield env
    env.close()


@pytest.mark.parametrize("name", GOAL_PLANNERS)
def test_reaches_goal_in_empty_room(empty_env, name):
    """In stage 1 (no obstacles) each goal-directed baseline succeeds within 15 s."""
    empty_env.task.planner = make_planner(name)
    for seed in (11, 12):
        empty_env.reset(options={"episode_seed": seed})
        for _ in range(150):
            _, _, terminated, truncated, info = empty_env.step(np.zeros(4, np.float32))
            if terminated or truncated:
                break
        assert info["outcome"] == "success", f"{name} seed {seed}: {info['outcome']}"
    empty_env.task.planner = None


def _input(scan: np.ndarray, region_scan: np.ndarray, time: float) -> PlannerInput:
    angles = beam_angles(360)
    region = compute_region(region_scan, angles)
    return PlannerInput(scan, angles, np.array([1.0, 2.0]), np.array([1.0, -0.5]), np.array([0.5, 0.2]),
                        np.array([4.0, 2.0]), region, time)


DEGENERATE = {
    "all_zero": (np.zeros(360), np.zeros(360)),
    "all_max": (np.full(360, 10.0), np.full(360, 10.0)),
    "nan_and_inf": (np.where(np.arange(360) % 2 == 0, np.nan, np.inf), np.full(360, 10.0)),
    "wrong_length": (np.ones(7), np.full(360, 1.0)),
    "touching": (np.full(360, 0.2), np.full(360, 0.2)),
}


@pytest.mark.parametrize("name", sorted(PLANNERS))
@pytest.mark.parametrize("case", sorted(DEGENERATE))
def test_degenerate_scans_never_raise(name, case):
    """Degenerate scans give a finite jerk within ±8 m/s³ (a brake at worst), never an exception."""
    planner = make_planner(name)
    planner.reset(load_task("stage5"), np.random.default_rng(0))
    scan, region_scan = DEGENERATE[case]
    for step in range(3):
        inp = _input(scan, region_scan, time=0.1 * step)
        jerk = planner.act(inp)
        assert jerk.shape == (2,) and np.all(np.isfinite(jerk)) and np.all(np.abs(jerk) <= 8.0 + 1e-9)
    if name in ("teb", "dwa") and case in ("nan_and_inf", "wrong_length"):
        assert planner.stats["failures"] >= 1


def test_tracker_reaches_velocity_without_overshoot():
    """The jerk-limited tracker settles on the commanded velocity within the limits."""
    lim = Limits()
    v, a = np.zeros(2), np.zeros(2)
    peak = 0.0
    for _ in range(40):
        j = track_velocity(v, a, np.array([2.5, -1.0]), lim)
        assert np.all(np.abs(j) <= lim.j_max + 1e-12)
        v, a = v + a * 0.1 + j * 0.005, a + j * 0.1
        peak = max(peak, float(np.max(np.abs(v))))
        assert np.all(np.abs(a) <= lim.a_max + 1e-9)
    assert np.allclose(v, [2.5, -1.0], atol=0.02)
    assert peak <= 2.5 + 0.05


def test_brake_stops():
    """Braking from 2.5 m/s stops the robot within 2 s."""
    lim = Limits()
    v, a = np.array([2.5, 2.5]), np.zeros(2)
    for _ in range(20):
        j = brake(v, a, lim)
        v, a = v + a * 0.1 + j * 0.005, a + j * 0.1
    assert np.all(np.abs(v) < 0.05)


def test_escape_backs_away_from_the_nearest_returns():
    """Escape drives the robot away from the nearest beams at the escape speed, and brakes between equal walls."""
    from mjnav.control.dynamics import escape

    lim, angles = Limits(), beam_angles(360)
    scan = np.full(360, 5.0)
    scan[[0, 1, 359]] = 0.23  # a return just ahead along +x
    v, a = np.array([0.3, 0.0]), np.zeros(2)
    for _ in range(20):
        j = escape(scan, angles, v, a, lim, speed=0.2)
        v, a = v + a * 0.1 + j * 0.005, a + j * 0.1
    assert np.allclose(v, [-0.2, 0.0], atol=0.02)
    scan[[179, 180, 181]] = 0.23  # the same return behind: no way out, stop
    assert np.allclose(escape(scan, angles, np.zeros(2), np.zeros(2), lim, speed=0.2), 0.0)


def test_mpc_gap_heads_for_open_space_near_the_goal_direction():
    """With the goal direction blocked close ahead and open space 90° to the left, mpc_gap's Q_l goes
    left while mpc_goal's stays on the goal line; without the clearance term both agree; Q_s lies on
    Q_l's ray within the short-term circle; bad parameters are refused."""
    from mjnav.planners import MpcGapConfig
    from mjnav.planners.mpc_goal import reference_points
    from mjnav.schema import ConfigError

    angles = beam_angles(360)
    scan = np.full(360, 6.0)
    deg = np.degrees(angles) % 360
    scan[(deg < 40) | (deg > 320)] = 1.0  # an obstacle 1 m ahead along +x (the goal direction)
    region = compute_region(scan, angles)
    goal = np.array([5.0, 0.0])
    _, straight, _ = reference_points(region, goal, 0.3)
    q_s, q_l, inside = reference_points(region, goal, 0.3, gap=MpcGapConfig())
    assert not inside and abs(straight[1]) < 1e-9 and straight[0] < 1.0
    assert q_l[1] > 1.0 and np.hypot(*q_l) > 2.0  # sideways, into the open
    assert np.hypot(*q_s) <= 0.3 + 1e-9 and abs(q_s[0] * q_l[1] - q_s[1] * q_l[0]) < 1e-9 and q_s @ q_l > 0
    _, plain, _ = reference_points(region, goal, 0.3, gap=MpcGapConfig(clearance_weight=0.0))
    assert np.allclose(plain / np.hypot(*plain), [1.0, 0.0])
    for bad in ({"clearance_weight": -1.0}, {"clearance_cap": 0.0}, {"directions": 3}, {"safety": 1.5}):
        with pytest.raises(ConfigError):
            MpcGapConfig(**bad)


def test_mpc_crowd_steps_aside_from_a_pedestrian_walking_at_it():
    """With no crowd mpc_crowd's Q_l goes straight at the goal at full speed; a pedestrian 2 m ahead
    walking towards the robot turns Q_l off the goal line, while one beside the line walking away
    from it leaves Q_l there. Bad parameters are refused."""
    from mjnav.planners import MpcCrowdConfig
    from mjnav.planners.mpc_crowd import crowd_long_point
    from mjnav.schema import ConfigError

    angles = beam_angles(360)
    region = compute_region(np.full(360, 8.0), angles)
    goal, still, config = np.array([6.0, 0.0]), np.zeros(2), MpcCrowdConfig()
    args = (0.325, 1.0, config)
    q_l = crowd_long_point(region, goal, still, np.zeros((0, 3)), np.zeros((0, 2)), *args)
    assert np.allclose(q_l, [max(config.speeds), 0.0])
    ahead = np.array([[2.0, 0.0, 0.3]])
    towards = crowd_long_point(region, goal, still, ahead, np.array([[-0.6, 0.0]]), *args)
    aside = np.array([[2.0, 1.2, 0.3]])  # off the line and walking away from it
    away = crowd_long_point(region, goal, still, aside, np.array([[0.0, 0.6]]), *args)
    assert abs(np.arctan2(towards[1], towards[0])) > np.radians(20)
    assert abs(away[1]) < 1e-9 and away[0] > 0.0
    for bad in ({"margin": 0.0}, {"weight": -1.0}, {"samples": 1}, {"directions": 3}, {"speeds": ()},
                {"safety": 0.0}):
        with pytest.raises(ConfigError):
            MpcCrowdConfig(**bad)
    from mjnav.planners import planner_config

    assert planner_config("mpc_crowd", ["speeds=[1.0, 2.0]", "margin=0.5"]).speeds == (1.0, 2.0)
    for bad in ("speeds=3", "speeds=[1.0, -2.0]", "speeds=[]"):
        with pytest.raises(ConfigError):
            planner_config("mpc_crowd", [bad])


def test_mpc_crowd_reads_the_ground_truth_crowd_and_differences_it():
    """In a stage-5 episode the task hands mpc_crowd every pedestrian ([x, y, r], world frame); its
    velocity estimate is the displacement over the control period, zero at first sight."""
    from mjnav.envs.gym_env import NavGymEnv

    env = NavGymEnv("stage5", seed=0)
    planner = env.task.planner = make_planner("mpc_crowd")
    seen = []
    act = planner.act
    planner.act = lambda inp: (seen.append(inp.pedestrians.copy()), act(inp))[1]
    env.reset(options={"episode_seed": 3})
    for _ in range(3):
        env.step(np.zeros(4, np.float32))
    env.close()
    assert [p.shape for p in seen] == [(10, 3)] * 3
    assert np.all((seen[0][:, 2] >= 0.1) & (seen[0][:, 2] <= 0.4))
    speeds = np.hypot(*planner.tracker.velocities.T)
    assert np.allclose(planner.tracker.velocities, (seen[2][:, :2] - seen[1][:, :2]) / 0.1)
    assert np.all((speeds > 0.2) & (speeds < 0.7))
    planner.reset(load_task("stage5"), np.random.default_rng(0))
    assert np.allclose(planner.tracker.update(0.0, seen[0][:, :2]), 0.0)
