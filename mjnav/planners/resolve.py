"""One resolver for every way of naming a planner: ``policy=<spec>``.

A planner spec is one of:

* a registered name (:data:`mjnav.planners.PLANNERS`: the built-ins, ``register`` calls and the
  entry-point group ``mjnav.planners`` of installed packages), e.g. ``teb``;
* ``package.module:Class``: imported with :func:`importlib.import_module`;
* ``path/to/file.py:Class``: the file is loaded as a module whose name depends only on the file's
  absolute path (``mjnav_planner_file_<hash>_<stem>``), so every worker process loads it the same
  way and nothing has to be pickled.

:func:`resolve` (``mjnav.planners.resolve_planner``, with :data:`mjnav.planners.PLANNERS`) turns a
spec into a :class:`PlannerSource`: the factory, its config class (its ``config_class`` attribute or
the registry's), the ground truth it declares
(``privileged``), what to record (``source``, :meth:`PlannerSource.sha256`) and how to build it
with ``planner.<field>=value`` overrides (:meth:`PlannerSource.make`).
"""

from __future__ import annotations

import dataclasses
import hashlib
import importlib
import importlib.util
import inspect
import json
import re
import sys
from collections.abc import Callable, Sequence
from pathlib import Path
from typing import Any

from mjnav.planners.base import Planner, declared_privileged
from mjnav.registry import Registry, RegistryError
from mjnav.schema import ConfigError, apply_overrides

__all__ = ["PlannerError", "PlannerSource", "is_spec", "resolve"]

_IDENT = r"[A-Za-z_]\w*"
_MODULE_SPEC = re.compile(rf"^{_IDENT}(\.{_IDENT})*:{_IDENT}$")
_FILE_SPEC = re.compile(rf"^(?P<file>.+\.py):(?P<cls>{_IDENT})$")


class PlannerError(ValueError):
    """A planner spec that cannot be loaded: missing file, failed import, no such class, not a Planner."""


@dataclasses.dataclass(frozen=True)
class PlannerSource:
    """A resolved planner spec.

    Attributes:
        spec: The spec as given (``teb``, ``pkg.mod:Mine``, ``dir/mine.py:Mine``).
        name: Display name: the registry name, ``module:Class`` or ``file.py:Class``.
        source: What is recorded as ``planner_source``: the registry name, ``module:Class`` or
            ``<absolute file path>:Class``.
        factory: Builds the planner: ``factory()`` or, with a config class, ``factory(config)``.
        config_class: Dataclass of its parameters (None: it takes none).
        files: Source files hashed by :meth:`sha256` (the planner's module, then those of its base
            classes from the same top-level package).
    """

    spec: str
    name: str
    source: str
    factory: Callable[..., Planner]
    config_class: type | None
    files: tuple[Path, ...]

    @property
    def privileged(self) -> frozenset[str]:
        """The ground truth it declares (:func:`mjnav.planners.base.declared_privileged`)."""
        return declared_privileged(self.factory)

    def config(self, overrides: Sequence[str] = ()) -> object | None:
        """Its config class's defaults plus ``overrides`` (None without a config class).

        Raises:
            ConfigError: Overrides for a planner without parameters, or a bad override.
        """
        if self.config_class is None:
            if overrides:
                raise ConfigError(f"planner overrides {list(overrides)}: {self.name} has no parameters "
                                  "(it declares no config_class)")
            return None
        return apply_overrides(self.config_class(), list(overrides))

    def params(self, overrides: Sequence[str] = ()) -> dict[str, Any]:
        """The resolved parameters as JSON values (``{}`` without a config class)."""
        config = self.config(overrides)
        return {} if config is None else json.loads(json.dumps(dataclasses.asdict(config)))

    def make(self, overrides: Sequence[str] = ()) -> Planner:
        """A fresh planner with ``overrides`` applied to its parameters.

        Raises:
            ConfigError: A bad override.
            PlannerError: The object built is not a Planner (no ``reset`` and ``act``).
        """
        config = self.config(overrides)
        planner = self.factory() if self.config_class is None else self.factory(config)
        _check_planner(planner, self.spec)
        return planner

    def sha256(self) -> str:
        """SHA-256 (hex) of its source files' bytes (:attr:`files`), so a changed planner is noticed."""
        digest = hashlib.sha256()
        for path in self.files:
            digest.update(path.read_bytes())
        return digest.hexdigest()


def is_spec(spec: str | Path, registry: Registry) -> bool:
    """Whether ``spec`` names a planner (a name in ``registry``, ``module:Class`` or ``file.py:Class``),
    by its form only: nothing outside the registry is imported."""
    text = str(spec)
    return text in registry or bool(_FILE_SPEC.match(text) or _MODULE_SPEC.match(text))


