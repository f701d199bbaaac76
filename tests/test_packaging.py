"""The tested lower bounds (``.ci/lower-bounds.txt``) are exactly the floors ``pyproject.toml`` declares."""

from __future__ import annotations

import tomllib
from pathlib import Path

from packaging.requirements import Requirement
from packaging.utils import canonicalize_name
from packaging.version import Version

ROOT = Path(__file__).resolve().parents[1]


def _floor(requirement: Requirement) -> Version:
    """The version a ``>=`` (or ``==``) specifier of ``requirement`` starts at."""
    floors = [Version(s.version) for s in requirement.specifier if s.operator in (">=", "==")]
    assert len(floors) == 1, f"{requirement} declares no single lower bound"
    return floors[0]


def test_every_declared_floor_is_the_version_the_lower_bound_check_pins() -> None:
    """Each runtime dependency's ``>=`` floor (or ``==`` pin) appears, as ``==``, in the lower-bounds file."""
    declared = map(Requirement, tomllib.loads((ROOT / "pyproject.toml").read_text())["project"]["dependencies"])
    floors = {canonicalize_name(r.name): _floor(r) for r in declared}
    lines = (ROOT / ".ci" / "lower-bounds.txt").read_text().splitlines()
    pinned = (Requirement(line) for line in lines if line.strip() and not line.startswith("#"))
    assert {canonicalize_name(r.name): _floor(r) for r in pinned} == floors
