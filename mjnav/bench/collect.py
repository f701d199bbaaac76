"""``mjnav bench collect``: PPO collection steps/s for 1, 2, ... workers, with where each step goes.

    mjnav bench collect task=stage7 [workers=1,2] [main_envs=-1,30] [pipeline=true,false]
        [rollouts=true,false] [rollout_envs=16,0] [rounds=3] [train.steps_per_env=64] [train.device=cuda]

Builds one training runner (:func:`mjnav.train.runner.build_runner`, the adapter of
``train.num_envs`` environments, rsl-rl's PPO) per worker count in ``workers`` (and, with 2 or
more workers, per trainer share in ``main_envs``: ``train.main_envs``; per setting in
``pipeline``: ``train.pipeline``; and, with the pipeline, per setting in ``rollouts``:
``train.rollouts``, with rollouts per part size in ``rollout_envs``: ``train.rollout_envs``) and
one environment alone, then times them in ``rounds``
interleaved rounds (each round: one PPO iteration of every runner, ``single_steps``
random-action steps of the single environment, in alternating order; :mod:`mjnav.timing`).
Prints, with medians over rounds:

* steps/s: collection (the rollout loop), the adapter's ``env.step`` alone (comparable with the
  single environment; with worker rollouts, the rollout less this process's policy calls in it,
  and the serving of its steps), the whole iteration (collection and update), and their ratios to 1
  worker and to the single environment: ratios of the medians, then the same ratios taken
  within each round (median and range over rounds; the blocks of one round run seconds apart,
  so the machine's drift over a run cancels);
* where one rollout step (all environments) goes, ms: the trainer's policy inference
  (``alg.act``; with the pipeline also the dispatch of the actions and the previous step's
  storage and logger, so that the storage and logger columns then hold only their hand-over;
  with worker rollouts, this process's policy calls in the rollout and the rest of ``alg.act``),
  then inside ``env.step`` (with worker rollouts inside the rollout) this process's own block,
  its wait for the worker processes (with worker rollouts: the rest of the rollout), the
  transfers through the shared buffers and the adapter's bookkeeping, then the PPO storage
  (``alg.process_env_step``), rsl-rl's logger and the rest of the loop; and, timed inside the
  worker processes, their mean and longest step (with worker rollouts their policy calls
  included) and the share of the step they are busy (the rest they wait for the trainer);
* per iteration: the returns (GAE) and the PPO update, seconds;
* a CPU-time estimate for a machine of its own: the trainer process's CPU time in the rollout
  loop and the slowest worker process's CPU time per step (which leave out waiting for a core
  on a shared machine), and ``num_envs`` over the larger of the two as env steps/s. It ignores
  the step-by-step wait for the slower side and the hand-off latency, so it is an upper bound;
  its ratios are what a loaded machine can still tell.

On a shared machine the rates drift; compare the shares and ratios of one run. ``workers`` takes
any list (``workers=1,2,4,8,15`` on a 16-core machine); ``train.device=cuda`` runs the policy
and the update on the GPU.
"""

from __future__ import annotations

import contextlib
import dataclasses
import functools
import io
import platform
import sys
import tempfile
import time
from collections import Counter
from collections.abc import Callable
from typing import Any

import numpy as np

from mjnav.args import Grammar, Parsed
from mjnav.bench.throughput import SingleEnv, parse_workers
from mjnav.config import TASK_SECTIONS, load_task
from mjnav.jobs import usable_cores
from mjnav.schema import ConfigError
from mjnav.train.config import TrainConfig, load_train

__all__ = ["STEP_PARTS", "CollectBench", "CollectOptions", "grammar", "run"]

#: Parts of one rollout step, ms (all environments), in the order of the loop.
STEP_PARTS: tuple[str, ...] = ("policy", "own block", "wait", "transfer", "adapter", "storage", "logger", "rest")


