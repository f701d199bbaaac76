"""``mjnav bench throughput``: steps/s for 1 env and the vectorised adapter, with a per-part breakdown.

    mjnav bench throughput task=stage7 [rounds=5] [steps=400] [vec_steps=10] [num_envs=64] [workers=1,2,cores] [crowd.count=25]

Prints, all from one run:
  * bare MuJoCo ``mj_step`` rate of the same compiled world (reference);
  * one environment with random actions, stepped by ``composer.Environment.step`` and by the
    Gymnasium environment's task steps (``NavEnvironment.step_task``, what the adapter runs):
    steps/s and µs per part (physics = substeps incl. pedestrians and tracking force, lidar,
    region, action mapping, MPC, reward, observation, rest = composer and wrapper overhead);
  * ``num_envs`` such environments stepped in turn in this process without the adapter (what
    the working set of many environments costs by itself), and stepped stage by stage as the
    adapter's workers step them (:func:`mjnav.envs.workers.step_in_stages`);
  * the rsl-rl adapter (``NavVecEnv``) over ``num_envs`` environments (default: the training
    default, ``train.num_envs``) with each count of ``workers`` (default 1, 2 and all usable cores;
    ``workers=1,2,4,8,15`` on a 16-core machine; this process stepping the first block), and as
    many worker processes as the largest count (at least 2) with this process idle; with the
    ratios to the first row and to one environment, and where an adapter step's time goes: this
    process's own block, its wait for the worker processes (the slower block), the transfers
    through the shared buffers, the adapter's bookkeeping, and the loop outside the adapter.

This machine's speed drifts by up to 2x within minutes, so every configuration is built first
and then timed in ``rounds`` rounds: each round runs one block of each configuration (``steps``
control steps alone, ``vec_steps`` adapter steps of all environments), in alternating order. Each
row reports the median over rounds and the spread; every row's figure is also given as a ratio to
the bare physics rate measured in the same rounds, which is what compares across runs.
"""

from __future__ import annotations

import dataclasses
import os
import platform
import sys
import time

import mujoco
import numpy as np

from mjnav.args import Grammar, Parsed
from mjnav.config import TASK_SECTIONS, load_task
from mjnav.envs.gym_env import NavGymEnv
from mjnav.envs.workers import step_in_stages
from mjnav.jobs import usable_cores
from mjnav.schema import ConfigError
from mjnav.timing import Block, time_rounds
from mjnav.train.config import TrainConfig

__all__ = [
    "EnvsInTurn", "SingleEnv", "ThroughputOptions", "VecBench", "adapter_rows", "bare_physics", "grammar",
    "parse_workers", "run"
]


@dataclasses.dataclass(frozen=True)
class ThroughputOptions:
    """The keys of ``bench throughput``.

    Attributes:
        task: Bundled stage name or task YAML path.
        rounds: Interleaved timing rounds (the median and spread are over these).
        steps: Control steps per single-environment block.
        vec_steps: Adapter steps (of all environments) per adapter block.
        num_envs: Environments of the adapter (default: the training default ``train.num_envs``).
        workers: Adapter worker counts, comma-separated, as in 1,2,4,8,15; cores is one per usable core.
        seed: Environment seed.
    """

    task: str = "stage7"
    rounds: int = 5
    steps: int = 400
    vec_steps: int = 10
    num_envs: int = TrainConfig.num_envs
    workers: str = "1,2,cores"
    seed: int = 0


def grammar() -> Grammar:
    """:class:`ThroughputOptions` and ``task.*`` overrides."""
    return Grammar(ThroughputOptions, ("task",), {}, TASK_SECTIONS)


def parse_workers(text: str, num_envs: int) -> list[int]:
    """Worker counts of a ``workers=`` list (``cores``: the usable cores), each in [1, num_envs];
    duplicates dropped, order kept.

    Raises:
        ConfigError: Not a comma-separated list of counts in range.
    """
    counts = []
    for item in str(text).split(","):
        item = item.strip()
        count = min(num_envs, usable_cores()) if item == "cores" else int(item) if item.isdigit() else None
        if count is None or not 1 <= count <= num_envs:
            raise ConfigError(f"workers: expected comma-separated counts in [1, num_envs={num_envs}] or 'cores', "
                              f"got {text!r}")
        counts.append(count)
    return list(dict.fromkeys(counts))


