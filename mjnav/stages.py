"""The stage registry (entry-point group ``mjnav.stages``): stage ids come from the YAML files.

Every ``tasks/<name>.yaml`` (or ``$MJNAV_TASKS_DIR/<name>.yaml``, :mod:`mjnav.resources`) is a
stage: ``task=<name>`` loads it, ``import mjnav`` registers the Gymnasium id of every
``stage<N>`` file (``mjnav/Stage8-v1`` for ``stage8.yaml``) and the curriculum walks the
``stage<N>`` numbers in order. Adding ``tasks/stage8.yaml`` needs no code change.

Outside packages add stages through entry points of the group ``mjnav.stages``: the entry point
names a callable ``make(overrides: list[str] | None) -> TaskConfig``. A file wins over an entry
point of the same name.

This module is light on purpose (``import mjnav`` reads it to register the Gymnasium ids): it
reads file names only and imports :mod:`mjnav.config` when a stage is built.
"""

from __future__ import annotations

import re
from collections.abc import Callable
from pathlib import Path
from typing import Any

from mjnav.registry import Registry, RegistryError
from mjnav.resources import tasks_dir

__all__ = ["STAGES", "env_id", "load_stage", "next_stage", "stage_files", "stage_name", "stage_names",
           "stage_numbers"]

#: Every stage, by name; :func:`stage_names` refreshes it from the tasks folder.
STAGES: Registry[Any] = Registry("stage", group="mjnav.stages")
_NUMBERED = re.compile(r"stage([1-9]\d*)")
_FROM_FILES: dict[str, Path] = {}  # the registry's entries that came from files, by name


def stage_files() -> dict[str, Path]:
    """``{name: path}`` of the YAML files in the tasks folder, by name."""
    return {path.stem: path for path in sorted(tasks_dir().glob("*.yaml"))}


def _file_factory(path: Path) -> Callable[..., Any]:
    """``make(overrides) -> TaskConfig`` of one YAML file."""
    def make(overrides: list[str] | dict[str, Any] | None = None) -> Any:
        # deferred: mjnav.config pulls in the MPC and region modules (~0.3 s: numba, scipy, osqp), which
        # `import mjnav` (it registers the Gymnasium ids from this module) must not pay
        from mjnav.config import load_task

        return load_task(path, overrides)

    make.__doc__ = f"The stage of {path} with dotted overrides."
    return make


def _sync() -> None:
    """Make the registry's file entries those of the tasks folder now (it may have changed)."""
    files = stage_files()
    for name in [n for n, p in _FROM_FILES.items() if files.get(n) != p]:
        STAGES.unregister(name)
        del _FROM_FILES[name]
    for name, path in files.items():
        if name not in _FROM_FILES:
            STAGES.register(name, _file_factory(path), source=f"file {path}", replace=True)
            _FROM_FILES[name] = path


def stage_names() -> list[str]:
    """Every stage name: the tasks folder's files and the entry points', sorted."""
    _sync()
    return STAGES.names()


def stage_numbers() -> list[int]:
    """The ``N`` of every ``stage<N>`` stage, ascending (the curriculum's stage list)."""
    return sorted(int(m.group(1)) for name in stage_names() if (m := _NUMBERED.fullmatch(name)))


def stage_name(number: int) -> str:
    """The stage of number ``number`` (``3`` -> ``stage3``).

    Raises:
        RegistryError: No such stage; the message lists the known ones.
    """
    name = f"stage{number}"
    if number not in stage_numbers():
        raise RegistryError(STAGES.unknown_message(name))
    return name


def next_stage(number: int) -> int | None:
    """The stage number after ``number`` in :func:`stage_numbers`, or None after the last."""
    return next((n for n in stage_numbers() if n > number), None)


def env_id(name: str) -> str:
    """The Gymnasium id of a stage (``stage8`` -> ``mjnav/Stage8-v1``)."""
    return f"mjnav/{name[:1].upper()}{name[1:]}-v1"


def load_stage(name: str, overrides: list[str] | dict[str, Any] | None = None) -> Any:
    """The :class:`mjnav.config.TaskConfig` of stage ``name`` with dotted overrides.

    Raises:
        RegistryError: Unknown stage (known names and the closest in the message).
    """
    _sync()
    return STAGES.get(name).factory(overrides)
