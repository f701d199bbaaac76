"""``mjnav plot <figure>``: one episode's paths, the paper's Ours-vs-TEB and qualitative figures,
learning curves, success by distance (:mod:`mjnav.eval.plots`).

    mjnav plot episode task=stage6 policy=PATH_OR_NAME [seed=0] [out=episode.png] [plans=0.5,1.5,2.5]
    mjnav plot compare tasks=stage5,stage6,stage7 policies=PATTERN,teb [seed=0] [out=compare.png]
    mjnav plot curve run=runs/stage6-... [out=curve.png] [smooth=10]
    mjnav plot distance evals=A/stage7.jsonl,B/stage7.jsonl [labels=Ours,TEB] [edges=0,2,4,6,8]

``mjnav plot <figure> --help`` lists each figure's keys.
"""

from __future__ import annotations

import dataclasses
import sys
from pathlib import Path

from mjnav.args import Grammar, Parsed
from mjnav.cli import main as cli_main
from mjnav.config import TASK_SECTIONS
from mjnav.eval.runner import episode_setup, run_episode
from mjnav.eval.tables import format_strata, load_rows, success_by_distance
from mjnav.verbs.render import setup_args

__all__ = ["CompareOptions", "CurveOptions", "DistanceOptions", "EpisodeOptions", "compare", "compare_grammar",
           "curve", "curve_grammar", "distance", "distance_grammar", "episode", "episode_grammar", "main"]


@dataclasses.dataclass(frozen=True)
class EpisodeOptions:
    """The keys of ``plot episode``.

    Attributes:
        task: Bundled stage name or task YAML path.
        policy: A run folder, policy file, shipped policy or planner (a registered name,
            ``package.module:Class`` or ``path/to/file.py:Class``).
        seed: Held-out scenario index (episode seed 2**32 + seed, as in evaluation).
        episode_seed: A raw episode seed instead of ``seed``.
        out: Figure file.
        plans: Comma-separated times (s) at which to draw a learned policy's convex region and
            reference trajectory (the paper's qualitative figure).
    """

    task: str = "stage6"
    policy: str = "mpc_goal"
    seed: int = 0
    episode_seed: int | None = None
    out: str = "episode.png"
    plans: str | None = None


@dataclasses.dataclass(frozen=True)
class CompareOptions:
    """The keys of ``plot compare``: every policy on the same scenario under the same task overrides.

    Attributes:
        policies: Comma-separated policies, one column each; ``{stage}`` in a path is filled in per task.
        tasks: Comma-separated stages, one row each (default: ``task``).
        task: The stage when ``tasks`` is not given.
        seed: Held-out scenario index.
        episode_seed: A raw episode seed instead of ``seed``.
        out: Figure file.
    """

    policies: str | None = None
    tasks: str | None = None
    task: str = "stage6"
    seed: int = 0
    episode_seed: int | None = None
    out: str = "compare.png"


@dataclasses.dataclass(frozen=True)
class CurveOptions:
    """The keys of ``plot curve``.

    Attributes:
        run: Run folder (its TensorBoard events); required.
        out: Figure file.
        smooth: Moving-average window, iterations.
    """

    run: str | None = None
    out: str = "curve.png"
    smooth: int = 10


@dataclasses.dataclass(frozen=True)
class DistanceOptions:
    """The keys of ``plot distance``: success by start-goal distance with 95 % intervals, as a figure
    and a markdown table.

    Attributes:
        evals: Comma-separated evaluation JSONL files (``mjnav evaluate``, ``mjnav tables``); required.
        labels: Comma-separated names, one per file (default: the folder names).
        edges: Comma-separated distance bin edges, metres.
        out: Figure file.
    """

    evals: str | None = None
    labels: str | None = None
    edges: str = "0,2,4,6,8"
    out: str = "distance.png"


def _grammar(options: type, prefixes: tuple[str, ...]) -> Grammar:
    return Grammar(options, prefixes, {}, TASK_SECTIONS)


def episode_grammar() -> Grammar:
    """:class:`EpisodeOptions`, ``task.*`` overrides and ``planner.*`` parameters."""
    return _grammar(EpisodeOptions, ("task", "planner"))


def compare_grammar() -> Grammar:
    """:class:`CompareOptions` and ``task.*`` overrides."""
    return _grammar(CompareOptions, ("task",))


def curve_grammar() -> Grammar:
    """:class:`CurveOptions`."""
    return _grammar(CurveOptions, ())


def distance_grammar() -> Grammar:
    """:class:`DistanceOptions`."""
    return _grammar(DistanceOptions, ())


def main(argv: list[str]) -> int:
    """``mjnav plot`` with ``argv`` (figure first); returns the exit code."""
    return cli_main(["plot", *argv])


def _panel(env, agent, seed: int, instants: list[float] | None = None) -> tuple[dict, object]:
    """Run one episode; the keyword arguments of :func:`mjnav.eval.plots.draw_episode` and its metrics."""
    metrics, _, trace = run_episode(env, agent, seed)
    dt = env.config.timing.control_period
    plans = []
    if instants:
        if not trace.plans:
            raise ValueError(f"plans=: {agent.name} is a baseline; only learned policies plan with the convex region")
        plans = [trace.plans[min(len(trace.plans) - 1, round(t / dt))] for t in instants]
    title = f"{env.config.name} · {agent.name} · {metrics.outcome} in {metrics.time_s:.1f} s"
    return {"positions": trace.positions, "pedestrians": trace.pedestrians, "layout": env.task.layout,
            "arena_size": env.config.arena.size, "title": title, "plans": plans}, metrics


