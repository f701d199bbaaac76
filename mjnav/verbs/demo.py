"""``mjnav demo``: build a stage, drive one episode with the non-learned convex-MPC planner, report
it, export the world.

No training needed: the robot uses ``mpc_goal`` (the free-space polygon + MPC heading for the goal).
The world of that seed is exported as a standalone MJCF scene (see the export page of the documentation).
"""

from __future__ import annotations

import dataclasses
import sys
import time

import numpy as np

from mjnav.args import Grammar, Parsed
from mjnav.config import TASK_SECTIONS
from mjnav.envs.gym_env import NavGymEnv
from mjnav.export import export_world
from mjnav.planners.mpc_goal import MpcGoalPlanner
from mjnav.schema import ConfigError

__all__ = ["DemoOptions", "grammar", "run"]


@dataclasses.dataclass(frozen=True)
class DemoOptions:
    """The ``demo`` verb's own keys.

    Attributes:
        task: Bundled stage name or task YAML path.
        seed: Episode seed.
        out: Folder of the exported world.
    """

    task: str = "stage6"
    seed: int = 7
    out: str = "out/demo"


def grammar() -> Grammar:
    """:class:`DemoOptions` and ``task.*`` overrides."""
    return Grammar(DemoOptions, ("task",), {}, TASK_SECTIONS)


def run(parsed: Parsed, argv: list[str]) -> int:
    """Run the demo; a bad task or override is one error line (exit code 2)."""
    try:
        demo(parsed.options, list(parsed.task))
    except ConfigError as err:
        print(f"error: {err}", file=sys.stderr)
        return 2
    return 0


def demo(opts: DemoOptions, overrides: list[str]) -> None:
    """Run the demo episode and export its world."""
    t0 = time.perf_counter()
    env = NavGymEnv(opts.task, overrides=overrides, seed=0)
    build = time.perf_counter() - t0
    env.task.planner = MpcGoalPlanner()
    env.reset(options={"episode_seed": opts.seed})
    layout, cfg = env.task.layout, env.config
    print(f"{cfg.name}: {cfg.arena.size[0]:g} x {cfg.arena.size[1]:g} m, {cfg.obstacles.count} obstacles, "
          f"{cfg.crowd.count} pedestrians ({cfg.crowd.model}); built in {1e3 * build:.0f} ms")
    print(f"start {np.round(layout.start, 2)}  goal {np.round(layout.goal, 2)}  "
          f"distance {np.linalg.norm(layout.goal - layout.start):.2f} m")
    path, ret, t0 = 0.0, 0.0, time.perf_counter()
    prev = env.task.sim.robot_state(env.physics)[0]
    for step in range(1, cfg.timing.episode_steps + 1):
        _, reward, terminated, truncated, info = env.step(np.zeros(4, np.float32))
        p, v, _ = env.task.sim.robot_state(env.physics)
        path, ret, prev = path + float(np.linalg.norm(p - prev)), ret + reward, p
        if step % 10 == 0 or terminated or truncated:
            t = step * cfg.timing.control_period
            print(f"  t={t:4.1f} s  pos {np.round(p, 2)}  speed {np.linalg.norm(v):.2f} m/s"
                  f"  to goal {np.linalg.norm(layout.goal - p):5.2f} m")
        if terminated or truncated:
            break
    wall = time.perf_counter() - t0
    print(f"outcome: {info['outcome']} after {step} steps ({step * cfg.timing.control_period:.1f} s simulated, "
          f"{wall:.2f} s wall, {step / wall:.0f} steps/s), path {path:.2f} m, return {ret:.1f}")
    print(f"MPC fallbacks {env.task.core.counters['fallbacks']}, region failures "
          f"{env.task.core.counters['region_failures']}")
    out = export_world(cfg, opts.seed, opts.out)
    print(f"exported the world to {out}")
