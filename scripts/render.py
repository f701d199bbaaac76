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

from mjnav.cli import render as main

if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
