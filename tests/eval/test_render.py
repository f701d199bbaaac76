"""Off-screen rendering: a 10-frame episode becomes a playable MP4 of the right size."""

from __future__ import annotations

import numpy as np
import pytest

from mjnav.viz.gl import probe_gl_backend

BACKEND = next((b for b in ("egl", "osmesa") if probe_gl_backend(b)), None)
needs_gl = pytest.mark.skipif(
    BACKEND is None, reason="no off-screen GL backend (needs libegl1 + libgl1-mesa-dri, or libosmesa6)"
)


def _read_video(path) -> tuple[np.ndarray, float]:
    """Frames and fps via mediapy; imageio-ffmpeg's reader when mediapy's ffmpeg call is unsupported."""
    import imageio_ffmpeg
    import mediapy

    mediapy.set_ffmpeg(imageio_ffmpeg.get_ffmpeg_exe())
    try:
        video = mediapy.read_video(str(path))
        return np.asarray(video), float(video.metadata.fps)
    except RuntimeError:  # mediapy passes -vsync, which ffmpeg >= 7 removed
        reader = imageio_ffmpeg.read_frames(str(path))
        meta = next(reader)
        w, h = meta["size"]
        return np.stack([np.frombuffer(f, np.uint8).reshape(h, w, 3) for f in reader]), float(meta["fps"])


@needs_gl
def test_ten_frame_render(tmp_path):
    """view=both at 160×128 per view: 10 frames of 128×320 at 10 fps, with visible content."""
    from mjnav.envs.gym_env import NavGymEnv
    from mjnav.eval.policies import load_policy
    from mjnav.eval.render import RenderConfig, render_episode

    env = NavGymEnv("stage5", seed=0)
    out = tmp_path / "episode.mp4"
    result = render_episode(env, load_policy("mpc_goal"), 4294967296 + 1, out,
                            RenderConfig(view="both", width=160, height=128, max_frames=10, rays=True))
    assert result["frames"] == 10 and out.stat().st_size > 0
    frames, fps = _read_video(out)
    assert frames.shape == (10, 128, 320, 3)
    assert fps == pytest.approx(10.0)
    assert frames.std() > 5.0  # not a blank image
    env.close()


@pytest.mark.parametrize(
    ("kwargs", "match"),
    [({"view": "sideways"}, "view"), ({"width": 0}, "640 x 480"), ({"height": 481}, "640 x 480"),
     ({"max_frames": 0}, "frames")],
)
def test_render_config_rejects_bad_values(kwargs, match):
    """Bad views, sizes and frame counts fail when the config is made, before any GL context."""
    from mjnav.eval.render import RenderConfig

    with pytest.raises(ValueError, match=match):
        RenderConfig(**kwargs)


@needs_gl
def test_an_unclosed_rendering_environment_exits_quietly():
    """A script that renders and never calls close() exits with status 0 and no GL traceback
    (MuJoCo's exit hook used to terminate the EGL display before the context was freed)."""
    import subprocess
    import sys

    script = (
        "import gymnasium as gym, numpy as np, mjnav\n"
        "env = gym.make('mjnav/Stage5-v1', render_mode='rgb_array', render_size=(64, 64), render_overlays=True)\n"
        "env.reset(seed=0); env.step(np.zeros(4)); assert env.render().shape == (64, 64, 3)\n"
    )
    done = subprocess.run([sys.executable, "-c", script], capture_output=True, text=True, timeout=120,
                          env={**__import__("os").environ, "MUJOCO_GL": BACKEND})
    assert done.returncode == 0, done.stderr
    assert "Traceback" not in done.stderr and "Error" not in done.stderr, done.stderr
