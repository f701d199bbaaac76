"""The shipped policies: ``policies/manifest.yaml`` (name, file, sha256, recipe, tables) and the recipes.

``policy=stage6_policy`` names a shipped policy wherever a policy is given; a shipped policy's
weights-only checkpoint is ``stage5_policy.weights`` (:func:`resolve`); ``recipe=stage6_policy``
retrains one from ``tasks/recipes/<recipe>.yaml`` (:class:`Recipe`). Files are checked against
the manifest's SHA-256 before use: a mismatch is a :class:`ShippedError` naming the file.

Folders come from :mod:`mjnav.resources` (a checkout or an installed wheel); never from ``docs``.
"""

from __future__ import annotations

import dataclasses
import difflib
import functools
import hashlib
from pathlib import Path
from typing import Any

import yaml

from mjnav.resources import policies_dir, recipes_dir

__all__ = ["WEIGHTS_SUFFIX", "Recipe", "ShippedError", "ShippedPolicy", "find", "get", "load_recipe", "names",
           "resolve", "stage_policy"]

#: ``NAME.weights`` names a shipped policy's weights-only checkpoint.
WEIGHTS_SUFFIX = ".weights"


class ShippedError(ValueError):
    """An unknown shipped policy or recipe, a missing file or a checksum mismatch."""


@dataclasses.dataclass(frozen=True)
class ShippedPolicy:
    """One manifest entry.

    Attributes:
        name: The name users give (``stage6_policy``).
        file: TorchScript actor file in the policies folder.
        sha256: Its SHA-256 (hex).
        recipe: Name of its recipe in ``tasks/recipes``.
        tables: The paper tables it serves.
        stage: The stage whose shipped policy it is (start=auto on the next stage starts from it), or None.
        weights: Weights-only checkpoint file (actor, critic, std), or None.
        weights_sha256: Its SHA-256, or None.
    """

    name: str
    file: str
    sha256: str
    recipe: str
    tables: tuple[int, ...] = ()
    stage: str | None = None
    weights: str | None = None
    weights_sha256: str | None = None

    def path(self) -> Path:
        """The checked actor file.

        Raises:
            ShippedError: Missing file or SHA-256 mismatch.
        """
        return _checked(policies_dir() / self.file, self.sha256, self.name)

    def weights_path(self) -> Path:
        """The checked weights-only checkpoint.

        Raises:
            ShippedError: This policy ships no weights, or the file is missing or altered.
        """
        if self.weights is None or self.weights_sha256 is None:
            with_weights = ", ".join(n for n in names() if get(n).weights)
            raise ShippedError(f"shipped policy {self.name!r} has no weights-only checkpoint (shipped with "
                               f"weights: {with_weights})")
        return _checked(policies_dir() / self.weights, self.weights_sha256, f"{self.name}{WEIGHTS_SUFFIX}")


@dataclasses.dataclass(frozen=True)
class Recipe:
    """How a shipped policy is (re)trained.

    Attributes:
        name: The recipe's name (its file stem).
        task: Stage trained on.
        task_overrides: Dotted TaskConfig overrides (evaluation rebuilds the task with them).
        start: Shipped policy whose weights the run starts from, or None (random weights).
        train: TrainConfig values over the defaults (nested mapping).
    """

    name: str
    task: str
    task_overrides: tuple[str, ...] = ()
    start: str | None = None
    train: dict[str, Any] = dataclasses.field(default_factory=dict)

    def train_overrides(self) -> list[str]:
        """:attr:`train` as dotted ``key=value`` overrides (``["schedule=fixed", ...]``)."""
        return [f"{key}={yaml.safe_dump(value, default_flow_style=True).strip().removesuffix('...').strip()}"
                for key, value in _flatten(self.train)]


def _flatten(data: dict[str, Any], prefix: str = "") -> list[tuple[str, Any]]:
    """``{"a": {"b": 1}}`` -> ``[("a.b", 1)]``."""
    items: list[tuple[str, Any]] = []
    for key, value in data.items():
        if isinstance(value, dict):
            items += _flatten(value, f"{prefix}{key}.")
        else:
            items.append((f"{prefix}{key}", value))
    return items


@functools.cache
def _sha256(path: Path, size: int, mtime_ns: int) -> str:
    return hashlib.sha256(path.read_bytes()).hexdigest()


