"""Benchmarks of the pedestrian models alone (no MuJoCo): cost per control step and contacts.

Both functions draw real episode layouts of a stage (``stage7``: 10 x 10 m, 30 pedestrians of
radius 0.1-0.4 m at 0.3-0.6 m/s) with :func:`mjnav.world.layout.sample_layout` and drive the
models through their public :class:`~mjnav.world.crowd.PedestrianModel` interface, one
control period (``timing.substeps`` steps of the physics time step) per call, as
:class:`mjnav.sim.NavSim` does.

Run ``mjnav bench crowd`` for a table (about 30 s; ``--help`` lists the keys).
"""

from __future__ import annotations

import dataclasses
import sys
import time
from collections.abc import Callable, Sequence

import numpy as np

from mjnav.args import Grammar, Parsed
from mjnav.config import TaskConfig, load_task
from mjnav.schema import ConfigError
from mjnav.world.crowd import PedestrianModel, RandomWalkModel
from mjnav.world.layout import Layout, sample_layout
from mjnav.world.orca import OrcaConfig, OrcaModel
from mjnav.world.shapes import make_shape_bank
from mjnav.world.social_force import SocialForceModel

__all__ = ["MODELS", "CrowdOptions", "StepCost", "crowd_step_cost", "grammar", "orca_contacts", "pyrvo_step_cost", "run"]

#: Models the benchmark builds, by name: a factory from the task config.
MODELS: dict[str, Callable[[TaskConfig], PedestrianModel]] = {
    "random_walk": lambda task: RandomWalkModel(task.crowd.yaw_rate, task.crowd.yaw_interval),
    "social_force": lambda task: SocialForceModel.from_config(task.crowd),
    "orca": lambda task: OrcaModel(),
    "orca_reactive": lambda task: OrcaModel(OrcaConfig(reactive=True)),
}


@dataclasses.dataclass(frozen=True)
class StepCost:
    """Measured cost of one model.

    Attributes:
        model: Model name (a key of :data:`MODELS`, or ``pyrvo``).
        us_per_control_step: Median over episodes of the mean wall time of one control period
            (``substeps`` model steps), microseconds.
        cpu_us_per_control_step: The same in process CPU time, microseconds: the better measure
            on a loaded machine, where wall time also counts waiting for a core.
        periods: Control periods timed in all.
        periods_per_call: Control periods advanced per ``advance`` call.
    """

    model: str
    us_per_control_step: float
    cpu_us_per_control_step: float
    periods: int
    periods_per_call: int = 1


def _layouts(task: TaskConfig, episodes: int, seed: int) -> list[Layout]:
    """``episodes`` layouts of ``task`` drawn from one seeded generator."""
    rng = np.random.default_rng(seed)
    bank = make_shape_bank(task.obstacles)
    return [
        sample_layout(task.arena, task.obstacles, task.crowd, task.layout, task.lidar, bank, rng,
                      inflation=task.region.inflation, robot_radius=task.robot.radius)  # fmt: skip
        for _ in range(episodes)
    ]


def _reset(model: PedestrianModel, task: TaskConfig, layout: Layout, seed: int) -> None:
    """Starts an episode of ``model`` on ``layout`` inside the task's walls."""
    hx, hy = 0.5 * task.arena.size[0], 0.5 * task.arena.size[1]
    model.reset(layout.ped_positions, layout.ped_radii, layout.ped_speeds, layout.ped_headings,
                bounds=(-hx, -hy, hx, hy), obstacles=list(layout.obstacle_polygons),
                rng=np.random.default_rng(seed))  # fmt: skip


def _robot_path(layout: Layout, periods: int, substeps: int) -> np.ndarray:
    """(periods, substeps, 2) robot centres along the straight line from start to goal, metres."""
    s = np.linspace(0.0, 1.0, periods * substeps)[:, None]
    start, goal = np.asarray(layout.start)[:2], np.asarray(layout.goal)[:2]
    return (start + s * (goal - start)).reshape(periods, substeps, 2)


