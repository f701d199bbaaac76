"""Step every stage for a long time and report memory growth and warnings.

    python scripts/soak.py [steps=1000000] [seed=0] [every=10000] [figure=docs/media/soak.png]

One Gymnasium environment per stage (1-7), episodes taken in turn, each with a random policy:
raw actions drawn uniformly from [-4, 4] (the sigmoid then spans the whole polygon) on even
episodes and ``mpc_goal`` on odd ones, so both the learned-action layer and a planner run. The
resident set size (``/proc/self/statm``) is sampled every ``every`` steps; growth is measured
from the first sample after warm-up (10 % of the steps) to the end. Every warning (Python
``warnings`` and the ``mjnav``/``absl`` loggers) is counted by message. Prints a JSON report,
saves RSS against steps, exits 1 when memory grew by more than 5 % or any exception escaped.
"""

from __future__ import annotations

import dataclasses
import json
import logging
import os
import sys
import time
import warnings
from collections import Counter
from pathlib import Path
from typing import Any

import numpy as np

from mjnav.args import Parsed
from mjnav.cli import run_script


def rss_mb() -> float:
    """Resident set size of this process, MiB (Linux ``/proc``; peak RSS elsewhere)."""
    try:
        with open("/proc/self/statm") as f:
            return int(f.read().split()[1]) * os.sysconf("SC_PAGE_SIZE") / 2**20
    except OSError:
        import resource

        return resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024


class _Counter(logging.Handler):
    def __init__(self, counts: Counter) -> None:
        super().__init__(logging.WARNING)
        self.counts = counts

    def emit(self, record: logging.LogRecord) -> None:
        self.counts[f"{record.name}: {record.getMessage()[:120]}"] += 1


def run(steps: int, seed: int = 0, every: int = 10_000) -> dict[str, Any]:
    """Soak; returns the report with the RSS samples."""
    from mjnav.envs.gym_env import NavGymEnv
    from mjnav.eval.policies import load_policy

    rng = np.random.default_rng(seed)
    envs = [NavGymEnv(f"stage{k}", seed=seed + k) for k in range(1, 8)]
    planner = load_policy("mpc_goal")
    counts: Counter = Counter()
    handler = _Counter(counts)
    for name in ("mjnav", "absl", "py.warnings"):
        logging.getLogger(name).addHandler(handler)
    samples, outcomes, done_steps, episode, t0 = [(0, rss_mb())], Counter(), 0, 0, time.perf_counter()
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        while done_steps < steps:
            env = envs[episode % len(envs)]
            use_planner = episode % 2 == 1
            seed_k = int(rng.integers(2**31 - 1))
            agent = planner if use_planner else None
            if agent is not None:
                agent.begin(env.task, seed_k)
            else:
                env.task.planner = None
            obs, _ = env.reset(options={"episode_seed": seed_k})
            finished = False
            while not finished and done_steps < steps:
                action = agent.act(obs) if agent is not None else rng.uniform(-4, 4, env.action_space.shape)
                obs, _, terminated, truncated, info = env.step(action.astype(np.float32))
                finished, done_steps = terminated or truncated, done_steps + 1
                if done_steps % every == 0:
                    samples.append((done_steps, rss_mb()))
            outcomes[info["outcome"] if finished else "cut"] += 1
            episode += 1
        for w in caught:
            counts[f"{w.category.__name__}: {str(w.message)[:120]}"] += 1
    for name in ("mjnav", "absl", "py.warnings"):
        logging.getLogger(name).removeHandler(handler)
    for env in envs:
        env.close()
    warm = next((s for s in samples if s[0] >= 0.1 * steps), samples[-1])
    growth = (samples[-1][1] - warm[1]) / warm[1]
    return {"steps": done_steps, "episodes": episode, "seconds": round(time.perf_counter() - t0, 1),
            "outcomes": dict(outcomes), "rss_mb_after_warm_up": round(warm[1], 1),
            "rss_mb_end": round(samples[-1][1], 1), "growth": round(growth, 4), "warnings": dict(counts),
            "samples": samples}


def figure(report: dict[str, Any], path: Path) -> None:
    """RSS against environment steps."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    steps, rss = zip(*report["samples"])
    fig, ax = plt.subplots(figsize=(6, 3.2))
    ax.plot(steps, rss, lw=1.2)
    ax.axvline(0.1 * report["steps"], color="grey", lw=0.8, ls="--")
    ax.set_xlabel("environment steps (all 7 stages in turn)")
    ax.set_ylabel("resident memory, MiB")
    ax.set_title(f"soak: {report['steps']:,} steps, growth after warm-up {100 * report['growth']:+.2f} %", fontsize=9)
    fig.tight_layout()
    path.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(path, dpi=110)
    plt.close(fig)


@dataclasses.dataclass(frozen=True)
class SoakOptions:
    """The keys of ``scripts/soak.py``.

    Attributes:
        steps: Environment steps in all (all 7 stages in turn).
        seed: Environment seed.
        every: Steps between two resident-memory samples.
        figure: Figure of memory against steps (empty: none).
    """

    steps: int = 1_000_000
    seed: int = 0
    every: int = 10_000
    figure: str = "docs/media/soak.png"


def main(argv: list[str]) -> int:
    """Parse ``key=value`` arguments (``--help``: the keys), soak, print the report; 1 on > 5 % growth."""
    return run_script(argv, "scripts/soak.py", "Step every stage for a long time and watch resident memory.",
                      SoakOptions, _main)


def _main(parsed: Parsed) -> int:
    opts: SoakOptions = parsed.options
    report = run(opts.steps, opts.seed, opts.every)
    if opts.figure:
        figure(report, Path(opts.figure))
    print(json.dumps({k: v for k, v in report.items() if k != "samples"}, indent=1))
    return 1 if report["growth"] > 0.05 else 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
