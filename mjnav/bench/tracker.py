"""``mjnav bench tracker``: the LiDAR pedestrian tracker against the simulator's ground truth.

    mjnav bench tracker [episodes=4] [tasks=stage4,stage5,stage6,stage7] [seed=0] [max_steps=300]

Real episodes: ``mpc_goal`` drives the robot through the Gymnasium environment; after each control
step the tracker reads the step's noisy scan and the robot's own position, and its reported tracks
are scored (:mod:`mjnav.perception.scoring`) against the pedestrians' true circles and their
finite-difference velocities. Episode seeds are ``seed + i``: training-range seeds, never the
held-out evaluation seeds ``2**32 + i``. Prints one row per stage: precision and recall (matched
within 0.3 m), recall of pedestrians within 5 m in line of sight, position and velocity RMSE,
identity switches, and the tracker's median cost per control step in microseconds.
"""

from __future__ import annotations

import dataclasses
import sys
import time
from typing import Any

import numpy as np

from mjnav.args import Grammar, Parsed
from mjnav.geometry.raycast import beam_angles
from mjnav.perception import Tracker, TrackerConfig
from mjnav.perception.scoring import TrackingScore, line_of_sight
from mjnav.schema import ConfigError

__all__ = ["TrackerOptions", "grammar", "measure_stage", "run"]


@dataclasses.dataclass(frozen=True)
class TrackerOptions:
    """The keys of ``bench tracker``.

    Attributes:
        episodes: Episodes per stage.
        tasks: Comma-separated stages, one row each.
        seed: First episode seed (training range: must stay below 2**32).
        max_steps: Control steps per episode at most.
    """

    episodes: int = 4
    tasks: str = "stage4,stage5,stage6,stage7"
    seed: int = 0
    max_steps: int = 300


def grammar() -> Grammar:
    """:class:`TrackerOptions`; no config overrides."""
    return Grammar(TrackerOptions, ())


def _episode(env: Any, agent: Any, tracker: Tracker, seed: int, max_steps: int, score: TrackingScore,
             times: list[float]) -> None:
    """One episode: step, track, score; tracker times appended to ``times`` (seconds)."""
    base = env.unwrapped
    task, config = base.task, base.task.config
    angles, dt = beam_angles(config.lidar.beams), config.timing.control_period
    agent.begin(task, seed)
    obs, _ = env.reset(options={"episode_seed": seed})
    tracker.reset()
    score.new_episode()
    previous = None
    for _ in range(max_steps):
        obs, _, terminated, truncated, _ = env.step(agent.act(obs))
        robot = task.sim.robot_state(base.physics)[0]
        start = time.perf_counter()
        tracker.step(task._scan, robot, dt)  # the step's noisy scan, as the observation saw it
        times.append(time.perf_counter() - start)
        truth = task.sim.pedestrian_circles()
        velocity = None if previous is None else (truth[:, :2] - previous[:, :2]) / dt
        seen = line_of_sight(robot, angles, task.sim.segments, truth, config.lidar.max_range)
        score.add(tracker.track_array(), truth, velocity, robot, seen)
        previous = truth
        if terminated or truncated:
            break


def measure_stage(task_name: str, episodes: int, seed: int, max_steps: int,
                  config: TrackerConfig | None = None) -> dict[str, float]:
    """Tracker quality and cost on ``episodes`` episodes of one stage.

    Args:
        task_name: Stage id (``stage7``).
        episodes: Episodes, seeds ``seed .. seed + episodes - 1``.
        seed: First episode seed; must keep every seed below 2**32 (training range).
        max_steps: Control steps per episode at most.
        config: Tracker settings; default the task's LiDAR noise with the other defaults.

    Returns:
        :meth:`TrackingScore.summary` plus ``us_per_step`` (median) and ``steps``.
    """
    # deferred: the environment stack ~0.5 s (MuJoCo, dm_control) and the planners ~0.2 s, not needed
    # by `mjnav bench tracker --help`
    from mjnav.envs.gym_env import NavGymEnv
    from mjnav.eval.policies import load_policy

    if seed < 0 or seed + episodes > 2**32:
        raise ValueError(f"bench tracker: seeds {seed}..{seed + episodes - 1} leave the training range [0, 2**32)")
    env = NavGymEnv(task_name, seed=0)
    lidar = env.task.config.lidar
    config = config or TrackerConfig(noise_std=lidar.noise_std)
    tracker = Tracker(config, beams=lidar.beams, max_range=lidar.max_range)
    agent = load_policy("mpc_goal")
    score, times = TrackingScore(), []
    _episode(env, agent, tracker, seed + episodes, 3, TrackingScore(), [])  # numba warm-up, not scored
    for i in range(episodes):
        _episode(env, agent, tracker, seed + i, max_steps, score, times)
    return {**score.summary(), "us_per_step": 1e6 * float(np.median(times)), "steps": float(len(times))}


def run(parsed: Parsed, argv: list[str]) -> int:
    """One row per stage; an unknown stage is one error line (exit code 2)."""
    opts: TrackerOptions = parsed.options
    print(f"{'stage':8s} {'steps':>6s} {'prec':>6s} {'recall':>7s} {'rec<=5m LOS':>11s} {'pos RMSE':>9s} "
          f"{'vel RMSE':>9s} {'ID sw':>6s} {'us/step':>8s}")
    for name in opts.tasks.split(","):
        try:
            row = measure_stage(name, opts.episodes, opts.seed, opts.max_steps)
        except (ConfigError, ValueError) as err:
            print(f"error: {err}", file=sys.stderr)
            return 2
        print(f"{name:8s} {row['steps']:6.0f} {row['precision']:6.3f} {row['recall']:7.3f} "
              f"{row['recall_near_los']:11.3f} {row['pos_rmse']:9.3f} {row['vel_rmse']:9.3f} "
              f"{row['id_switches']:6.0f} {row['us_per_step']:8.1f}", flush=True)
    return 0
