"""``mjnav render``: one episode off-screen to MP4 with the action layer drawn in."""

from __future__ import annotations

import dataclasses
import sys
from typing import Literal

from mjnav.args import Grammar, Parsed
from mjnav.config import TASK_SECTIONS
from mjnav.eval.runner import episode_setup
from mjnav.viz.gl import GlBackendError, select_gl_backend

__all__ = ["RenderOptions", "grammar", "run"]


@dataclasses.dataclass(frozen=True)
class RenderOptions:
    """The ``render`` verb's own keys.

    Attributes:
        task: Bundled stage name or task YAML path.
        policy: A run folder, policy file, shipped policy or planner (a registered name,
            ``package.module:Class`` or ``path/to/file.py:Class``).
        seed: Held-out scenario index (episode seed 2**32 + seed, as in evaluation).
        episode_seed: A raw episode seed instead of ``seed``.
        out: MP4 file to write.
        view: ``top`` (whole arena), ``track`` (following the robot) or ``both`` side by side.
        width: Frame width, pixels.
        height: Frame height, pixels.
        frames: Frames to render (default: the whole episode).
        rays: Draw the LiDAR rays.
    """

    task: str = "stage6"
    policy: str = "mpc_goal"
    seed: int = 0
    episode_seed: int | None = None
    out: str = "episode.mp4"
    view: Literal["top", "track", "both"] = "top"
    width: int = 480
    height: int = 480
    frames: int | None = None
    rays: bool = False


def grammar() -> Grammar:
    """:class:`RenderOptions`, ``task.*`` overrides and ``planner.*`` parameters. The GL backend is EGL,
    else OSMesa (``MUJOCO_GL`` overrides)."""
    return Grammar(RenderOptions, ("task", "planner"), {}, TASK_SECTIONS)


def setup_args(opts: RenderOptions | object) -> dict[str, object]:
    """The ``args`` of :func:`mjnav.eval.runner.episode_setup`: task, policy and a seed."""
    args = {"task": opts.task, "policy": opts.policy, "seed": opts.seed}
    if opts.episode_seed is not None:
        args["episode_seed"] = opts.episode_seed
    return args


def run(parsed: Parsed, argv: list[str]) -> int:
    """Render the episode and print where it went."""
    opts: RenderOptions = parsed.options
    try:
        select_gl_backend()  # before MuJoCo is imported
    except GlBackendError as err:
        return _error(err)
    # deferred: imports MuJoCo, which reads MUJOCO_GL once, so only after select_gl_backend(); also ~0.5 s
    from mjnav.eval.render import RenderConfig, render_episode

    try:  # bad task, override, policy or value: one line, before anything is rendered
        env, agent, seed = episode_setup(setup_args(opts), parsed.task, parsed.planner)
        config = RenderConfig(opts.view, opts.width, opts.height, opts.frames, opts.rays)
    except (ValueError, FileNotFoundError, KeyError) as err:  # KeyError: an unknown planner name
        return _error(err)
    result = render_episode(env, agent, seed, opts.out, config)
    print(f"{result['path']}: {result['frames']} frames, outcome {result['outcome']} ({result['backend']})")
    return 0


def _error(err: Exception) -> int:
    print(f"error: {err}", file=sys.stderr)
    return 2