@dataclasses.dataclass(frozen=True)
class CollectOptions:
    """The keys of ``bench collect``.

    Attributes:
        task: Bundled stage name or task YAML path.
        workers: Worker counts to compare (``train.workers``, the trainer stepping the first block),
            comma-separated, as in 1,2,4,8,15; cores is one per usable core.
        main_envs: Trainer shares to compare with 2 or more workers, comma-separated
            (``train.main_envs``: the environments the trainer steps itself; -1: an even share).
        pipeline: ``train.pipeline`` settings to compare, comma-separated (``true,false``): the
            trainer dispatches each step's actions before its value estimates and storage, or
            keeps rsl-rl's order; with ``true`` the policy part holds the dispatch and the previous
            step's storage and logger as well (:mod:`mjnav.train.ppo`).
        rollouts: ``train.rollouts`` settings to compare with the pipeline, comma-separated
            (``true,false``): each worker runs the whole rollout of its environments with a copy of
            the actor, or they step in lockstep, step by step.
        rollout_envs: ``train.rollout_envs`` values to compare with rollouts, comma-separated
            (most environments a worker runs together through a rollout; 0: its whole block).
        rounds: Interleaved timing rounds (one PPO iteration of every configuration per round).
        single_steps: Random-action steps of the single environment per round.
    """

    task: str = "stage7"
    workers: str = "1,2"
    main_envs: str = "-1"
    pipeline: str = "true"
    rollouts: str = "true"
    rollout_envs: str = "16"
    rounds: int = 3
    single_steps: int = 400


def grammar() -> Grammar:
    """:class:`CollectOptions`, ``task.*`` and ``train.*`` overrides."""
    return Grammar(CollectOptions, ("task", "train"), {}, TASK_SECTIONS)