def crowd_step_cost(
    task: str = "stage7",
    models: Sequence[str] = tuple(MODELS),
    episodes: int = 5,
    periods: int = 300,
    seed: int = 0,
    lookahead: int = 1,
) -> list[StepCost]:
    """Time of one control period of each pedestrian model on real episode layouts.

    Every model gets the same layouts; each episode is reset, warmed up (numba compiles on first
    use; not timed), then ``periods`` periods are timed, the robot moving from start to goal.
    A model that reacts to the robot is advanced one period per call; one that ignores it
    ``lookahead`` periods per call (:class:`mjnav.sim.NavSim` uses ``CROWD_LOOKAHEAD`` = 10).

    Args:
        task: Stage name or YAML path for :func:`mjnav.config.load_task`.
        models: Names from :data:`MODELS`.
        episodes: Layouts per model, >= 1.
        periods: Timed control periods per episode, >= 1 (rounded up to whole calls).
        seed: Seed of the layouts and of the models' generators.
        lookahead: Periods per call for models that ignore the robot, >= 1.

    Returns:
        One :class:`StepCost` per model, in the order given.

    Raises:
        KeyError: An unknown model name.
    """
    config = load_task(task)
    substeps, dt = config.timing.substeps, config.timing.physics_timestep
    layouts = _layouts(config, episodes, seed)
    results = []
    for name in models:
        per_episode = []
        for k, layout in enumerate(layouts):
            model = MODELS[name](config)
            _reset(model, config, layout, seed + k)
            block = 1 if model.reacts_to_robot else lookahead
            calls = -(-periods // block)
            path = _robot_path(layout, (calls + 1) * block, substeps).reshape(calls + 1, block * substeps, 2)
            model.advance(dt, block * substeps, robot_positions=path[0], robot_radius=config.robot.radius)
            start, cpu = time.perf_counter(), time.process_time()
            for c in range(1, calls + 1):
                model.advance(dt, block * substeps, robot_positions=path[c], robot_radius=config.robot.radius)
            timed = calls * block
            per_episode.append(((time.perf_counter() - start) / timed, (time.process_time() - cpu) / timed))
        wall, cpu = 1e6 * np.median(per_episode, axis=0)
        results.append(StepCost(name, float(wall), float(cpu), periods * episodes, block))
    return results


def pyrvo_step_cost(task: str = "stage7", episodes: int = 5, periods: int = 300, seed: int = 0) -> StepCost | None:
    """The same measurement for RVO2 through the ``pyrvo`` binding, if it is installed (else None).

    Only ORCA itself is timed (``do_step`` per physics step, walls as an obstacle, CrowdNav's
    parameters), with preferred velocities towards fixed random goals set from Python before
    each step as a crowd model would: no goal redraws, guard or contact counting.
    """
    try:
        import pyrvo  # noqa: PLC0415  # deferred: optional, not a dependency (None without it)
    except ImportError:
        return None
    config, orca = load_task(task), OrcaConfig()
    substeps, dt = config.timing.substeps, config.timing.physics_timestep
    hx, hy = 0.5 * config.arena.size[0], 0.5 * config.arena.size[1]
    per_episode = []
    for k, layout in enumerate(_layouts(config, episodes, seed)):
        sim, n = pyrvo.RVOSimulator(), len(layout.ped_radii)
        sim.set_time_step(dt)
        for i in range(n):
            sim.add_agent(tuple(layout.ped_positions[i]), orca.neighbor_dist, orca.max_neighbors, orca.time_horizon,
                          orca.time_horizon_obst, float(layout.ped_radii[i]) + orca.safety_margin,
                          float(layout.ped_speeds[i]), (0.0, 0.0))  # fmt: skip
        sim.add_obstacle([(-hx, -hy), (-hx, hy), (hx, hy), (hx, -hy)])
        sim.process_obstacles()
        goals = np.random.default_rng(seed + k).uniform(-0.8 * hx, 0.8 * hx, (n, 2))
        start = cpu = 0.0
        for p in range(periods + 5):
            if p == 5:
                start, cpu = time.perf_counter(), time.process_time()
            for _ in range(substeps):
                now = np.array([sim.get_agent_position(i).to_tuple() for i in range(n)])
                delta = goals - now
                pref = delta * (layout.ped_speeds / np.maximum(np.linalg.norm(delta, axis=1), 1e-9))[:, None]
                for i in range(n):
                    sim.set_agent_pref_velocity(i, tuple(pref[i]))
                sim.do_step()
        per_episode.append(((time.perf_counter() - start) / periods, (time.process_time() - cpu) / periods))
    wall, cpu = 1e6 * np.median(per_episode, axis=0)
    return StepCost("pyrvo", float(wall), float(cpu), periods * episodes)


def orca_contacts(
    task: str = "stage7", episodes: int = 100, config: OrcaConfig | None = None, seed: int = 0
) -> dict[str, int]:
    """Pedestrian-pedestrian contacts of ORCA crowds over whole episodes of ``task`` (no robot).

    A non-reactive crowd does not depend on the robot, so these are the crowds of real episodes
    (layouts drawn as the task draws them; goal draws seeded here, not as :class:`mjnav.sim.NavSim`
    seeds them), each run for the full ``timing.episode_steps`` control periods.

    Args:
        task: Stage name or YAML path.
        episodes: Episodes, >= 1.
        config: ORCA parameters; None: the defaults.
        seed: Seed of the layouts and the models' generators.

    Returns:
        ``{"episodes", "steps", "overlapping_pair_steps", "episodes_with_contact",
        "guard_corrections"}``: steps are physics steps in all; a contact is a pair of discs
        overlapping after a step.
    """
    task_config = load_task(task)
    timing = task_config.timing
    steps = timing.episode_steps * timing.substeps
    totals = {"episodes": episodes, "steps": 0, "overlapping_pair_steps": 0, "episodes_with_contact": 0,
              "guard_corrections": 0}  # fmt: skip
    for k, layout in enumerate(_layouts(task_config, episodes, seed)):
        model = OrcaModel(config)
        _reset(model, task_config, layout, seed + k)
        model.advance(timing.physics_timestep, steps)
        totals["steps"] += steps
        totals["overlapping_pair_steps"] += model.overlaps
        totals["episodes_with_contact"] += int(model.overlaps > 0)
        totals["guard_corrections"] += model.guard_corrections
    return totals


@dataclasses.dataclass(frozen=True)
class CrowdOptions:
    """The keys of ``bench crowd``.

    Attributes:
        task: Stage whose layouts and crowd are used.
        episodes: Layouts timed per model (each ``periods`` control periods).
        periods: Control periods timed per layout.
        contact_episodes: Whole ORCA episodes whose pedestrian-pedestrian contacts are counted.
    """

    task: str = "stage7"
    episodes: int = 5
    periods: int = 300
    contact_episodes: int = 20


def grammar() -> Grammar:
    """:class:`CrowdOptions`; no config overrides."""
    return Grammar(CrowdOptions, ())


def run(parsed: Parsed, argv: list[str]) -> int:
    """Prints the cost table of every model (and pyrvo's if installed) and ORCA's contacts; an
    unknown task is one error line (exit code 2)."""
    opts: CrowdOptions = parsed.options
    try:
        load_task(opts.task)
    except ConfigError as err:
        print(f"error: {err}", file=sys.stderr)
        return 2
    print("model          periods/call  wall us/control step  CPU us/control step")
    costs = [*crowd_step_cost(opts.task, episodes=opts.episodes, periods=opts.periods),
             *crowd_step_cost(opts.task, models=("random_walk", "orca"), episodes=opts.episodes,
                              periods=opts.periods, lookahead=10),
             pyrvo_step_cost(opts.task, episodes=opts.episodes, periods=opts.periods)]
    for cost in costs:
        if cost is not None:
            print(f"{cost.model:14s} {cost.periods_per_call:12d} {cost.us_per_control_step:21.1f} "
                  f"{cost.cpu_us_per_control_step:20.1f}")  # fmt: skip
    print(f"orca contacts, {opts.task}:", orca_contacts(opts.task, episodes=opts.contact_episodes))
    return 0
