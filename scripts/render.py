"""Render one episode off-screen to MP4 with the action layer drawn in.

    python scripts/render.py task=stage6 policy=PATH_OR_NAME [seed=0] [out=episode.mp4]
                             [view=top|track|both] [width=480] [height=480] [frames=N] [rays=false]
                             [task.KEY=VALUE ...]

``seed`` is the held-out scenario index (episode seed 2**32 + seed, as scripts/evaluate.py);
``episode_seed=K`` selects a raw episode seed instead. The GL backend is EGL, else OSMesa
(``MUJOCO_GL`` overrides; EGL needs libegl1 + libgl1-mesa-dri, OSMesa libosmesa6).
"""

from __future__ import annotations

import sys

from mjnav.eval.gl import GlBackendError, select_gl_backend
from mjnav.schema import split_args

_KEYS = ("task", "policy", "seed", "episode_seed", "out", "view", "width", "height", "frames", "rays")


def _parse(argv: list[str]) -> tuple[dict, list[str]]:
    opts, overrides = split_args(argv, dict.fromkeys(_KEYS))
    return {k: v for k, v in opts.items() if v is not None}, overrides


def main(argv: list[str]) -> int:
    """Render and print where the video went."""
    try:
        args, overrides = _parse(argv)
        select_gl_backend()  # before MuJoCo is imported
    except (ValueError, GlBackendError) as err:
        print(f"error: {err}", file=sys.stderr)
        return 2
    from mjnav.eval.render import RenderConfig, render_episode
    from mjnav.eval.runner import episode_setup

    try:  # bad task, override, policy or value: one line, before anything is rendered
        env, agent, seed = episode_setup(args, overrides)
        frames = int(args["frames"]) if "frames" in args else None
        config = RenderConfig(args.get("view", "top"), int(args.get("width", 480)), int(args.get("height", 480)),
                              frames, str(args.get("rays", False)).lower() in ("1", "true", "yes"))
    except (ValueError, FileNotFoundError) as err:
        print(f"error: {err}", file=sys.stderr)
        return 2
    result = render_episode(env, agent, seed, args.get("out", "episode.mp4"), config)
    print(f"{result['path']}: {result['frames']} frames, outcome {result['outcome']} ({result['backend']})")
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