class CollectBench:
    """One training runner with ``workers`` workers; accumulates its phase times over timed iterations."""

    def __init__(self, config, train: TrainConfig, log_dir: str) -> None:
        # deferred: torch, rsl-rl and the adapter take ~4 s to import and are not needed by --help
        from mjnav.train.runner import build_runner, make_vec_env

        self.train = train
        env = make_vec_env(config, train)
        try:
            with contextlib.redirect_stdout(io.StringIO()):
                self.runner = build_runner(env, train, log_dir, label=f"{train.workers} workers")
        except BaseException:
            env.close()
            raise
        self.env = env
        self.seconds: Counter = Counter()  # phase -> seconds over the timed iterations
        self.iterations = 0
        self._rollout_cpu: float | None = None  # process CPU time at the first act() of the rollout
        self._instrument()
        self.block()  # warm-up: the first iteration's allocations, numba dispatch, solver caches
        self.seconds, self.iterations = Counter(), 0

    def _instrument(self) -> None:
        runner = self.runner
        act, returns = runner.alg.act, runner.alg.compute_returns

        @functools.wraps(act)
        def act_from_rollout_start(*args: Any, **kwargs: Any) -> Any:
            if self._rollout_cpu is None:
                self._rollout_cpu = time.process_time()
            return act(*args, **kwargs)

        @functools.wraps(returns)
        def returns_after_rollout(*args: Any, **kwargs: Any) -> Any:
            if self._rollout_cpu is not None:
                self.seconds["trainer cpu"] += time.process_time() - self._rollout_cpu
                self._rollout_cpu = None
            return returns(*args, **kwargs)

        runner.alg.act, runner.alg.compute_returns = act_from_rollout_start, returns_after_rollout
        self._timed(runner.alg, "act", "policy")
        self._timed(runner.alg, "process_env_step", "storage")
        self._timed(runner.logger, "process_env_step", "logger")
        self._timed(runner.alg, "compute_returns", "returns")
        self._timed(runner.alg, "update", "update")
        self._timed(runner.env, "rollout", "rollout")
        step, log = runner.env.step, runner.logger.log

        @functools.wraps(step)
        def step_and_note(*args: Any, **kwargs: Any) -> Any:
            start = time.perf_counter()
            result = step(*args, **kwargs)
            seconds, perf = self.seconds, result[3]["log"]
            seconds["env.step"] += time.perf_counter() - start
            for key in ("own_block", "wait", "transfer", "env_step", "worker_step", "worker_step_max",
                        "worker_cpu_max"):
                seconds[key] += perf[f"perf/{key}_ms"] / 1e3
            seconds["rollout policy"] += perf.get("perf/rollout_policy_ms", 0.0) / 1e3
            seconds["steps"] += 1
            return result

        @functools.wraps(log)
        def log_and_note(*args: Any, collect_time: float, learn_time: float, **kwargs: Any) -> Any:
            self.seconds["collection"] += collect_time
            return log(*args, collect_time=collect_time, learn_time=learn_time, **kwargs)

        runner.env.step, runner.logger.log = step_and_note, log_and_note

    def _timed(self, owner: Any, name: str, label: str) -> None:
        """Replace ``owner.name`` on the instance by a wrapper adding its wall time to ``seconds[label]``."""
        method: Callable = getattr(owner, name)

        @functools.wraps(method)
        def timed(*args: Any, **kwargs: Any) -> Any:
            start = time.perf_counter()
            try:
                return method(*args, **kwargs)
            finally:
                self.seconds[label] += time.perf_counter() - start

        setattr(owner, name, timed)

    def block(self) -> int:
        """One PPO iteration (collection and update); returns the env steps collected."""
        from mjnav.train.runner import learn  # deferred: as in __init__ (already loaded there)

        with contextlib.redirect_stdout(io.StringIO()):
            learn(self.runner, 1)
        self.iterations += 1
        return self.train.num_envs * self.train.steps_per_env

    def step_parts(self) -> dict[str, float]:
        """ms per rollout step (all environments) of each of :data:`STEP_PARTS`."""
        s = self.seconds
        n = max(s["steps"], 1)
        chose = s["rollout policy"]  # this process's policy calls within the rollouts
        wait = s["wait"]  # with rollouts: its wait for the worker processes at their end, spread over the steps
        parts = {"policy": s["policy"] - s["rollout"] + chose, "own block": s["own_block"], "wait": wait,
                 "transfer": s["transfer"],
                 "adapter": s["env.step"] + s["rollout"] - chose - s["own_block"] - wait - s["transfer"],
                 "storage": s["storage"], "logger": s["logger"]}
        parts["rest"] = s["collection"] - sum(parts.values())
        return {k: 1e3 * v / n for k, v in parts.items()}

    def cpu_estimate(self) -> tuple[float, float, float]:
        """Trainer CPU ms and slowest worker process's CPU ms per rollout step, and the env
        steps/s they allow on cores of their own (``num_envs`` over the larger; an upper bound)."""
        s = self.seconds
        n = max(s["steps"], 1)
        trainer, worker = 1e3 * s["trainer cpu"] / n, 1e3 * s["worker_cpu_max"] / n
        return trainer, worker, 1e3 * self.train.num_envs / max(trainer, worker, 1e-9)

    def close(self) -> None:
        """Stop the adapter's workers."""
        self.env.close()


def run(parsed: Parsed, argv: list[str]) -> int:
    """Benchmark; a bad task, override or value is one error line (exit code 2)."""
    try:
        opts: CollectOptions = parsed.options
        if opts.rounds < 1 or opts.single_steps < 1:
            raise ConfigError(f"rounds and single_steps must be >= 1, got {opts.rounds} and {opts.single_steps}")
        config = load_task(opts.task, list(parsed.task))
        train = load_train(list(parsed.train))
        configs = _configs(parse_workers(opts.workers, train.num_envs), opts.main_envs, opts.pipeline, train,
                           opts.rollouts, opts.rollout_envs)
    except (ConfigError, ValueError) as err:
        print(f"error: {err}", file=sys.stderr)
        return 2
    bench(config, configs, opts)
    return 0


