"""Environment throughput: steps/s for 1 env and the vectorised adapter, with a per-part breakdown.

    python scripts/benchmark.py task=stage7 [steps=2000] [vec_steps=200] [num_envs=16] [task.crowd.count=25]

Prints (all from one run, so ratios are comparable on a noisy machine):
  * bare MuJoCo ``mj_step`` rate of the same compiled world (reference);
  * one environment through the composer task with random actions: steps/s and µs per part
    (physics = substeps incl. pedestrians and tracking force, lidar, region, action mapping, MPC,
    reward, observation, rest = composer and adapter overhead);
  * the rsl-rl adapter (``NavVecEnv``) over ``num_envs`` environments with 1, 2 and all-core workers
    (this process stepping the first block), and all-core worker processes with this process idle.
"""

from __future__ import annotations

import os
import sys
import time

import mujoco
import numpy as np

from mjnav.config import load_task
from mjnav.envs.gym_env import NavGymEnv
from mjnav.schema import ConfigError, split_args

SCRIPT_KEYS = {"task": "stage7", "steps": 2000, "vec_steps": 200, "num_envs": 16, "seed": 0}


def bare_physics_rate(env: NavGymEnv, steps: int = 5000) -> float:
    """mj_step calls per second on the environment's own compiled model (pedestrians frozen)."""
    model, data = env.physics.model.ptr, env.physics.data.ptr
    start = time.perf_counter()
    for _ in range(steps):
        mujoco.mj_step(model, data)
    return steps / (time.perf_counter() - start)


def single_env(config, steps: int, seed: int) -> tuple[float, dict[str, float], NavGymEnv]:
    """Steps/s of one environment with random actions and µs per step of each part."""
    env = NavGymEnv(config, seed=seed)
    rng = np.random.default_rng(seed)
    env.reset(seed=seed)
    for _ in range(50):  # warm-up: numba dispatch, solver caches
        if any(env.step(rng.normal(size=4).astype(np.float32))[2:4]):
            env.reset()
    task = env.task
    for timers in (task.timers, task.core.timers):
        timers.update(dict.fromkeys(timers, 0.0))
    actions = rng.normal(size=(steps, 4)).astype(np.float32)
    reset_time, start = 0.0, time.perf_counter()
    for a in actions:
        _, _, term, trunc, _ = env.step(a)
        if term or trunc:
            t0 = time.perf_counter()
            env.reset()
            reset_time += time.perf_counter() - t0
    total = time.perf_counter() - start
    parts = {k: 1e6 * v / steps for k, v in {**task.timers, **task.core.timers}.items()}
    parts["reset (amortised)"] = 1e6 * reset_time / steps
    parts["rest (composer, adapter)"] = 1e6 * total / steps - sum(parts.values())
    return steps / total, parts, env


def vec_rate(config, num_envs: int, workers: int, steps: int, seed: int, step_in_main: bool = True) -> float:
    """Env steps/s of the rsl-rl adapter with random actions."""
    import torch

    from mjnav.envs.vec_env import NavVecEnv
    from mjnav.train.runner import TaskEnvFactory

    torch.set_num_threads(1)
    env = NavVecEnv(TaskEnvFactory(config), num_envs=num_envs, seed=seed, workers=workers,
                    max_episode_length=config.timing.episode_steps, step_in_main=step_in_main)
    try:
        gen = torch.Generator().manual_seed(seed)
        for _ in range(10):
            env.step(torch.randn(num_envs, 4, generator=gen))
        start = time.perf_counter()
        for _ in range(steps):
            env.step(torch.randn(num_envs, 4, generator=gen))
        return steps * num_envs / (time.perf_counter() - start)
    finally:
        env.close()


def main(argv: list[str]) -> None:
    """Run the benchmark and print markdown tables."""
    opts, overrides = split_args(argv, SCRIPT_KEYS)
    config = load_task(opts["task"], overrides)
    rate, parts, env = single_env(config, int(opts["steps"]), int(opts["seed"]))
    bare = bare_physics_rate(env)
    substeps = config.timing.substeps
    print(f"## {config.name}: {config.crowd.count} pedestrians, {config.obstacles.count} obstacles, "
          f"LiDAR backend {config.lidar.backend}, MPC solver {config.mpc.solver}\n")
    print(f"bare mj_step: {bare:,.0f} /s -> {bare / substeps:,.0f} control periods/s ({substeps} substeps)")
    print(f"one environment (composer task, random actions): {rate:,.0f} steps/s "
          f"({1e6 / rate:.0f} us/step, {rate / (bare / substeps):.2f} x bare physics)\n")
    print("| part | us/step | share |\n|---|---|---|")
    total = sum(parts.values())
    for name, us in parts.items():
        print(f"| {name} | {us:.1f} | {us / total:.0%} |")
    env.close()
    cores = os.cpu_count() or 1
    print(f"\n| adapter: {opts['num_envs']} envs | workers | processes started | env steps/s |\n|---|---|---|---|")
    rows = [(w, True) for w in sorted({1, 2, cores})] + [(max(2, cores), False)]
    for workers, in_main in rows:
        r = vec_rate(config, int(opts["num_envs"]), workers, int(opts["vec_steps"]), int(opts["seed"]), in_main)
        started = workers - 1 if in_main else workers
        note = "" if in_main else " (this process only waits)"
        print(f"| NavVecEnv | {workers} | {started}{note} | {r:,.0f} |")


if __name__ == "__main__":
    try:
        main(sys.argv[1:])
    except ConfigError as err:
        sys.exit(f"error: {err}")
