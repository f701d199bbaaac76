"""The tested lower bounds (``.ci/lower-bounds.txt``) are exactly the floors ``pyproject.toml`` declares."""

from __future__ import annotations

import re
import tomllib
from pathlib import Path

from packaging.version import Version

ROOT = Path(__file__).resolve().parents[1]


def _name(requirement: str) -> str:
    return re.split(r"[<>=!~\[; ]", requirement, maxsplit=1)[0].lower().replace("_", "-")


def test_every_declared_floor_is_the_version_the_lower_bound_check_pins() -> None:
    """Each runtime dependency's ``>=`` floor (or ``==`` pin) appears, as ``==``, in the lower-bounds file."""
    project = tomllib.loads((ROOT / "pyproject.toml").read_text())["project"]
    floors = {}
    for requirement in project["dependencies"]:
        found = re.search(r"(>=|==)\s*([0-9][^,;\s]*)", requirement)
        assert found, f"{requirement!r} declares no lower bound"
        floors[_name(requirement)] = Version(found.group(2))
    pins = {}
    for line in (ROOT / ".ci" / "lower-bounds.txt").read_text().splitlines():
        if line.strip() and not line.startswith("#"):
            name, version = line.split("==")
            pins[_name(name)] = Version(version)
    assert pins == floors