def _configs(counts: list[int], shares: str, pipeline: str, train: TrainConfig, rollouts: str = "true",
             parts: str = "16") -> dict[str, TrainConfig]:
    """Training configs by row label: each worker count, with each trainer share when it has >= 2
    workers, each pipeline setting (labelled ``rsl-rl order`` when off), with the pipeline each
    rollouts setting (``step by step`` when off) and with rollouts each part size (``parts of K``
    when there are several).

    Raises:
        ConfigError: ``shares`` is not a list of -1 or counts in [1, num_envs), ``parts`` not a list
            of counts >= 0, or ``pipeline`` or ``rollouts`` not a list of true and false.
    """
    values, sizes = _integers("main_envs", shares), _integers("rollout_envs", parts)
    if any(size < 0 for size in sizes):
        raise ConfigError(f"rollout_envs: expected counts >= 0, got {parts!r}")
    modes = [(p, r, k) for p in _switches("pipeline", pipeline)
             for r in (_switches("rollouts", rollouts) if p else [False]) for k in (sizes if r else [sizes[0]])]
    configs = {}
    for w in counts:
        for m in values if w >= 2 else [-1]:
            for piped, rolled, size in modes:
                label = (f"{w}" if m < 0 else f"{w}, main {m}") + (
                    (f", parts of {size}" if len(sizes) > 1 else "") if rolled
                    else ", step by step" if piped else ", rsl-rl order")
                configs[label] = load_train([f"workers={w}", f"main_envs={m}", f"pipeline={str(piped).lower()}",
                                             f"rollouts={str(rolled).lower()}", f"rollout_envs={size}"], base=train)
    return configs


def _integers(name: str, text: str) -> list[int]:
    """A comma-separated list of integers (ConfigError otherwise)."""
    try:
        return [int(v) for v in str(text).split(",")]
    except ValueError:
        raise ConfigError(f"{name}: expected comma-separated integers, got {text!r}") from None


def _switches(name: str, text: str) -> list[bool]:
    """A comma-separated list of true and false (ConfigError otherwise; the empty string too)."""
    settings = [v.strip().lower() for v in str(text).split(",")]
    if any(v not in ("true", "false") for v in settings):
        raise ConfigError(f"{name}: expected comma-separated true or false, got {text!r}")
    return list(dict.fromkeys(v == "true" for v in settings))


def bench(config, configs: dict[str, TrainConfig], opts: CollectOptions) -> None:
    """Build every configuration, time them in interleaved rounds and print markdown tables."""
    train = next(iter(configs.values()))
    single = SingleEnv(config, opts.single_steps, train.seed)
    benches: dict[str, CollectBench] = {}
    rates: dict[str, list[float]] = {"single": []}
    collection: dict[str, list[float]] = {label: [] for label in configs}
    env_step: dict[str, list[float]] = {label: [] for label in configs}  # env steps/s of env.step alone
    try:
        with tempfile.TemporaryDirectory(prefix="mjnav-bench-collect-") as tmp:
            for k, (label, cfg) in enumerate(configs.items()):
                benches[label] = CollectBench(config, cfg, f"{tmp}/{k}")
            names: list[Any] = ["single", *configs]
            for r in range(opts.rounds):
                for name in names if r % 2 == 0 else names[::-1]:
                    if name == "single":
                        start = time.perf_counter()
                        rates["single"].append(single.block() / (time.perf_counter() - start))
                        continue
                    seconds = benches[name].seconds
                    before = seconds["collection"], _stepping(seconds), seconds["steps"]
                    steps = benches[name].block()
                    collection[name].append(steps / (seconds["collection"] - before[0]))
                    env_step[name].append(benches[name].train.num_envs * (seconds["steps"] - before[2])
                                          / (_stepping(seconds) - before[1]))
    finally:
        single.env.close()
        for b in benches.values():
            b.close()
    _print(config, train, opts, np.array(rates["single"]), {w: np.array(v) for w, v in collection.items()},
           {w: np.array(v) for w, v in env_step.items()}, benches)


def _stepping(seconds: Counter) -> float:
    """Seconds of ``env.step`` and of the rollouts, less this process's policy calls within them."""
    return seconds["env.step"] + seconds["rollout"] - seconds["rollout policy"]


def _paired(values: np.ndarray, reference: np.ndarray) -> str:
    """Median (min-max) over rounds of ``values / reference``, round by round."""
    ratios = values / reference
    return f"{np.median(ratios):.2f} ({ratios.min():.2f}-{ratios.max():.2f})"


