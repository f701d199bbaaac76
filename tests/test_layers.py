"""The package's imports point one way: no import circle and no import from a lower layer into a
higher one.

:data:`LAYERS` is the one declaration of the layer order, lowest first. Each layer lists mjnav
modules or packages; a module belongs to the entry that names it or its closest enclosing package
(``mjnav.tasks.design`` before ``mjnav.tasks``). A module may import modules of its own layer and
of lower layers. Every ``import`` statement counts: top-level ones, deferred ones inside functions
and ``if TYPE_CHECKING:`` ones. An import edge goes to the module named (``from mjnav.world import
crowd`` to ``mjnav.world.crowd``, ``from mjnav.world import PEDESTRIAN_MODELS`` to the package
``mjnav.world``); Python also runs each enclosing package's ``__init__`` first, which is the
package's own dependency on its contents and not counted as an edge of the importer.
"""

from __future__ import annotations

import ast
import functools
from pathlib import Path

import pytest

PACKAGE = Path(__file__).resolve().parents[1] / "mjnav"

#: The layer order, lowest first (see the module docstring).
LAYERS: list[list[str]] = [
    ["mjnav.registry", "mjnav.timing", "mjnav.resources", "mjnav.jobs"],
    ["mjnav.schema", "mjnav.args", "mjnav.shipped", "mjnav.geometry"],
    ["mjnav.control", "mjnav.perception"],
    ["mjnav.world", "mjnav.tasks", "mjnav.tasks.design", "mjnav.tasks.privileged"],
    ["mjnav.config"],
    ["mjnav.stages", "mjnav.planners", "mjnav.entities", "mjnav.sensors", "mjnav.fused"],
    ["mjnav.sim"],
    ["mjnav.tasks.core", "mjnav.tasks.nav", "mjnav.tasks.observation", "mjnav.tasks.reward"],
    ["mjnav.viz", "mjnav.envs"],
    ["mjnav.policy"],
    ["mjnav.train", "mjnav.eval"],
    ["mjnav.export", "mjnav.bench", "mjnav.verbs", "mjnav.cli", "mjnav.__main__", "mjnav.train.__main__", "mjnav"],
]


def _module_name(path: Path) -> str:
    parts = list(path.relative_to(PACKAGE.parent).with_suffix("").parts)
    return ".".join(parts[:-1] if parts[-1] == "__init__" else parts)


@functools.cache
def _modules() -> dict[str, Path]:
    return {_module_name(p): p for p in sorted(PACKAGE.rglob("*.py"))}


def _target(name: str) -> str | None:
    """The mjnav module ``name`` refers to: itself if it is one, else its closest enclosing module."""
    while name and name not in _modules():
        name = name.rpartition(".")[0]
    return name or None


@functools.cache
def _imports(module: str) -> frozenset[tuple[str, int]]:
    """``(imported mjnav module, line)`` of every import statement of ``module``, wherever it sits."""
    path = _modules()[module]
    package = module if path.name == "__init__.py" else module.rpartition(".")[0]
    found = set()
    for node in ast.walk(ast.parse(path.read_text(encoding="utf-8"))):
        names: list[str] = []
        if isinstance(node, ast.Import):
            names = [alias.name for alias in node.names]
        elif isinstance(node, ast.ImportFrom):
            base = node.module or ""
            if node.level:
                anchor = package.split(".")[: len(package.split(".")) - node.level + 1]
                base = ".".join([*anchor, *([base] if base else [])])
            names = [f"{base}.{a.name}" if f"{base}.{a.name}" in _modules() else base for a in node.names]
        for name in names:
            target = _target(name) if name.split(".")[0] == "mjnav" else None
            if target is not None and target != module:
                found.add((target, node.lineno))
    return frozenset(found)


def _layer_of(module: str) -> int:
    """Index in :data:`LAYERS` of the closest entry naming ``module`` or an enclosing package."""
    owners = {entry: i for i, layer in enumerate(LAYERS) for entry in layer}
    name = module
    while name:
        if name in owners:
            return owners[name]
        name = name.rpartition(".")[0]
    raise AssertionError(f"{module} is in no layer: add it to LAYERS in {Path(__file__).name}")


def test_every_layer_entry_names_a_module() -> None:
    """Each entry of LAYERS is an existing mjnav module or package, listed once."""
    entries = [entry for layer in LAYERS for entry in layer]
    assert len(entries) == len(set(entries))
    assert [e for e in entries if e not in _modules()] == []


@pytest.mark.parametrize("module", sorted(_modules()))
def test_no_upward_import(module: str) -> None:
    """A module imports only modules of its own layer or of lower ones."""
    layer = _layer_of(module)
    upward = sorted(f"line {line}: {target} (layer {_layer_of(target)})"
                    for target, line in _imports(module) if _layer_of(target) > layer)
    assert upward == [], f"{module} (layer {layer}) imports upwards: {upward}"


def test_no_import_circle() -> None:
    """The graph of imports between mjnav modules has no circle."""
    graph = {m: sorted({t for t, _ in _imports(m)}) for m in _modules()}
    state: dict[str, int] = {}  # 1: on the current path, 2: done

    def visit(module: str, path: list[str]) -> list[str] | None:
        state[module] = 1
        for target in graph[module]:
            if state.get(target) == 1:
                return [*path[path.index(target):], target] if target in path else [*path, target]
            if target not in state and (circle := visit(target, [*path, target])):
                return circle
        state[module] = 2
        return None

    for module in graph:
        if module not in state and (circle := visit(module, [module])):
            pytest.fail("import circle: " + " -> ".join(circle))


def test_walker_sees_deferred_and_type_checking_imports() -> None:
    """The walker counts imports inside functions and under TYPE_CHECKING (its own check)."""
    imports = {t for t, _ in _imports("mjnav.planners.random")}
    assert "mjnav.config" in imports  # under TYPE_CHECKING
    assert "mjnav.control.dynamics" in imports