def _checked(path: Path, expected: str, label: str) -> Path:
    if not path.is_file():
        raise ShippedError(f"shipped policy {label!r}: {path} is missing (reinstall mjnav or restore the file)")
    stat = path.stat()
    found = _sha256(path, stat.st_size, stat.st_mtime_ns)
    if found != expected:
        raise ShippedError(f"shipped policy {label!r}: checksum mismatch for {path} (sha256 {found[:16]}..., the "
                           f"manifest says {expected[:16]}...): the file was altered or replaced; restore it, or "
                           "update policies/manifest.yaml if the change is meant")
    return path


@functools.cache
def _manifest(folder: Path) -> dict[str, ShippedPolicy]:
    data = yaml.safe_load((folder / "manifest.yaml").read_text(encoding="utf-8")) or {}
    entries = data.get("policies") if isinstance(data, dict) else None
    if not isinstance(entries, dict):
        raise ShippedError(f"{folder / 'manifest.yaml'}: expected a 'policies' mapping")
    return {name: ShippedPolicy(name=name, **{**fields, "tables": tuple(fields.get("tables", ()))})
            for name, fields in entries.items()}


def names() -> list[str]:
    """Every shipped policy name, sorted."""
    return sorted(_manifest(policies_dir()))


def get(name: str) -> ShippedPolicy:
    """The manifest entry of ``name``.

    Raises:
        ShippedError: Unknown name; the known ones and the closest in the message.
    """
    entries = _manifest(policies_dir())
    if name not in entries:
        close = difflib.get_close_matches(name, list(entries), n=1)
        raise ShippedError(f"unknown shipped policy {name!r} (known: {', '.join(sorted(entries))}"
                           + (f"; closest: {close[0]})" if close else ")"))
    return entries[name]


def find(spec: str | Path) -> ShippedPolicy | None:
    """The entry a policy spec names: ``NAME``, ``NAME.weights`` or a path to a shipped file; else None."""
    text = str(spec)
    entries = _manifest(policies_dir())
    key = text.removesuffix(WEIGHTS_SUFFIX)
    if key in entries:
        return entries[key]
    path = Path(text)
    if path.is_file() and path.resolve().parent == policies_dir().resolve():
        return next((e for e in entries.values() if path.name in (e.file, e.weights)), None)
    return None


def resolve(spec: str | Path) -> Path | None:
    """The checked file of ``NAME`` (the actor) or ``NAME.weights`` (its weights-only checkpoint);
    None when ``spec`` is not a shipped name.

    Raises:
        ShippedError: Missing file, checksum mismatch, or no weights shipped.
    """
    text = str(spec)
    entries = _manifest(policies_dir())
    if text in entries:
        return entries[text].path()
    if text.endswith(WEIGHTS_SUFFIX) and text.removesuffix(WEIGHTS_SUFFIX) in entries:
        return entries[text.removesuffix(WEIGHTS_SUFFIX)].weights_path()
    return None


def stage_policy(stage: str) -> ShippedPolicy | None:
    """The shipped policy of ``stage`` (its manifest ``stage``), or None."""
    return next((e for e in _manifest(policies_dir()).values() if e.stage == stage), None)


def load_recipe(name: str) -> Recipe:
    """The recipe ``tasks/recipes/<name>.yaml``, or the recipe of the shipped policy ``name``.

    Raises:
        ShippedError: No such recipe, or a malformed one (the file and key in the message).
    """
    path = recipes_dir() / f"{name}.yaml"
    if not path.is_file() and name in _manifest(policies_dir()):
        path = recipes_dir() / f"{get(name).recipe}.yaml"
    if not path.is_file():
        known = sorted(p.stem for p in recipes_dir().glob("*.yaml"))
        raise ShippedError(f"unknown recipe {name!r} (known: {', '.join(known)})")
    data = yaml.safe_load(path.read_text(encoding="utf-8")) or {}
    fields = {f.name for f in dataclasses.fields(Recipe)} - {"name"}
    unknown = sorted(set(data) - fields) if isinstance(data, dict) else ["<not a mapping>"]
    if unknown or "task" not in data:
        raise ShippedError(f"{path}: unknown keys {unknown} or no 'task' (keys: {', '.join(sorted(fields))})")
    return Recipe(name=path.stem, task=str(data["task"]), task_overrides=tuple(data.get("task_overrides") or ()),
                  start=data.get("start"), train=dict(data.get("train") or {}))
