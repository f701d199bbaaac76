"""Command-line entry points: ``mjnav-train``, ``mjnav-evaluate``, ``mjnav-render``, ``mjnav-export``
(console scripts of the installed package), ``python -m mjnav.train`` and the ``scripts/`` files,
which only call these.

Every command takes ``key=value`` arguments (see each function), prints one ``error: ...`` line
on bad input and returns exit code 2 for it, 0 on success.
"""

from __future__ import annotations

import sys
from collections.abc import Sequence

from mjnav.schema import ConfigError

__all__ = ["evaluate", "export", "render", "train"]


def _args(argv: Sequence[str] | None) -> list[str]:
    return list(sys.argv[1:] if argv is None else argv)


def _error(err: Exception) -> int:
    print(f"error: {err}", file=sys.stderr)
    return 2


def train(argv: Sequence[str] | None = None) -> int:
    """Train a policy with PPO (:mod:`mjnav.train.session`: ``task=stage6 [start=...] [train.KEY=VALUE] ...``)."""
    from mjnav.train.session import run

    try:
        run(_args(argv))
    except ConfigError as err:
        return _error(err)
    return 0


def evaluate(argv: Sequence[str] | None = None) -> int:
    """Evaluate a policy on held-out scenarios (:func:`mjnav.eval.runner.main`)."""
    from mjnav.eval.runner import main

    return main(_args(argv))


def render(argv: Sequence[str] | None = None) -> int:
    """Render one episode to MP4 with the action layer drawn in.

    ``task=stage6 policy=PATH_OR_NAME [seed=0 | episode_seed=K] [out=episode.mp4] [view=top|track|both]
    [width=480] [height=480] [frames=N] [rays=false] [task.KEY=VALUE ...]``; ``seed`` is the held-out
    scenario index (as for evaluation). The GL backend is EGL, else OSMesa (``MUJOCO_GL`` overrides).
    """
    from mjnav.eval.gl import GlBackendError, select_gl_backend
    from mjnav.schema import split_args

    keys = ("task", "policy", "seed", "episode_seed", "out", "view", "width", "height", "frames", "rays")
    try:
        opts, overrides = split_args(_args(argv), dict.fromkeys(keys))
        args = {k: v for k, v in opts.items() if v is not None}
        select_gl_backend()  # before MuJoCo is imported
    except (ValueError, GlBackendError) as err:
        return _error(err)
    from mjnav.eval.render import RenderConfig, render_episode
    from mjnav.eval.runner import episode_setup

    try:  # bad task, override, policy or value: one line, before anything is rendered
        env, agent, seed = episode_setup(args, overrides)
        frames = int(args["frames"]) if "frames" in args else None
        config = RenderConfig(args.get("view", "top"), int(args.get("width", 480)), int(args.get("height", 480)),
                              frames, str(args.get("rays", False)).lower() in ("1", "true", "yes"))
    except (ValueError, FileNotFoundError) as err:
        return _error(err)
    result = render_episode(env, agent, seed, args.get("out", "episode.mp4"), config)
    print(f"{result['path']}: {result['frames']} frames, outcome {result['outcome']} ({result['backend']})")
    return 0


def export(argv: Sequence[str] | None = None) -> int:
    """Export one episode as a standalone MuJoCo scene plus pedestrian trajectories.

    ``task=stage6 seed=7 out=DIR [steps=300] [task.crowd.count=25 ...]`` (the ``task.`` prefix of
    overrides is optional here); writes ``DIR/scene.xml`` and ``DIR/trajectory.npz`` (export page of the docs).
    """
    from mjnav.config import load_task
    from mjnav.export import export_world

    own, overrides = {"task": "stage6", "seed": "0", "out": "out/export", "steps": "300"}, []
    try:
        for arg in _args(argv):
            key, sep, value = arg.partition("=")
            if not sep:
                raise ConfigError(f"argument {arg!r}: expected key=value")
            if key in own:
                own[key] = value
            else:
                overrides.append(arg.removeprefix("task."))
        config = load_task(own["task"], overrides)
        seed, steps = _integer(own, "seed"), _integer(own, "steps")
        scene = export_world(config, seed, own["out"], steps=steps)
    except (ConfigError, ValueError) as err:
        return _error(err)
    print(f"wrote {scene} and {scene.parent / 'trajectory.npz'}")
    return 0


def _integer(own: dict[str, str], key: str) -> int:
    try:
        return int(own[key])
    except ValueError:
        raise ConfigError(f"{key}: expected an integer, got {own[key]!r}") from None
