"""``mjnav bench sim``: NavSim build, reset and control-step times per LiDAR backend, plus bare mj_step.

    mjnav bench sim [steps=300] [tasks=stage7,stage4]

Prints medians in microseconds (build and reset in milliseconds). A control step is what one RL
step costs the simulation: command, ``substeps`` physics steps with pedestrian motion and the
tracking force, the final sync, then one noisy scan.
"""

from __future__ import annotations

import dataclasses
import sys
import time
from collections.abc import Callable

import mujoco
import numpy as np
from dm_control import mjcf

from mjnav.args import Grammar, Parsed
from mjnav.config import load_task
from mjnav.schema import ConfigError
from mjnav.sim import NavSim

__all__ = ["SimOptions", "bench", "grammar", "run"]


@dataclasses.dataclass(frozen=True)
class SimOptions:
    """The keys of ``bench sim``.

    Attributes:
        steps: Control steps timed per row.
        tasks: Comma-separated stages, one table each.
    """

    steps: int = 300
    tasks: str = "stage7,stage4"


def grammar() -> Grammar:
    """:class:`SimOptions`; no config overrides."""
    return Grammar(SimOptions, ())


def _median_us(fn: Callable[[], object], repeats: int) -> float:
    times = []
    for _ in range(repeats):
        start = time.perf_counter()
        fn()
        times.append(time.perf_counter() - start)
    return 1e6 * float(np.median(times))


def _episode_steps(
    sim: NavSim, physics: mjcf.Physics, rng: np.random.Generator, steps: int, scan_fn: Callable[[], object]
) -> dict[str, list[float]]:
    """Drives the robot towards its goal (gentle PD on jerk), re-placing it after collisions."""
    out: dict[str, list[float]] = {"step": [], "physics": [], "scan": []}
    goal = sim.initialize_episode(physics, rng).goal
    for _ in range(steps):
        p, v, a = sim.robot_state(physics)
        jerk = np.clip(2.0 * (goal - p) - 4.0 * v - 3.0 * a, -8.0, 8.0)
        t0 = time.perf_counter()
        sim.control_step(physics, jerk)
        t1 = time.perf_counter()
        scan_fn()
        t2 = time.perf_counter()
        out["step"].append(t2 - t0)
        out["physics"].append(t1 - t0)
        out["scan"].append(t2 - t1)
        if sim.robot_in_collision(physics)[0] or np.linalg.norm(goal - p) < 0.3:
            goal = sim.initialize_episode(physics, rng).goal
    return out


def bench(task: str, steps: int) -> None:
    """Prints the table for one task."""
    config = load_task(task)
    build = []
    for _ in range(3):
        start = time.perf_counter()
        sim = NavSim(config)
        physics = sim.make_physics()
        build.append(time.perf_counter() - start)
    rng = np.random.default_rng(0)
    sim.initialize_episode(physics, rng)  # numba warm-up
    reset = _median_us(lambda: sim.initialize_episode(physics, rng), 30)
    size = config.arena.size
    print(f"{task}: {size[0]:.0f}x{size[1]:.0f} m, {config.obstacles.count} obstacles, "
          f"{config.crowd.count} pedestrians, {physics.model.ngeom} geoms")
    print(f"  build (entities + compile) {1e3 * np.median(build):8.1f} ms")
    print(f"  reset (initialize_episode) {reset / 1e3:8.2f} ms")
    print("  control step, median us          total  physics+peds    scan")
    rows = [("Euler", True, "analytic"), ("Euler", True, "mujoco"), ("Euler", False, "analytic"),
            ("RK4", True, "analytic"), ("RK4", True, "mujoco"), ("RK4", False, "analytic")]
    for integrator, sites, backend in rows:
        variant = NavSim(config, integrator=integrator, rangefinders=sites)
        vphys = variant.make_physics()
        times = _episode_steps(variant, vphys, np.random.default_rng(1), steps,
                               lambda v=variant, p=vphys, b=backend: v.scan(p, rng, backend=b))
        med = {k: 1e6 * float(np.median(v)) for k, v in times.items()}
        label = f"{integrator}, {'sites' if sites else 'no sites'}, {backend}"
        print(f"    {label:29s} {med['step']:8.1f} {med['physics']:12.1f} {med['scan']:8.1f}")
    sim.lidars["mujoco"].method = "sensor"
    sensor = _median_us(lambda: sim.scan(physics, rng, backend="mujoco"), 100)
    sim.lidars["mujoco"].method = "multiray"
    print(f"    {'scan via rangefinder sensors':29s} {'':8s} {'':12s} {sensor:8.1f}")
    model, data = physics.model.ptr, physics.data.ptr
    default = model.opt.integrator
    for integrator in ("Euler", "RK4"):
        model.opt.integrator = getattr(mujoco.mjtIntegrator, f"mjINT_{integrator.upper()}")
        step = _median_us(lambda: mujoco.mj_step(model, data), 2000)
        print(f"  bare mj_step {integrator:5s} (sites) {step:7.1f} us  ({1e6 / step:9.0f} steps/s)")
    model.opt.integrator = default


def run(parsed: Parsed, argv: list[str]) -> int:
    """Benchmark each task; an unknown task is one error line (exit code 2)."""
    opts: SimOptions = parsed.options
    try:
        tasks = [(task, load_task(task)) for task in opts.tasks.split(",")]
    except ConfigError as err:
        print(f"error: {err}", file=sys.stderr)
        return 2
    for task, _ in tasks:
        bench(task, opts.steps)
    return 0
