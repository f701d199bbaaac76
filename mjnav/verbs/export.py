"""``mjnav export``: one episode as a standalone MuJoCo scene plus pedestrian trajectories
(``DIR/scene.xml`` and ``DIR/trajectory.npz``, format on the export page of the documentation)."""

from __future__ import annotations

import dataclasses
import sys

from mjnav.args import Grammar, Parsed
from mjnav.config import TASK_SECTIONS, load_task
from mjnav.schema import ConfigError

__all__ = ["ExportOptions", "grammar", "run"]


@dataclasses.dataclass(frozen=True)
class ExportOptions:
    """The ``export`` verb's own keys.

    Attributes:
        task: Bundled stage name or task YAML path.
        seed: Episode seed of the exported layout.
        out: Output folder.
        steps: Control steps of pedestrian trajectory to record.
    """

    task: str = "stage6"
    seed: int = 0
    out: str = "out/export"
    steps: int = 300


def grammar() -> Grammar:
    """:class:`ExportOptions` and ``task.*`` overrides."""
    return Grammar(ExportOptions, ("task",), {}, TASK_SECTIONS)


def run(parsed: Parsed, argv: list[str]) -> int:
    """Export and print the two files written."""
    # deferred: mjnav.export ~0.2 s after mjnav.config (MuJoCo, dm_control), not needed by `mjnav export --help`
    from mjnav.export import export_world

    opts: ExportOptions = parsed.options
    try:
        config = load_task(opts.task, list(parsed.task))
        scene = export_world(config, opts.seed, opts.out, steps=opts.steps)
    except (ConfigError, ValueError) as err:
        print(f"error: {err}", file=sys.stderr)
        return 2
    print(f"wrote {scene} and {scene.parent / 'trajectory.npz'}")
    return 0