def _print_paired(single: np.ndarray, collection: dict[str, np.ndarray], env_step: dict[str, np.ndarray]) -> None:
    """The ratios of the first table taken within each round, where the machine's speed drifts least."""
    counts = list(collection)
    print(f"\n| workers | collection x {counts[0]}, paired by round | env.step alone x {counts[0]}, paired by round "
          f"| env.step alone x one environment, paired by round |\n|---|---|---|---|")
    for w, values in collection.items():
        print(f"| {w} | {_paired(values, collection[counts[0]])} | {_paired(env_step[w], env_step[counts[0]])} | "
              f"{_paired(env_step[w], single)} |")


def _print(config, train: TrainConfig, opts: CollectOptions, single: np.ndarray, collection: dict[str, np.ndarray],
           env_step: dict[str, np.ndarray], benches: dict[str, CollectBench]) -> None:
    print(f"## {config.name}: {config.crowd.count} pedestrians; {train.num_envs} environments x "
          f"{train.steps_per_env} steps per iteration, {train.epochs} epochs x {train.minibatches} minibatches, "
          f"device {train.device}; medians of {opts.rounds} interleaved rounds (min-max)\n")
    print(f"Python {platform.python_version()} ({sys.executable}); {usable_cores()} usable cores\n")
    one = np.median(single)
    print(f"one environment alone, random actions: {np.median(single):,.0f} steps/s "
          f"({single.min():,.0f}-{single.max():,.0f})\n")
    counts = list(collection)
    first = np.median(collection[counts[0]])
    env_rates = {w: np.median(values) for w, values in env_step.items()}
    print(f"| workers | collection, env steps/s | x {counts[0]} | env.step alone, env steps/s | "
          f"x {counts[0]} | x one environment | iteration incl. update, env steps/s |")
    print("|---|---|---|---|---|---|---|")
    for w, values in collection.items():
        b = benches[w]
        steps = b.train.num_envs * b.train.steps_per_env * b.iterations
        whole = steps / max(b.seconds["collection"] + b.seconds["returns"] + b.seconds["update"], 1e-9)
        alone = env_step[w]
        print(f"| {w} | {np.median(values):,.0f} ({values.min():,.0f}-{values.max():,.0f}) | "
              f"{np.median(values) / first:.2f} | {env_rates[w]:,.0f} ({alone.min():,.0f}-{alone.max():,.0f}) | "
              f"{env_rates[w] / env_rates[counts[0]]:.2f} | "
              f"{env_rates[w] / one:.2f} | {whole:,.0f} |")
    _print_paired(single, collection, env_step)
    print("\n| rollout step, ms (share) | " + " | ".join(STEP_PARTS) +
          " | whole step | worker processes' step: mean / longest | worker processes busy |")
    print("|---|" + "---|" * (len(STEP_PARTS) + 3))
    for w, b in benches.items():
        parts, s = b.step_parts(), b.seconds
        total = sum(parts.values()) or 1.0
        n = max(s["steps"], 1)
        busy = f"{1e3 * s['worker_step'] / n / total:.0%}" if s["worker_step"] else "-"
        cells = " | ".join(f"{parts[p]:.2f} ({parts[p] / total:.0%})" for p in STEP_PARTS)
        print(f"| {w} | {cells} | {total:.2f} | {1e3 * s['worker_step'] / n:.2f} / "
              f"{1e3 * s['worker_step_max'] / n:.2f} | {busy} |")
    estimates = {w: b.cpu_estimate() for w, b in benches.items()}
    base = estimates[counts[0]][2]
    print("\n| CPU time per rollout step, ms | trainer process | slowest worker process | "
          f"estimate on cores of their own, env steps/s | x {counts[0]} |\n|---|---|---|---|---|")
    for w, (trainer, worker, rate) in estimates.items():
        print(f"| {w} | {trainer:.2f} | {worker:.2f} | {rate:,.0f} | {rate / base:.2f} |")
    print("\n| per iteration, s | collection | returns | PPO update |\n|---|---|---|---|")
    for w, b in benches.items():
        s, it = b.seconds, max(b.iterations, 1)
        print(f"| {w} | {s['collection'] / it:.2f} | {s['returns'] / it:.3f} | {s['update'] / it:.2f} |")
