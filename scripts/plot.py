"""Figures: one episode's paths, the paper's Ours-vs-TEB and qualitative figures, learning curves.

    python scripts/plot.py episode task=stage6 policy=PATH_OR_NAME [seed=0] [out=episode.png]
                           [plans=0.5,1.5,2.5] [task.KEY=VALUE ...]
    python scripts/plot.py compare tasks=stage5,stage6,stage7 policies={stage}_policy,teb
                           [seed=0] [out=compare.png] [task.KEY=VALUE ...]
    python scripts/plot.py curve run=runs/stage6-... [out=curve.png] [smooth=10]
    python scripts/plot.py distance evals=A/stage7.jsonl,B/stage7.jsonl [labels=Ours,TEB]
                           [edges=0,2,4,6,8] [out=distance.png]

``seed`` is the held-out scenario index (episode seed 2**32 + seed, as scripts/evaluate.py);
``episode_seed=K`` gives a raw episode seed. ``plans=`` draws, at those times (s), the convex
region and the reference trajectory of a learned policy (the paper's qualitative figure).
``compare``: one row per task, one column per policy (``{stage}`` is filled in), every policy on
the same scenario under the same task overrides. ``distance``: success by start-goal distance
(95 % intervals) of evaluation JSONLs (scripts/evaluate.py, paper_tables.py), as a figure and a
markdown table. See :mod:`mjnav.eval.plots`.
"""

from __future__ import annotations

import sys
from pathlib import Path

from mjnav.schema import split_args

_KEYS = ("task", "policy", "seed", "episode_seed", "out", "run", "smooth", "plans", "tasks", "policies",
         "evals", "labels", "edges")


def _parse(argv: list[str]) -> tuple[dict, list[str]]:
    opts, overrides = split_args(argv, dict.fromkeys(_KEYS))
    return {k: v for k, v in opts.items() if v is not None}, overrides


def _panel(env, agent, seed: int, instants: list[float] | None = None) -> tuple[dict, object]:
    """Run one episode; the keyword arguments of :func:`mjnav.eval.plots.draw_episode` and its metrics."""
    from mjnav.eval.runner import run_episode

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


def _episode(env, agent, seed: int, args: dict[str, str]) -> str:
    from mjnav.eval.plots import plot_episode

    instants = [float(t) for t in str(args["plans"]).split(",")] if "plans" in args else None
    panel, metrics = _panel(env, agent, seed, instants)
    panel["title"] += f" · seed {seed}"
    out = plot_episode(out=args.get("out", "episode.png"), dt=env.config.timing.control_period, **panel)
    return f"{out}: {metrics.outcome}, {metrics.time_s:.1f} s, {metrics.distance_m:.2f} m"


def _compare(args: dict[str, str], overrides: list[str]) -> str:
    from mjnav.eval.plots import plot_grid
    from mjnav.eval.runner import episode_setup

    if "policies" not in args:
        raise ValueError("compare needs policies=A,B (a {stage} in a path is filled in per task)")
    rows, lines = [], []
    for task in str(args.get("tasks", args.get("task", "stage6"))).split(","):
        row = []
        for pattern in str(args["policies"]).split(","):
            one = {k: v for k, v in args.items() if k in ("seed", "episode_seed")}
            env, agent, seed = episode_setup({**one, "task": task, "policy": pattern.format(stage=task)}, overrides)
            panel, metrics = _panel(env, agent, seed)
            row.append(panel)
            lines.append(f"{task} {agent.name}: {metrics.outcome}, {metrics.time_s:.1f} s")
            env.close()
        rows.append(row)
    out = plot_grid(rows, args.get("out", "compare.png"))
    return "\n".join([f"{out}:", *lines])


def _distance(args: dict[str, str]) -> str:
    from mjnav.eval.plots import plot_success_by_distance
    from mjnav.eval.tables import format_strata, load_rows, success_by_distance

    if "evals" not in args:
        raise ValueError("distance needs evals=A.jsonl[,B.jsonl] (evaluation records)")
    paths = [Path(p) for p in str(args["evals"]).split(",")]
    labels = str(args["labels"]).split(",") if "labels" in args else [p.parent.name or p.stem for p in paths]
    if "labels" not in args and len(set(labels)) < len(labels):  # e.g. two stages of one method
        labels = [f"{p.parent.name}/{p.stem}" if p.parent.name else p.stem for p in paths]
    if len(labels) != len(paths) or len(set(labels)) < len(labels):
        raise ValueError(f"labels=: need {len(paths)} distinct names, got {labels}")
    try:
        edges = [float(e) for e in str(args.get("edges", "0,2,4,6,8")).split(",")]
    except ValueError:
        raise ValueError(f"edges=: comma-separated distances in m, got {args['edges']!r}") from None
    series = {}
    for label, path in zip(labels, paths):
        rows = load_rows(path)
        if not rows:
            raise FileNotFoundError(f"{path}: no evaluation records")
        series[label] = success_by_distance(rows, edges)
    out = plot_success_by_distance(series, args.get("out", "distance.png"))
    return f"{out}:\n{format_strata(series)}"


def main(argv: list[str]) -> int:
    """Dispatch to ``episode``, ``compare``, ``curve`` or ``distance``."""
    if not argv or argv[0] not in ("episode", "compare", "curve", "distance"):
        print(__doc__, file=sys.stderr)
        return 2
    try:
        args, overrides = _parse(argv[1:])
    except ValueError as err:
        print(f"error: {err}", file=sys.stderr)
        return 2
    if argv[0] in ("compare", "distance"):
        try:
            print(_compare(args, overrides) if argv[0] == "compare" else _distance(args))
        except (ValueError, FileNotFoundError) as err:
            print(f"error: {err}", file=sys.stderr)
            return 2
        return 0
    if argv[0] == "episode":
        from mjnav.eval.runner import episode_setup

        try:
            loaded = episode_setup(args, overrides)
        except (ValueError, FileNotFoundError) as err:
            print(f"error: {err}", file=sys.stderr)
            return 2
        try:
            print(_episode(*loaded, args))
        except ValueError as err:
            print(f"error: {err}", file=sys.stderr)
            return 2
        return 0
    from mjnav.eval.plots import plot_learning_curve

    if "run" not in args:
        print("error: curve needs run=RUN_DIR", file=sys.stderr)
        return 2
    try:
        print(plot_learning_curve(args["run"], args.get("out", "curve.png"), int(args.get("smooth", 10))))
    except (ValueError, FileNotFoundError) as err:
        print(f"error: {err}", file=sys.stderr)
        return 2
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
