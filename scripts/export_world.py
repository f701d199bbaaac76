"""Export one episode as a standalone MuJoCo scene plus pedestrian trajectories.

Usage::

    python scripts/export_world.py task=stage6 seed=7 out=DIR [steps=300] [task.crowd.count=25 ...]

``task``, ``seed``, ``out`` and ``steps`` are the script's own keys; every other ``key=value`` is a
dotted config override validated by :func:`mjnav.config.load_task` (unknown keys fail). The
``task.`` prefix the other scripts use is optional here (``crowd.count=25`` works too). Writes
``DIR/scene.xml`` and ``DIR/trajectory.npz`` (format: ``docs/export.md``).
"""

from __future__ import annotations

import sys

from mjnav.cli import export as main

if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