def _fail(err: Exception) -> int:
    print(f"error: {err}", file=sys.stderr)
    return 2


def episode(parsed: Parsed, argv: list[str]) -> int:
    """Plot one episode; returns the exit code."""
    # deferred: mjnav.eval.plots ~0.4 s (matplotlib), not needed by `mjnav plot <figure> --help`
    from mjnav.eval.plots import plot_episode

    opts: EpisodeOptions = parsed.options
    try:
        env, agent, seed = episode_setup(setup_args(opts), parsed.task, parsed.planner)
        try:
            instants = [float(t) for t in opts.plans.split(",")] if opts.plans else None
        except ValueError:
            raise ValueError(f"plans=: comma-separated times in s, got {opts.plans!r}") from None
        panel, metrics = _panel(env, agent, seed, instants)
    except (ValueError, FileNotFoundError, KeyError) as err:  # KeyError: an unknown planner name
        return _fail(err)
    panel["title"] += f" · seed {seed}"
    out = plot_episode(out=opts.out, dt=env.config.timing.control_period, **panel)
    print(f"{out}: {metrics.outcome}, {metrics.time_s:.1f} s, {metrics.distance_m:.2f} m")
    return 0


def compare(parsed: Parsed, argv: list[str]) -> int:
    """Plot every policy on every task; returns the exit code."""
    # deferred: mjnav.eval.plots ~0.4 s (matplotlib), not needed by `mjnav plot <figure> --help`
    from mjnav.eval.plots import plot_grid

    opts: CompareOptions = parsed.options
    if opts.policies is None:
        return _fail(ValueError("compare needs policies=A,B (a {stage} in a path is filled in per task)"))
    rows, lines = [], []
    try:
        for task in (opts.tasks or opts.task).split(","):
            row = []
            for pattern in opts.policies.split(","):
                one = dataclasses.replace(opts, task=task)
                env, agent, seed = episode_setup({**setup_args(one), "policy": pattern.format(stage=task)},
                                                 parsed.task)
                panel, metrics = _panel(env, agent, seed)
                row.append(panel)
                lines.append(f"{task} {agent.name}: {metrics.outcome}, {metrics.time_s:.1f} s")
                env.close()
            rows.append(row)
    except (ValueError, FileNotFoundError, KeyError) as err:  # KeyError: an unknown planner name
        return _fail(err)
    print("\n".join([f"{plot_grid(rows, opts.out)}:", *lines]))
    return 0


def curve(parsed: Parsed, argv: list[str]) -> int:
    """Plot a run's learning curves; returns the exit code."""
    # deferred: mjnav.eval.plots ~0.4 s (matplotlib), not needed by `mjnav plot <figure> --help`
    from mjnav.eval.plots import plot_learning_curve

    opts: CurveOptions = parsed.options
    if opts.run is None:
        return _fail(ValueError("curve needs run=RUN_DIR"))
    try:
        print(plot_learning_curve(opts.run, opts.out, opts.smooth))
    except (ValueError, FileNotFoundError, KeyError) as err:  # KeyError: an unknown planner name
        return _fail(err)
    return 0


def distance(parsed: Parsed, argv: list[str]) -> int:
    """Plot and tabulate success by start-goal distance; returns the exit code."""
    try:
        print(_distance(parsed.options))
    except (ValueError, FileNotFoundError, KeyError) as err:  # KeyError: an unknown planner name
        return _fail(err)
    return 0


def _distance(opts: DistanceOptions) -> str:
    # deferred: mjnav.eval.plots ~0.4 s (matplotlib), not needed by `mjnav plot <figure> --help`
    from mjnav.eval.plots import plot_success_by_distance

    if opts.evals is None:
        raise ValueError("distance needs evals=A.jsonl[,B.jsonl] (evaluation records)")
    paths = [Path(p) for p in opts.evals.split(",")]
    labels = opts.labels.split(",") if opts.labels else [p.parent.name or p.stem for p in paths]
    if not opts.labels and len(set(labels)) < len(labels):  # e.g. two stages of one method
        labels = [f"{p.parent.name}/{p.stem}" if p.parent.name else p.stem for p in paths]
    if len(labels) != len(paths) or len(set(labels)) < len(labels):
        raise ValueError(f"labels=: need {len(paths)} distinct names, got {labels}")
    try:
        edges = [float(e) for e in opts.edges.split(",")]
    except ValueError:
        raise ValueError(f"edges=: comma-separated distances in m, got {opts.edges!r}") from None
    series = {}
    for label, path in zip(labels, paths):
        rows = load_rows(path)
        if not rows:
            raise FileNotFoundError(f"{path}: no evaluation records")
        series[label] = success_by_distance(rows, edges)
    out = plot_success_by_distance(series, opts.out)
    return f"{out}:\n{format_strata(series)}"