def resolve(spec: str | Path, registry: Registry) -> PlannerSource:
    """The planner named by ``spec`` (module docstring).

    Args:
        spec: Registered name, ``package.module:Class`` or ``path/to/file.py:Class``.
        registry: Where names are looked up (:data:`mjnav.planners.PLANNERS`).

    Raises:
        mjnav.registry.RegistryError: An unknown name (the message lists the known ones).
        PlannerError: A missing file, a failed import (with its message), no such class, a class
            that is not a Planner, or a bad ``privileged`` declaration.
    """
    text = str(spec)
    planners = registry
    if text in planners:
        entry = planners.get(text)
        found = PlannerSource(text, text, text, entry.factory, entry.config_class, _source_files(entry.factory))
    elif match := _FILE_SPEC.match(text):
        path = Path(match["file"]).expanduser().resolve()
        factory = _attribute(_load_file(path, text), match["cls"], text)
        found = PlannerSource(text, f"{path.name}:{match['cls']}", f"{path}:{match['cls']}", factory,
                              getattr(factory, "config_class", None), _source_files(factory))
    elif _MODULE_SPEC.match(text):
        module_name, cls = text.split(":")
        factory = _attribute(_import(module_name, text), cls, text)
        found = PlannerSource(text, text, text, factory, getattr(factory, "config_class", None),
                              _source_files(factory))
    else:
        raise RegistryError(f"{planners.unknown_message(text)}; or give package.module:Class or "
                            "path/to/file.py:Class")
    try:  # a bad declaration fails here, at load time
        found.privileged  # noqa: B018
    except ValueError as err:
        raise PlannerError(f"planner {text!r}: {err}") from err
    return found


def _module_name(path: Path) -> str:
    """A module name that depends only on the absolute path (the same in every process)."""
    digest = hashlib.sha256(str(path).encode()).hexdigest()[:12]
    stem = re.sub(r"\W", "_", path.stem)
    return f"mjnav_planner_file_{digest}_{stem}"


def _load_file(path: Path, spec: str) -> Any:
    """The module of a planner file, loaded once per process under :func:`_module_name`."""
    if not path.is_file():
        raise PlannerError(f"planner {spec!r}: no such file {str(path)!r}")
    name = _module_name(path)
    if name in sys.modules:
        return sys.modules[name]
    module_spec = importlib.util.spec_from_file_location(name, path)
    if module_spec is None or module_spec.loader is None:
        raise PlannerError(f"planner {spec!r}: {str(path)!r} cannot be loaded as a Python module")
    module = importlib.util.module_from_spec(module_spec)
    sys.modules[name] = module  # dataclasses and pickling look their module up by name
    try:
        module_spec.loader.exec_module(module)
    except Exception as err:
        del sys.modules[name]
        raise PlannerError(f"planner {spec!r}: importing {str(path)!r} failed: {type(err).__name__}: {err}") from err
    return module


def _import(module_name: str, spec: str) -> Any:
    try:
        return importlib.import_module(module_name)
    except Exception as err:
        raise PlannerError(f"planner {spec!r}: importing module {module_name!r} failed: "
                           f"{type(err).__name__}: {err}") from err


def _attribute(module: Any, name: str, spec: str) -> Callable[..., Planner]:
    """``module.name``, checked to be a Planner class (``reset`` and ``act``)."""
    if not hasattr(module, name):
        public = sorted(n for n, v in vars(module).items() if isinstance(v, type) and not n.startswith("_")
                        and getattr(v, "__module__", None) == module.__name__)
        raise PlannerError(f"planner {spec!r}: {module.__name__} has no {name!r} (its classes: "
                           f"{', '.join(public) or 'none'})")
    factory = getattr(module, name)
    _check_planner(factory, spec)
    return factory


def _check_planner(obj: object, spec: str) -> None:
    """Raise :class:`PlannerError` unless ``obj`` has callable ``reset`` and ``act``."""
    missing = [m for m in ("reset", "act") if not callable(getattr(obj, m, None))]
    if missing:
        raise PlannerError(f"planner {spec!r}: {getattr(obj, '__name__', type(obj).__name__)} is not a Planner "
                           f"(no {' or '.join(missing)}; see mjnav.planners.base.Planner)")


def _source_files(factory: Callable[..., Any]) -> tuple[Path, ...]:
    """The file of ``factory``'s module, then those of its base classes from the same top-level package."""
    module = getattr(factory, "__module__", None) or ""
    root = module.split(".")[0]
    classes = inspect.getmro(factory) if inspect.isclass(factory) else (factory,)
    files: list[Path] = []
    for obj in classes:
        owner = getattr(obj, "__module__", None) or ""
        if owner.split(".")[0] != root:
            continue
        file = getattr(sys.modules.get(owner), "__file__", None)
        if file is not None and Path(file).resolve() not in files:
            files.append(Path(file).resolve())
    return tuple(files)
