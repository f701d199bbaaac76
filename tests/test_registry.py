"""The one registry shape: registration, lookup errors, config classes and entry points."""

from __future__ import annotations

import dataclasses
import importlib
import sys

import pytest

from mjnav.registry import Registry, RegistryError


@dataclasses.dataclass
class _Cfg:
    gain: float = 1.0


class _Thing:
    config_class = _Cfg

    def __init__(self, config: _Cfg) -> None:
        self.config = config


def test_register_make_and_config_defaults():
    reg: Registry[_Thing] = Registry("widget")
    reg.register("thing", _Thing)
    assert reg.get("thing").config_class is _Cfg
    assert reg.make("thing").config.gain == 1.0
    assert reg.make("thing", _Cfg(gain=2.0)).config.gain == 2.0
    assert "thing" in reg and reg.names() == ["thing"]


def test_decorator_and_plain_factory():
    reg: Registry[int] = Registry("number")

    @reg.register("seven")
    def seven() -> int:
        return 7

    assert reg.make("seven") == 7
    with pytest.raises(RegistryError, match="takes no parameters"):
        reg.make("seven", _Cfg())


def test_unknown_name_lists_known_and_closest():
    reg = Registry("planner")
    reg.register("mpc_goal", object)
    reg.register("teb", object)
    with pytest.raises(RegistryError, match=r"unknown planner 'mpc_gaol' \(known: mpc_goal, teb; closest: mpc_goal\)"):
        reg.get("mpc_gaol")


def test_clash_needs_replace_and_bad_names_are_refused():
    reg = Registry("planner")
    reg.register("a", object)
    with pytest.raises(RegistryError, match="already registered"):
        reg.register("a", dict)
    reg.register("a", dict, replace=True)
    assert reg.get("a").factory is dict
    for bad in ("", "a b", "x=y", "m:C"):
        with pytest.raises(RegistryError):
            reg.register(bad, object)


def test_entry_points_of_an_installed_package(tmp_path, monkeypatch):
    pkg = tmp_path / "outside_pkg.py"
    pkg.write_text("class Outside:\n    config_class = None\n    def __init__(self):\n        self.ok = True\n")
    dist = tmp_path / "outside_pkg-1.0.dist-info"
    dist.mkdir()
    (dist / "METADATA").write_text("Metadata-Version: 2.1\nName: outside-pkg\nVersion: 1.0\n")
    (dist / "entry_points.txt").write_text("[mjnav.test_things]\noutside = outside_pkg:Outside\n")
    monkeypatch.syspath_prepend(str(tmp_path))
    importlib.invalidate_caches()
    reg = Registry("thing", group="mjnav.test_things")
    reg.register("builtin", object, source="builtin")
    assert reg.names() == ["builtin", "outside"]
    entry = reg.get("outside")
    assert entry.source == "entry point outside-pkg" and reg.make("outside").ok
    sys.modules.pop("outside_pkg", None)


def test_broken_entry_point_names_itself(tmp_path, monkeypatch):
    dist = tmp_path / "broken-1.0.dist-info"
    dist.mkdir()
    (dist / "METADATA").write_text("Metadata-Version: 2.1\nName: broken\nVersion: 1.0\n")
    (dist / "entry_points.txt").write_text("[mjnav.test_broken]\nbad = no_such_module_xyz:Thing\n")
    monkeypatch.syspath_prepend(str(tmp_path))
    importlib.invalidate_caches()
    reg = Registry("thing", group="mjnav.test_broken")
    with pytest.raises(RegistryError, match="'bad' from entry point 'no_such_module_xyz:Thing'.*failed to load"):
        reg.get("bad")
