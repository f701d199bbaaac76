"""``mjnav bench evalscale``: held-out evaluation episodes per second with 1 and more workers, in one run.

    mjnav bench evalscale [backend=ray] [workers=1,2] [episodes=40] [task=stage5] [policy=mpc_goal]

For each worker count the same held-out episodes are evaluated (:func:`mjnav.eval.runner.evaluate`)
and timed; the last line is the ratio of the largest worker count's episodes/s to the first's (the
target for 2 workers on Ray is >= 1.7x). With ``backend=ray`` each worker count gets its own local
Ray (``ray.init(num_cpus=workers)``, timed apart) and a warm-up evaluation of ``workers`` episodes
of other seeds, so every worker process has imported mjnav and built its environment before the
timed episodes (a Ray worker keeps its environment across tasks); the table shows the start-up
(``ray.init`` + warm-up) and the timed episodes apart, and the ratio of both. With
``backend=local`` a pool of processes starts inside each timed evaluation (there is no warm pool).

The records of every worker count are compared with the first's (all fields but the solve times,
which are measured on the clock): the last column says whether they are the same episode for episode.
"""

from __future__ import annotations

import dataclasses
import sys
import tempfile
import time
from pathlib import Path
from typing import Any

from mjnav.args import Grammar, Parsed
from mjnav.schema import ConfigError

__all__ = ["EvalScaleOptions", "grammar", "run"]

#: Seed offset of the warm-up episodes: far from every evaluation and tuning set (0, 5e6, 6e6, 1e9).
WARM_UP_OFFSET = 2_000_000_000


@dataclasses.dataclass(frozen=True)
class EvalScaleOptions:
    """The keys of ``bench evalscale``.

    Attributes:
        task: Stage or task YAML.
        policy: Policy or planner (a cheap planner measures the scaling of the evaluation itself).
        episodes: Timed held-out episodes per worker count.
        workers: Comma-separated worker counts, the first the reference of the ratio.
        backend: ``ray`` or ``local`` (:data:`mjnav.eval.runner.BACKENDS`).
    """

    task: str = "stage5"
    policy: str = "mpc_goal"
    episodes: int = 40
    workers: str = "1,2"
    backend: str = "ray"


def grammar() -> Grammar:
    """:class:`EvalScaleOptions` and ``task.*`` overrides."""
    # deferred: mjnav.config ~0.3 s (numba, scipy, osqp), not needed by `mjnav --help`
    from mjnav.config import TASK_SECTIONS

    return Grammar(EvalScaleOptions, ("task",), {}, TASK_SECTIONS)


def _comparable(record: Any) -> Any:
    """``record`` without what the clock measures (solve times; their count kept)."""
    if isinstance(record, dict):
        return {k: len(v) if k == "solve_times_ms" else _comparable(v) for k, v in record.items()}
    return record


def _measure(spec: Any, out: Path) -> dict[str, float]:
    """Start-up and timed seconds of one worker count (see the module docstring)."""
    # deferred: the evaluation stack (MuJoCo, planners), not needed by `mjnav bench --help`
    from mjnav.eval.runner import evaluate

    times = {"init": 0.0, "warm": 0.0}
    ray = None
    if spec.backend == "ray":
        import ray  # deferred: an optional extra (pip install mjnav[ray])

        start = time.perf_counter()
        ray.init(num_cpus=spec.workers, include_dashboard=False, log_to_driver=False)
        times["init"] = time.perf_counter() - start
        start = time.perf_counter()
        warm = dataclasses.replace(spec, episodes=spec.workers, seed_offset=WARM_UP_OFFSET)
        evaluate(warm, None, progress=False)
        times["warm"] = time.perf_counter() - start
    try:
        start = time.perf_counter()
        evaluate(spec, out, progress=False)
        times["timed"] = time.perf_counter() - start
    finally:
        if ray is not None:
            ray.shutdown()
    return times


def run(parsed: Parsed, argv: list[str]) -> int:
    """Time each worker count and print the table and the ratio; returns the exit code."""
    # deferred: the evaluation stack (MuJoCo, planners), not needed by `mjnav bench --help`
    from mjnav.eval.runner import BACKENDS, EvalError, EvalSpec, jsonl_name, read_jsonl
    from mjnav.policy import training_overrides

    opts: EvalScaleOptions = parsed.options
    try:
        counts = [int(w) for w in opts.workers.split(",") if w.strip()]
        if not counts or min(counts) < 1 or opts.episodes < 1 or opts.backend not in BACKENDS:
            raise ConfigError(f"workers: comma-separated counts >= 1, episodes >= 1, backend one of "
                              f"{', '.join(BACKENDS)}; got workers={opts.workers} episodes={opts.episodes} "
                              f"backend={opts.backend}")
        base = EvalSpec(opts.task, opts.policy, opts.episodes, 0, parsed.task, 1,
                        tuple(training_overrides(opts.policy)), backend=opts.backend)
    except (ConfigError, ValueError, FileNotFoundError) as err:
        print(f"error: {err}", file=sys.stderr)
        return 2
    rows, reference = [], None
    with tempfile.TemporaryDirectory(prefix="mjnav-evalscale-") as tmp:
        for workers in counts:
            spec = dataclasses.replace(base, workers=workers)
            out = Path(tmp) / f"w{workers}"
            try:
                times = _measure(spec, out)
            except (EvalError, ConfigError, ValueError, FileNotFoundError) as err:  # no Ray, a bad task
                print(f"error: {err}", file=sys.stderr)
                return 2
            records = [_comparable(r) for r in read_jsonl(out / jsonl_name(base.task))]
            reference = records if reference is None else reference
            rows.append((workers, times, records == reference))
    _print(opts, rows)
    return 0


def _print(opts: EvalScaleOptions, rows: list[tuple[int, dict[str, float], bool]]) -> None:
    """The table and the ratio lines."""
    print(f"## {opts.task}, {opts.policy}, {opts.episodes} held-out episodes, backend {opts.backend}\n")
    print("| workers | start-up s (ray.init + warm-up) | timed s | episodes/s | with start-up | same records |")
    print("|---|---|---|---|---|---|")
    rates = []
    for workers, t, same in rows:
        startup = t["init"] + t["warm"]
        rate, whole = opts.episodes / t["timed"], opts.episodes / (t["timed"] + startup)
        rates.append((rate, whole))
        print(f"| {workers} | {t['init']:.1f} + {t['warm']:.1f} | {t['timed']:.1f} | {rate:.2f} | {whole:.2f} | "
              f"{'yes' if same else 'NO'} |")
    (first, first_whole), (last, last_whole) = rates[0], rates[-1]
    print(f"\n{rows[-1][0]} workers / {rows[0][0]}: {last / first:.2f}x episodes/s "
          f"({last_whole / first_whole:.2f}x with start-up)")
