"""The LiDAR tracks inside the task loop: off by default, on with ``tracks.enabled`` or a planner
declaring ``uses_tracks``; deterministic; made without drawing from the task's random streams."""

from __future__ import annotations

import numpy as np
import pytest

from mjnav.config import load_task
from mjnav.perception import Tracker
from mjnav.planners.base import PlannerInput, declared_tracks


class _Recorder:
    """Brakes and keeps the tracks of every input."""

    def __init__(self) -> None:
        self.tracks: list[np.ndarray | None] = []

    def reset(self, config, rng) -> None:
        self.tracks = []

    def act(self, inp: PlannerInput) -> np.ndarray:
        self.tracks.append(inp.tracks)
        return -np.asarray(inp.acceleration)


class _Tracking(_Recorder):
    uses_tracks = True


def _run(planner: object | None, overrides: tuple[str, ...] = (), steps: int = 12, seed: int = 3):
    """``steps`` steps of a stage6 episode; (the task's tracks after each step, robot positions,
    the planner)."""
    from mjnav.envs.gym_env import NavGymEnv

    env = NavGymEnv("stage6", overrides=list(overrides) or None, seed=0)
    env.task.planner = planner
    env.reset(options={"episode_seed": seed})
    tracks, positions = [env.task.tracks], []
    for _ in range(steps):
        env.step(np.zeros(4, np.float32))
        tracks.append(env.task.tracks)
        positions.append(env.task.sim.robot_state(env.physics)[0].copy())
        if env.task.outcome.done:
            break
    env.close()
    return tracks, np.array(positions), planner


def test_tracks_are_off_by_default():
    """Default config, a planner declaring nothing: no tracker, PlannerInput.tracks None."""
    assert load_task("stage6").tracks.enabled is False
    tracks, _, planner = _run(_Recorder(), steps=3)
    assert all(t is None for t in tracks) and all(t is None for t in planner.tracks)


def test_a_planner_declaring_uses_tracks_gets_them():
    """uses_tracks=True turns the tracker on: (T, 5) read-only, nearest first, the task's own."""
    tracks, positions, planner = _run(_Tracking())
    assert all(t is not None for t in planner.tracks)
    assert any(len(t) for t in planner.tracks), "no pedestrian tracked in 12 steps of stage6"
    for before, seen in zip(tracks, planner.tracks):
        np.testing.assert_array_equal(before, seen)  # the planner sees the tracks of the last scan
    for t, p in zip(tracks[1:], positions):
        assert t.shape[1] == 5 and not t.flags.writeable
        d = np.hypot(t[:, 0] - p[0], t[:, 1] - p[1])
        assert np.all(np.diff(d) >= 0.0)
        assert np.all((t[:, 4] >= 0.1) & (t[:, 4] <= 0.4))


def test_tracks_enabled_runs_the_tracker_without_a_planner_and_changes_nothing():
    """tracks.enabled=true: tracks every step; the episode (positions) is the same as without."""
    with_tracks, positions, _ = _run(None, ("tracks.enabled=true",))
    without, positions_off, _ = _run(None)
    assert all(t is not None for t in with_tracks) and all(t is None for t in without)
    np.testing.assert_array_equal(positions, positions_off)


def test_tracks_are_deterministic_and_draw_no_random_number():
    """The same episode twice gives the same tracks; the task's generator is where it would be
    without the tracker (the tracker draws nothing)."""
    from mjnav.envs.gym_env import NavGymEnv

    first, _, _ = _run(_Tracking())
    second, _, _ = _run(_Tracking())
    for a, b in zip(first, second):
        np.testing.assert_array_equal(a, b)
    states = []
    for overrides in (["tracks.enabled=true"], None):
        env = NavGymEnv("stage6", overrides=overrides, seed=0)
        env.reset(options={"episode_seed": 5})
        for _ in range(5):
            env.step(np.zeros(4, np.float32))
        states.append(env.task.rng.bit_generator.state)
        env.close()
    assert states[0] == states[1]


def test_the_task_tracks_are_the_tracker_on_the_robots_scans():
    """The task's tracks equal a stand-alone Tracker fed the task's scans and robot positions."""
    from mjnav.envs.gym_env import NavGymEnv

    env = NavGymEnv("stage6", overrides=["tracks.enabled=true"], seed=0)
    config = env.task.config
    tracker = Tracker(config.tracks, beams=config.lidar.beams, max_range=config.lidar.max_range)
    env.reset(options={"episode_seed": 4})
    for step in range(8):
        if step:
            env.step(np.zeros(4, np.float32))
        p = env.task.sim.robot_state(env.physics)[0]
        tracker.step(env.task._scan, p, config.timing.control_period)
        mine = tracker.track_array()[:, :5]
        mine = mine[np.argsort(np.hypot(*(mine[:, :2] - p).T), kind="stable")]
        np.testing.assert_array_equal(env.task.tracks, mine)
    env.close()


def test_tracks_section_follows_the_lidar_noise_and_rejects_bad_values():
    """tracks.noise_std is lidar.noise_std (derived); a bad tracker value names its key."""
    assert load_task("stage6", ["lidar.noise_std=0.02"]).tracks.noise_std == 0.02
    assert load_task("stage6", ["lidar.noise_std=0"]).tracks.noise_std == 0.0
    with pytest.raises(ValueError, match="gate"):
        load_task("stage6", ["tracks.gate=-1"])


def test_uses_tracks_must_be_a_bool():
    """declared_tracks: absent is False; a non-bool is a clear error."""

    class Bad:
        uses_tracks = "yes"

    assert declared_tracks(None) is False and declared_tracks(_Tracking) is True
    with pytest.raises(ValueError, match="uses_tracks"):
        declared_tracks(Bad())
