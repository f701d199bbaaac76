"""Rendering one episode of an agent to MP4, with the action layer drawn into the scene.

Nothing here is imported by the environments: training and evaluation create no renderer. The
drawing itself (views, cameras, overlays, captions) is :mod:`mjnav.viz.scene`; this module runs the
agent and writes one frame per control step with :func:`mediapy.write_video` (imageio-ffmpeg's
binary).
"""

from __future__ import annotations

from pathlib import Path
from typing import TYPE_CHECKING, Any

import imageio_ffmpeg
import mediapy
import numpy as np

from mjnav.viz.gl import select_gl_backend
from mjnav.viz.scene import Captioner, OffscreenView, RenderConfig, camera_ids, render_frame

__all__ = ["RenderConfig", "render_episode"]

if TYPE_CHECKING:
    from mjnav.envs.gym_env import NavGymEnv
    from mjnav.eval.policies import Agent


def render_episode(
    env: NavGymEnv, agent: Agent, seed: int, out: str | Path, config: RenderConfig | None = None
) -> dict[str, Any]:
    """Run and render one episode to an MP4 (one frame per control step, 1/t_c fps).

    Args:
        env: A :class:`mjnav.envs.gym_env.NavGymEnv`, possibly wrapped (steps go through the wrappers).
        agent: A loaded :class:`mjnav.eval.policies.Agent`.
        seed: Episode seed.
        out: Output ``.mp4`` path.
        config: View, size, frame limit, rays.

    Returns:
        ``{"path", "frames", "outcome", "backend"}``.

    Raises:
        mjnav.viz.gl.GlBackendError: No off-screen GL backend works.
    """
    cfg = config or RenderConfig()
    backend = select_gl_backend()
    base = env.unwrapped
    agent.begin(base.task, seed)
    obs, _ = env.reset(options={"episode_seed": seed})
    cams = camera_ids(base.task, base.physics, cfg.view)
    views = [OffscreenView(base.physics.model.ptr, cfg.width, cfg.height, backend) for _ in cams]
    captioner = Captioner(cfg.width * len(cams))
    frames, outcome, done = [], "running", False
    try:
        frames.append(render_frame(base.task, base.physics, views, cams, captioner, cfg.rays, outcome))
        while not done and (cfg.max_frames is None or len(frames) < cfg.max_frames):
            obs, _, terminated, truncated, info = env.step(agent.act(obs))
            done, outcome = terminated or truncated, info["outcome"]
            frames.append(render_frame(base.task, base.physics, views, cams, captioner, cfg.rays, outcome))
    finally:
        for view in views:
            view.close()
    mediapy.set_ffmpeg(imageio_ffmpeg.get_ffmpeg_exe())
    fps = round(1.0 / base.task.config.timing.control_period)
    Path(out).parent.mkdir(parents=True, exist_ok=True)
    mediapy.write_video(str(out), np.stack(frames), fps=fps)
    return {"path": str(out), "frames": len(frames), "outcome": outcome, "backend": backend}