def bare_physics(env: NavGymEnv, steps: int) -> Block:
    """Blocks of ``steps`` mj_step calls on a copy of the environment's compiled model and data."""
    model = env.physics.model.ptr
    data = mujoco.MjData(model)
    mujoco.mj_copyData(data, model, env.physics.data.ptr)

    def block() -> int:
        for _ in range(steps):
            mujoco.mj_step(model, data)
        return steps

    return block


class SingleEnv:
    """One environment with random actions; accumulates per-part times over all timed blocks."""

    def __init__(self, config, steps: int, seed: int, task_steps: bool = True) -> None:
        self.env = NavGymEnv(config, seed=seed, task_steps=task_steps)
        self.steps = steps
        self.rng = np.random.default_rng(seed)
        self.env.reset(seed=seed)
        self.reset_time = self.total_time = 0.0
        self.total_steps = 0
        self.block()  # warm-up: numba dispatch, solver caches
        task = self.env.task
        self._timers = (task.timers, task.core.timers)
        for timers in self._timers:
            timers.update(dict.fromkeys(timers, 0.0))
        self.reset_time = self.total_time = 0.0
        self.total_steps = 0

    def block(self) -> int:
        """``steps`` random-action control steps (finished episodes are reset)."""
        env, reset_time = self.env, 0.0
        actions = self.rng.normal(size=(self.steps, 4)).astype(np.float32)
        start = time.perf_counter()
        for a in actions:
            _, _, term, trunc, _ = env.step(a)
            if term or trunc:
                t0 = time.perf_counter()
                env.reset()
                reset_time += time.perf_counter() - t0
        self.total_time += time.perf_counter() - start
        self.reset_time += reset_time
        self.total_steps += self.steps
        return self.steps

    def parts(self) -> dict[str, float]:
        """µs per step of each part over all timed blocks; ``rest`` is what no timer covers."""
        n = max(self.total_steps, 1)
        parts = {k: 1e6 * v / n for timers in self._timers for k, v in timers.items()}
        parts["reset (amortised)"] = 1e6 * self.reset_time / n
        parts["rest (composer, wrappers)"] = 1e6 * self.total_time / n - sum(parts.values())
        return parts


class EnvsInTurn:
    """``num_envs`` Gymnasium environments (task steps) stepped in this process, no adapter: in
    turn, or stage by stage as the adapter's workers step them (``staged``, :func:`step_in_stages`)."""

    def __init__(self, config, num_envs: int, steps: int, seed: int, staged: bool = False) -> None:
        self.envs = [NavGymEnv(config) for _ in range(num_envs)]
        for i, env in enumerate(self.envs):
            env.reset(seed=seed + i)
        self.steps, self.rng, self.staged = steps, np.random.default_rng(seed), staged
        self.block()  # warm-up

    def block(self) -> int:
        """``steps`` random-action steps of every environment (finished episodes are reset)."""
        for _ in range(self.steps):
            actions = self.rng.normal(size=(len(self.envs), 4)).astype(np.float32)
            if self.staged:
                results = step_in_stages(self.envs, list(actions))
            else:
                results = (env.step(action) for env, action in zip(self.envs, actions, strict=True))
            for env, (_, _, term, trunc, _) in zip(self.envs, results, strict=True):
                if term or trunc:
                    env.reset()
        return self.steps * len(self.envs)

    def close(self) -> None:
        """Close every environment."""
        for env in self.envs:
            env.close()


