"""Export one episode as a standalone MuJoCo scene plus pedestrian trajectories.

Usage::

    python scripts/export_world.py task=stage6 seed=7 out=DIR [steps=300] [crowd.count=25 ...]

``task``, ``seed``, ``out`` and ``steps`` are the script's own keys; every other ``key=value`` is a
dotted config override validated by :func:`mjnav.config.load_task` (unknown keys fail). Writes
``DIR/scene.xml`` and ``DIR/trajectory.npz`` (format: ``docs/export.md``).
"""

from __future__ import annotations

import sys

from mjnav.config import load_task
from mjnav.export import export_world

_OWN = {"task": "stage6", "seed": "0", "out": "out/export", "steps": "300"}


def main(argv: list[str]) -> None:
    """Parses ``key=value`` arguments and runs the export."""
    own, overrides = dict(_OWN), []
    for arg in argv:
        key, sep, value = arg.partition("=")
        if not sep:
            raise SystemExit(f"argument {arg!r}: expected key=value")
        if key in own:
            own[key] = value
        else:
            overrides.append(arg)
    config = load_task(own["task"], overrides)
    scene = export_world(config, int(own["seed"]), own["out"], steps=int(own["steps"]))
    print(f"wrote {scene} and {scene.parent / 'trajectory.npz'}")


if __name__ == "__main__":
    main(sys.argv[1:])
