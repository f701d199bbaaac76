"""Where mjnav's data folders are: ``tasks/``, ``assets/`` and ``policies/``.

In a source checkout (and an editable install) they sit at the top of the repository, next to
the ``mjnav`` package. A wheel carries them inside the package as ``mjnav/_data/<folder>``
(``pyproject.toml`` maps them there), so an installed mjnav finds them without the checkout.
The installed copy wins when both exist.

``MJNAV_TASKS_DIR`` (a folder of stage YAML files) replaces ``tasks/``: tests and users add a
stage without touching the package (``tasks/stage8.yaml`` in that folder is ``task=stage8``).

This module is a bottom layer: it imports nothing from mjnav.
"""

from __future__ import annotations

import os
from pathlib import Path

__all__ = ["FOLDERS", "TASKS_ENV", "asset", "assets_dir", "data_dir", "policies_dir", "recipes_dir", "tasks_dir"]

#: The data folders, by name.
FOLDERS = ("tasks", "assets", "policies")
#: Environment variable that replaces the tasks folder (a path).
TASKS_ENV = "MJNAV_TASKS_DIR"
_PACKAGE = Path(__file__).resolve().parent


def data_dir(folder: str) -> Path:
    """The folder ``tasks``, ``assets`` or ``policies``: installed (``mjnav/_data/``) or in the checkout.

    Raises:
        ValueError: ``folder`` is not one of :data:`FOLDERS`.
        FileNotFoundError: Neither location exists (a broken install).
    """
    if folder not in FOLDERS:
        raise ValueError(f"data folder {folder!r}: expected one of {', '.join(FOLDERS)}")
    for candidate in (_PACKAGE / "_data" / folder, _PACKAGE.parent / folder):
        if candidate.is_dir():
            return candidate
    raise FileNotFoundError(f"mjnav's {folder}/ folder is neither in {_PACKAGE / '_data'} (installed) nor in "
                            f"{_PACKAGE.parent} (checkout): reinstall mjnav")


def tasks_dir() -> Path:
    """The stage YAML folder: ``$MJNAV_TASKS_DIR`` if set, else :func:`data_dir` ``("tasks")``.

    Raises:
        FileNotFoundError: ``$MJNAV_TASKS_DIR`` names no folder.
    """
    override = os.environ.get(TASKS_ENV)
    if override:
        path = Path(override)
        if not path.is_dir():
            raise FileNotFoundError(f"${TASKS_ENV}={override!r} is not a folder")
        return path
    return data_dir("tasks")


def recipes_dir() -> Path:
    """The recipes of the shipped policies (``tasks/recipes``; never replaced by ``$MJNAV_TASKS_DIR``)."""
    return data_dir("tasks") / "recipes"


def assets_dir() -> Path:
    """The MJCF folder (``robot.xml``, ``pedestrian.xml``)."""
    return data_dir("assets")


def asset(name: str) -> Path:
    """The path of one asset file (``asset("robot.xml")``).

    Raises:
        FileNotFoundError: No such asset.
    """
    path = assets_dir() / name
    if not path.is_file():
        known = ", ".join(sorted(p.name for p in assets_dir().iterdir()))
        raise FileNotFoundError(f"asset {name!r} not in {assets_dir()} (known: {known})")
    return path


def policies_dir() -> Path:
    """The shipped policy folder (``manifest.yaml`` and the policy files)."""
    return data_dir("policies")