class VecBench:
    """The rsl-rl adapter with random actions; accumulates where its steps' time goes."""

    def __init__(self, config, num_envs: int, workers: int, steps: int, seed: int, step_in_main: bool) -> None:
        # deferred: torch ~1 s, the adapter and rsl-rl ~3 s more (after this module's own imports),
        # not needed by the other benchmark rows nor by `mjnav bench throughput --help`
        import torch

        from mjnav.envs.vec_env import NavVecEnv
        from mjnav.train.runner import TaskEnvFactory

        torch.set_num_threads(1)
        self.env = NavVecEnv(TaskEnvFactory(config), num_envs=num_envs, seed=seed, workers=workers,
                             max_episode_length=config.timing.episode_steps, step_in_main=step_in_main)
        self.steps, self.num_envs = steps, num_envs
        self.gen = torch.Generator().manual_seed(seed)
        self.sums = dict.fromkeys(("own", "wait", "transfer", "step", "total"), 0.0)  # ms over timed blocks
        self.total_steps = 0
        try:
            self.block()  # warm-up
        except BaseException:
            self.env.close()
            raise
        self.sums, self.total_steps = dict.fromkeys(self.sums, 0.0), 0

    def block(self) -> int:
        """``steps`` adapter steps of all environments."""
        import torch  # deferred: as in __init__ (already loaded there, so free here)

        sums = self.sums
        start = time.perf_counter()
        for _ in range(self.steps):
            log = self.env.step(torch.randn(self.num_envs, 4, generator=self.gen))[3]["log"]
            sums["own"] += log["perf/own_block_ms"]
            sums["wait"] += log["perf/wait_ms"]
            sums["transfer"] += log["perf/transfer_ms"]
            sums["step"] += log["perf/env_step_ms"]
        sums["total"] += 1e3 * (time.perf_counter() - start)
        self.total_steps += self.steps
        return self.steps * self.num_envs

    def parts(self) -> dict[str, float]:
        """ms per adapter step: own block, wait for the worker processes, transfers through the
        shared buffers, bookkeeping, outside the adapter."""
        s, n = self.sums, max(self.total_steps, 1)
        return {"own block": s["own"] / n, "wait for worker processes": s["wait"] / n,
                "transfers": s["transfer"] / n,
                "adapter bookkeeping": (s["step"] - s["own"] - s["wait"] - s["transfer"]) / n,
                "outside the adapter (random actions)": (s["total"] - s["step"]) / n}


def adapter_rows(counts: list[int]) -> list[tuple[str, int, bool]]:
    """(label, workers, step_in_main) of the adapter configurations: each count with this process
    stepping the first block, then as many worker processes as the largest count (at least 2)."""
    rows = [(f"{w} worker{'s' if w > 1 else ''}", w, True) for w in counts]
    procs = max(2, *counts)
    return [*rows, (f"{procs} worker processes (this process waits)", procs, False)]


def run(parsed: Parsed, argv: list[str]) -> int:
    """Benchmark; a bad task, override or value is one error line (exit code 2)."""
    try:
        opts: ThroughputOptions = parsed.options
        if opts.rounds < 1:
            raise ConfigError(f"rounds must be >= 1, got {opts.rounds}")
        config = load_task(opts.task, list(parsed.task))
        parse_workers(opts.workers, opts.num_envs)
    except ConfigError as err:
        print(f"error: {err}", file=sys.stderr)
        return 2
    bench(config, opts)
    return 0


def bench(config, opts: ThroughputOptions) -> None:
    """Build every configuration, time them in interleaved rounds and print markdown tables."""
    seed, num_envs, rounds = opts.seed, opts.num_envs, opts.rounds
    singles = {name: SingleEnv(config, opts.steps, seed, task_steps=name == "task")
               for name in ("composer", "task")}
    blocks: dict[str, Block] = {"bare": bare_physics(singles["task"].env, 5 * opts.steps)}
    blocks.update({f"single {name}": single.block for name, single in singles.items()})
    closers = [single.env.close for single in singles.values()]
    vecs: dict[str, VecBench] = {}
    try:
        for name, staged in (("in turn", False), ("in stages", True)):
            envs = EnvsInTurn(config, num_envs, opts.vec_steps, seed, staged)
            blocks[name] = envs.block
            closers.append(envs.close)
        for label, workers, in_main in adapter_rows(parse_workers(opts.workers, num_envs)):
            vecs[label] = VecBench(config, num_envs, workers, opts.vec_steps, seed, in_main)
            blocks[label] = vecs[label].block
            closers.append(vecs[label].env.close)
        rates = time_rounds(blocks, rounds)
    finally:
        for close in closers:
            close()
    _print(config, rates, {name: single.parts() for name, single in singles.items()}, num_envs, rounds)
    _print_split({label: vec.parts() for label, vec in vecs.items()})


