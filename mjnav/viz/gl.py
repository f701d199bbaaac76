"""Pick an off-screen OpenGL backend for MuJoCo rendering (no MuJoCo import here).

Order: ``MUJOCO_GL`` if set, else ``egl`` then ``osmesa``. Each candidate is probed in a
subprocess (a failed EGL initialisation would pin PyOpenGL's platform in this process), and the
winner is exported as ``MUJOCO_GL`` / ``PYOPENGL_PLATFORM`` when MuJoCo and PyOpenGL are not
imported yet. System packages (Debian/Ubuntu):

* EGL: ``libegl1`` + ``libgl1-mesa-dri`` (Mesa's software/GPU drivers) or an NVIDIA driver;
* OSMesa: ``libosmesa6`` (software only, slower).

Call :func:`select_gl_backend` before importing ``mujoco``/``dm_control`` where possible; the
renderer (:mod:`mjnav.viz.scene`) creates its context explicitly, so it also works when MuJoCo
was imported first.
"""

from __future__ import annotations

import functools
import os
import subprocess
import sys
from collections.abc import Sequence

__all__ = ["GlBackendError", "probe_gl_backend", "select_gl_backend"]

_HEADLESS = ("egl", "osmesa")
_PROBE = (
    "import sys\n"
    "b = sys.argv[1]\n"
    "mod = __import__('mujoco.' + b, fromlist=['GLContext'])\n"
    "ctx = mod.GLContext(16, 16)\n"
    "ctx.make_current()\n"
    "import mujoco\n"
    "m = mujoco.MjModel.from_xml_string('<mujoco><worldbody><geom size=\"1\"/></worldbody></mujoco>')\n"
    "con = mujoco.MjrContext(m, mujoco.mjtFontScale.mjFONTSCALE_100)\n"
    "con.free()\n"
    "ctx.free()\n"
    "print('ok')\n"
)


class GlBackendError(RuntimeError):
    """No off-screen OpenGL backend works on this machine (the message says what to install)."""


@functools.cache
def probe_gl_backend(backend: str, timeout: float = 60.0) -> bool:
    """Whether MuJoCo can open an off-screen context with ``backend`` (``egl`` or ``osmesa``)."""
    if backend not in _HEADLESS:
        return False
    env = {k: v for k, v in os.environ.items() if k not in ("PYOPENGL_PLATFORM", "MUJOCO_GL")}
    env["MUJOCO_GL"] = backend
    try:
        out = subprocess.run([sys.executable, "-c", _PROBE, backend], env=env, capture_output=True, text=True,
                             timeout=timeout, check=False)
    except (OSError, subprocess.SubprocessError):
        return False
    return out.returncode == 0 and "ok" in out.stdout


def select_gl_backend(candidates: Sequence[str] | None = None) -> str:
    """The first working headless backend; exported to the environment when still possible.

    Args:
        candidates: Backends to try in order; default ``MUJOCO_GL`` if set, else egl, osmesa.

    Returns:
        ``egl`` or ``osmesa``.

    Raises:
        GlBackendError: None works (names the Debian packages that provide them).
    """
    preset = os.environ.get("MUJOCO_GL", "").lower().strip()
    if os.environ.get("MJNAV_GL_DEFAULTED") == "1":
        preset = ""  # set by ``import mjnav`` as a default, not by the user: try every backend
    order = list(candidates) if candidates else ([preset] if preset in _HEADLESS else list(_HEADLESS))
    for backend in order:
        if probe_gl_backend(backend):
            if "mujoco" not in sys.modules and "OpenGL" not in sys.modules:
                os.environ["MUJOCO_GL"] = backend
                os.environ["PYOPENGL_PLATFORM"] = backend
            return backend
    raise GlBackendError(
        f"no off-screen OpenGL backend works (tried {', '.join(order)}). Install EGL "
        "(`apt-get install libegl1 libgl1-mesa-dri`, or an NVIDIA driver) or OSMesa "
        "(`apt-get install libosmesa6`), or set MUJOCO_GL to a working backend."
    )
