"""One registry shape for every extension point: name → factory and config class.

Planners, pedestrian models, designs, LiDAR backends, robots and stages each keep one
:class:`Registry`. Entries come from three places, looked up in this order:

1. ``register`` calls in mjnav's own modules (the built-ins);
2. ``register`` calls in user code (``@PLANNERS.register("mine", config=MineConfig)``);
3. Python entry points of installed packages, in the registry's ``group`` (e.g.
   ``[project.entry-points."mjnav.planners"] mine = "mypkg.planner:Mine"``); they are read on the
   first lookup that misses and on :meth:`Registry.names`. An entry point names the factory; its
   config class is the factory's ``config_class`` attribute, if it has one.

This module is the bottom layer: it imports nothing from mjnav.
"""

from __future__ import annotations

import dataclasses
import difflib
from collections.abc import Callable, Iterator
from importlib import metadata
from typing import Any, Generic, TypeVar

__all__ = ["Entry", "Registry", "RegistryError"]

T = TypeVar("T")


class RegistryError(KeyError):
    """An unknown or clashing registry name; the message lists the known names and the closest."""

    def __str__(self) -> str:  # KeyError would quote the message
        return str(self.args[0]) if self.args else ""


@dataclasses.dataclass(frozen=True)
class Entry(Generic[T]):
    """One registered name.

    Attributes:
        name: The name users give (``policy=teb``, ``crowd.model=orca``).
        factory: Builds the object; called as ``factory()`` or ``factory(config)``.
        config_class: Dataclass of the parameters the factory takes (None: none).
        source: Where it came from: ``"builtin"``, ``"user"`` or ``"entry point <pkg>"``.
    """

    name: str
    factory: Callable[..., T]
    config_class: type | None = None
    source: str = "user"

    def make(self, config: Any = None) -> T:
        """The object, from ``config`` (defaults of :attr:`config_class` if None)."""
        if self.config_class is None:
            if config is not None:
                raise RegistryError(f"{self.name} takes no parameters (got {config!r})")
            return self.factory()
        return self.factory(self.config_class() if config is None else config)


class Registry(Generic[T]):
    """Name → :class:`Entry` for one kind of extension.

    Args:
        kind: What the entries are, for messages (``"planner"``).
        group: Entry-point group read for outside packages (``"mjnav.planners"``); None: none.
    """

    def __init__(self, kind: str, group: str | None = None) -> None:
        self.kind = kind
        self.group = group
        self._entries: dict[str, Entry[T]] = {}
        self._entry_points_read = group is None

    def register(self, name: str, factory: Callable[..., T] | None = None, *, config: type | None = None,
                 source: str = "user", replace: bool = False) -> Any:
        """Add ``name``; usable as a call or, without ``factory``, as a class/function decorator.

        Raises:
            RegistryError: ``name`` is taken and ``replace`` is False, or ``name`` is not a plain
                identifier-like string.
        """
        if not isinstance(name, str) or not name or any(c in name for c in " =,:/"):
            raise RegistryError(f"{self.kind} name {name!r}: use a non-empty name without spaces, '=', ',', ':' or '/'")
        if factory is None:
            def decorate(obj: Callable[..., T]) -> Callable[..., T]:
                self.register(name, obj, config=config, source=source, replace=replace)
                return obj
            return decorate
        if name in self._entries and not replace:
            raise RegistryError(f"{self.kind} {name!r} is already registered ({self._entries[name].source}); "
                                f"pass replace=True to override it")
        self._entries[name] = Entry(name, factory, config if config is not None else getattr(factory, "config_class", None),
                                    source)
        return factory

    def unregister(self, name: str) -> None:
        """Remove ``name`` (tests and interactive use); unknown names are ignored."""
        self._entries.pop(name, None)

    def _read_entry_points(self) -> None:
        if self._entry_points_read:
            return
        self._entry_points_read = True
        for ep in metadata.entry_points(group=self.group):
            if ep.name in self._entries:
                continue  # a built-in or explicit registration wins over a package's entry point
            try:
                factory = ep.load()
            except Exception as err:  # a broken outside package must not hide the built-ins
                raise RegistryError(f"{self.kind} {ep.name!r} from entry point {ep.value!r} "
                                    f"(group {self.group}) failed to load: {type(err).__name__}: {err}") from err
            dist = ep.dist.name if ep.dist is not None else "?"
            self.register(ep.name, factory, source=f"entry point {dist}")

    def get(self, name: str) -> Entry[T]:
        """The entry of ``name``.

        Raises:
            RegistryError: Unknown name; the message lists the known ones and the closest match.
        """
        if name not in self._entries:
            self._read_entry_points()
        if name not in self._entries:
            raise RegistryError(self.unknown_message(name))
        return self._entries[name]

    def unknown_message(self, name: str) -> str:
        """``unknown <kind> 'x' (known: ...; closest: ...)``."""
        known = self.names()
        close = difflib.get_close_matches(str(name), known, n=1)
        hint = f"; closest: {close[0]}" if close else ""
        return f"unknown {self.kind} {name!r} (known: {', '.join(known)}{hint})"

    def make(self, name: str, config: Any = None) -> T:
        """``get(name).make(config)``."""
        return self.get(name).make(config)

    def names(self) -> list[str]:
        """Every registered name, entry points included, sorted."""
        self._read_entry_points()
        return sorted(self._entries)

    def __contains__(self, name: object) -> bool:
        if name not in self._entries:
            self._read_entry_points()
        return name in self._entries

    def __iter__(self) -> Iterator[str]:
        return iter(self.names())

    def __len__(self) -> int:
        return len(self.names())

    def __repr__(self) -> str:
        return f"Registry({self.kind!r}, group={self.group!r}, names={sorted(self._entries)})"
