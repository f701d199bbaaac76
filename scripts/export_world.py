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

from mjnav.config import load_task
from mjnav.export import export_world
from mjnav.schema import ConfigError

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
            overrides.append(arg.removeprefix("task."))
    config = load_task(own["task"], overrides)
    seed, steps = _integer(own, "seed"), _integer(own, "steps")
    scene = export_world(config, seed, own["out"], steps=steps)
    print(f"wrote {scene} and {scene.parent / 'trajectory.npz'}")



def _integer(own: dict[str, str], key: str) -> int:
    try:
        return int(own[key])
    except ValueError:
        raise ConfigError(f"{key}: expected an integer, got {own[key]!r}") from None


if __name__ == "__main__":
    try:
        main(sys.argv[1:])
    except ConfigError as err:
        sys.exit(f"error: {err}")
