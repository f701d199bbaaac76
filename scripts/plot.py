"""Figures: one episode's paths (the paper's qualitative figure) or a run's learning curve.

    python scripts/plot.py episode task=stage6 policy=PATH_OR_NAME [seed=0] [out=episode.png]
                           [task.KEY=VALUE ...]
    python scripts/plot.py curve run=runs/stage6-... [out=curve.png] [smooth=10]

``seed`` is the held-out scenario index (episode seed 2**32 + seed, as scripts/evaluate.py);
``episode_seed=K`` gives a raw episode seed. See :mod:`mjnav.eval.plots`.
"""

from __future__ import annotations

import sys

from mjnav.schema import split_args

_KEYS = ("task", "policy", "seed", "episode_seed", "out", "run", "smooth")


def _parse(argv: list[str]) -> tuple[dict, list[str]]:
    opts, overrides = split_args(argv, dict.fromkeys(_KEYS))
    return {k: v for k, v in opts.items() if v is not None}, overrides


def _episode(env, agent, seed: int, args: dict[str, str]) -> str:
    from mjnav.eval.plots import plot_episode
    from mjnav.eval.runner import run_episode

    metrics, _, trace = run_episode(env, agent, seed)
    title = f"{env.config.name} · {agent.name} · seed {seed} · {metrics.outcome} in {metrics.time_s:.1f} s"
    out = plot_episode(trace.positions, trace.pedestrians, env.task.layout, env.config.arena.size,
                       args.get("out", "episode.png"), env.config.timing.control_period, title=title)
    return f"{out}: {metrics.outcome}, {metrics.time_s:.1f} s, {metrics.distance_m:.2f} m"


def main(argv: list[str]) -> int:
    """Dispatch to ``episode`` or ``curve``."""
    if not argv or argv[0] not in ("episode", "curve"):
        print(__doc__, file=sys.stderr)
        return 2
    try:
        args, overrides = _parse(argv[1:])
    except ValueError as err:
        print(f"error: {err}", file=sys.stderr)
        return 2
    if argv[0] == "episode":
        from mjnav.eval.runner import episode_setup

        try:
            loaded = episode_setup(args, overrides)
        except (ValueError, FileNotFoundError) as err:
            print(f"error: {err}", file=sys.stderr)
            return 2
        print(_episode(*loaded, args))
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