_SINGLE_LABELS = {"composer": "composer.Environment.step (dm_env)",
                  "task": "Gymnasium, task steps (as in the adapter)"}


def _print(config, rates: dict[str, np.ndarray], parts: dict[str, dict[str, float]], num_envs: int,
           rounds: int) -> None:
    substeps = config.timing.substeps
    bare = rates.pop("bare")
    periods = np.median(bare) / substeps  # control periods/s of bare physics
    singles = {name: rates.pop(f"single {name}") for name in parts}
    in_turn = {name: rates.pop(name) for name in ("in turn", "in stages")}

    def spread(values: np.ndarray) -> str:
        return f"{np.median(values):,.0f} ({values.min():,.0f}-{values.max():,.0f})"

    print(f"## {config.name}: {config.crowd.count} pedestrians, {config.obstacles.count} obstacles, "
          f"LiDAR backend {config.lidar.backend}, MPC solver {config.mpc.solver}; "
          f"medians of {rounds} interleaved rounds (min-max)\n")
    print(f"Python {platform.python_version()} ({sys.executable}, {platform.python_compiler()}); "
          f"{os.cpu_count()} CPUs\n")
    print(f"bare mj_step: {spread(bare)} /s -> {periods:,.0f} control periods/s ({substeps} substeps)\n")
    print("| one environment, random actions | steps/s | us/step | x bare physics periods |\n|---|---|---|---|")
    for name, values in singles.items():
        print(f"| {_SINGLE_LABELS[name]} | {spread(values)} | {1e6 / np.median(values):.0f} | "
              f"{np.median(values) / periods:.3f} |")
    for name, values in in_turn.items():
        print(f"| {num_envs} such environments {name}, this process, no adapter "
              f"(x {np.median(values) / np.median(singles['task']):.2f} one environment) | {spread(values)} | "
              f"{1e6 / np.median(values):.0f} | {np.median(values) / periods:.3f} |")
    names = list(parts)
    print("\n| part (us/step) | " + " | ".join(_SINGLE_LABELS[n] for n in names) + " |")
    print("|---|" + "---|" * len(names))
    totals = {n: sum(parts[n].values()) for n in names}
    for part in parts[names[0]]:
        cells = " | ".join(f"{parts[n][part]:.1f} ({parts[n][part] / totals[n]:.0%})" for n in names)
        print(f"| {part} | {cells} |")
    first_label = next(iter(rates))
    first, one = np.median(rates[first_label]), np.median(singles["task"])
    print(f"\n| adapter: {num_envs} envs | env steps/s | x {first_label} | x one environment (task steps) | "
          f"x bare physics periods |\n|---|---|---|---|---|")
    for label, values in rates.items():
        rate = np.median(values)
        print(f"| {label} | {spread(values)} | {rate / first:.2f} | {rate / one:.2f} | {rate / periods:.3f} |")


def _print_split(splits: dict[str, dict[str, float]]) -> None:
    """Where an adapter step's time goes, per adapter configuration (means over the timed blocks)."""
    parts = list(next(iter(splits.values())))
    print("\n| adapter step, ms (share) | " + " | ".join(parts) + " |\n|---|" + "---|" * len(parts))
    for label, split in splits.items():
        total = sum(split.values()) or 1.0
        print(f"| {label} | " + " | ".join(f"{split[p]:.2f} ({split[p] / total:.0%})" for p in parts) + " |")
