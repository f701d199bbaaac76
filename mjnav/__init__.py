"""mjnav: MuJoCo crowd-navigation scenarios and learning-based convex MPC.

``import mjnav`` registers the Gymnasium ids ``mjnav/Stage<N>-v1``, one per ``tasks/stage<N>.yaml``;
``mjnav.make_env("stage6", seed=0)`` returns the dm_control composer environment.
"""

from __future__ import annotations

import os
from typing import Any

if not os.environ.get("DISPLAY") and "MUJOCO_GL" not in os.environ:
    # Headless by default: without this dm_control tries GLFW first and warns on every import.
    # EGL (Debian libegl1 + libgl1-mesa-dri) is the off-screen backend; mjnav.viz.gl still falls
    # back to OSMesa for rendering because the marker says the choice was not the user's.
    os.environ["MUJOCO_GL"] = "egl"
    os.environ["MJNAV_GL_DEFAULTED"] = "1"

from mjnav.envs.registration import ENV_IDS, register_envs

__version__ = "0.1.0"
__all__ = ["ENV_IDS", "load_task", "make_env", "make_gym_env"]

register_envs()


def __getattr__(name: str) -> Any:
    """Import the heavy entry points only when used: ``import mjnav`` takes ~0.5 s, the environment
    stack (MuJoCo, dm_control, numba kernels) ~2.3 s more (measured with ``python -X importtime``)."""
    if name == "make_env":
        from mjnav.envs.factory import make_env  # deferred: ~2.3 s (see above)

        return make_env
    if name == "make_gym_env":
        from mjnav.envs.gym_env import make_gym_env  # deferred: ~2.3 s (see above)

        return make_gym_env
    if name == "load_task":
        from mjnav.config import load_task  # deferred: ~0.3 s (numba, scipy, osqp)

        return load_task
    raise AttributeError(f"module 'mjnav' has no attribute {name!r}")
