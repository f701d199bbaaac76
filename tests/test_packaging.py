"""Packaging: the tested lower bounds (``.ci/lower-bounds.txt``) are the floors ``pyproject.toml``
declares, and the wheel carries the data folders."""

from __future__ import annotations

import tomllib
from pathlib import Path

import pytest
import yaml
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


def test_the_wheel_carries_tasks_assets_and_policies(tmp_path: Path) -> None:
    """The built wheel holds every stage, recipe, asset and manifest file under mjnav/_data/ (where
    mjnav.resources looks in an install), and no stray top-level packages."""
    import subprocess
    import sys
    import zipfile

    pytest.importorskip("setuptools", minversion="68")
    subprocess.run([sys.executable, "-m", "pip", "wheel", "--no-deps", "--no-build-isolation", "-q", "-w",
                    str(tmp_path), str(ROOT)], check=True, capture_output=True)
    (wheel,) = tmp_path.glob("mjnav-*.whl")
    names = set(zipfile.ZipFile(wheel).namelist())
    manifest = yaml.safe_load((ROOT / "policies" / "manifest.yaml").read_text())["policies"]
    shipped = {f"policies/{e[key]}" for e in manifest.values() for key in ("file", "weights") if e.get(key)}
    wanted = {str(p.relative_to(ROOT)) for folder in ("tasks", "assets") for p in (ROOT / folder).rglob("*.*")}
    assert {f"mjnav/_data/{name}" for name in wanted | shipped | {"policies/manifest.yaml"}} <= names
    assert {name.split("/")[0] for name in names if not name.startswith("mjnav")} <= {"mjnav-0.1.0.dist-info"}
