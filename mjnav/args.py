"""The one command-line grammar of mjnav: every verb, every script and ``gym.make(..., overrides=...)``.

Every argument is a ``key=value`` token:

* ``key=value`` where ``key`` is a field of the verb's options dataclass (its own keys, listed by
  ``--help``), or one of the verb's aliases (``seed=3`` in ``train`` means ``train.seed=3``);
* ``task.<section>.<field>=value`` or the short form ``<section>.<field>=value`` (the first part a
  :class:`mjnav.config.TaskConfig` field): a task config override, the same in every verb;
* ``train.<field>=value``: a PPO config override (:class:`mjnav.train.config.TrainConfig`);
* ``planner.<field>=value``: a planner parameter (``mjnav evaluate policy=dwa planner.w_clearance=0.8``).

Values are read as YAML (``25``, ``true``, ``[0.2, 0.3]``, ``1e-4``) and checked against the
field's type with the config loader's messages; a ``str`` field takes the text as written. An
unknown key is answered with its name, the keys that are known and the closest match.

This module depends on :mod:`mjnav.schema` and the standard library only (so the environment
factory can use it); the config classes that ``--help`` documents are passed in by the caller.
"""

from __future__ import annotations

import dataclasses
import difflib
import inspect
import re
import types
import typing
from collections.abc import Iterable, Mapping, Sequence
from typing import Any

import yaml

from mjnav.schema import ConfigError, coerce

__all__ = [
    "HELP_FLAGS",
    "ArgsError",
    "Grammar",
    "Parsed",
    "attribute_docs",
    "closest",
    "config_key",
    "describe_fields",
    "parse",
    "task_overrides",
    "unknown_key",
]

#: Tokens that ask for help instead of running.
HELP_FLAGS = ("-h", "--help")
#: Prefixes of config keys and what they configure.
PREFIXES = {"task": "task config override", "train": "PPO config override", "planner": "planner parameter"}


class ArgsError(ConfigError):
    """A malformed token, an unknown key or a bad value; the message names the key."""


@dataclasses.dataclass(frozen=True)
class Grammar:
    """What one verb accepts.

    Attributes:
        options: The verb's options dataclass (its own keys, with defaults and documented attributes).
        prefixes: Config prefixes the verb takes (``task``, ``train``, ``planner``).
        aliases: Extra keys and the key each one stands for (``{"seed": "train.seed"}``).
        task_sections: Field names of the task config: the short form ``<section>.<field>=v``.
    """

    options: type
    prefixes: tuple[str, ...] = ("task",)
    aliases: Mapping[str, str] = dataclasses.field(default_factory=dict)
    task_sections: tuple[str, ...] = ()


@dataclasses.dataclass(frozen=True)
class Parsed:
    """A parsed command line.

    Attributes:
        options: The verb's options dataclass, defaults filled in.
        task: Task config overrides without the ``task.`` prefix (``["crowd.count=25"]``).
        train: PPO config overrides without the ``train.`` prefix.
        planner: Planner parameters without the ``planner.`` prefix.
        given: Names of the options set on the command line.
    """

    options: Any
    task: tuple[str, ...] = ()
    train: tuple[str, ...] = ()
    planner: tuple[str, ...] = ()
    given: frozenset[str] = frozenset()


def closest(name: str, known: Iterable[str]) -> str | None:
    """The known name most like ``name`` (difflib), or None when none is close."""
    match = difflib.get_close_matches(name, list(known), n=1, cutoff=0.6)
    return match[0] if match else None


def unknown_key(key: str, known: Sequence[str], forms: Sequence[str] = ()) -> ArgsError:
    """The error for an unknown key: its name, the known keys (and key forms) and the closest match."""
    listed = ", ".join([*(f"{k}=" for k in known), *forms]) or "none: this command takes no keys"
    near = closest(key, known)
    hint = f"; did you mean {near!r}?" if near else ""
    return ArgsError(f"unknown key {key!r} (known: {listed}){hint}")


def _split(token: str) -> tuple[str, str]:
    key, sep, raw = token.partition("=")
    if not sep:
        raise ArgsError(f"argument {token!r}: expected key=value")
    if not key.strip():
        raise ArgsError(f"argument {token!r}: empty key")
    return key.strip(), raw


def _is_text(tp: Any) -> bool:
    """Whether a field of type ``tp`` takes the text as written (``str``, ``str | None``)."""
    if typing.get_origin(tp) in (typing.Union, types.UnionType):
        return all(a is str or a is type(None) for a in typing.get_args(tp))
    return tp is str


def _value(key: str, raw: str, tp: Any) -> Any:
    """``raw`` as a value of the field type ``tp`` (YAML, as config overrides are read)."""
    if _is_text(tp):
        return raw
    try:
        value = yaml.safe_load(raw) if raw else ""
    except yaml.YAMLError:
        value = raw
    return coerce(value, tp, key)


def _forms(grammar: Grammar) -> list[str]:
    forms = []
    if "task" in grammar.prefixes:
        forms += ["task.<section>.<field>=", "<section>.<field>="]
    forms += [f"{p}.<field>=" for p in grammar.prefixes if p != "task"]
    return forms


def _config_key(key: str, grammar: Grammar) -> tuple[str, str] | None:
    """(prefix, key without it) of a config key the verb takes, or None."""
    head, dot, rest = key.partition(".")
    if not dot or not rest:
        return None
    if head in grammar.prefixes:
        return head, rest
    if head in grammar.task_sections and "task" in grammar.prefixes:
        return "task", key
    return None


def config_key(key: str, grammar: Grammar) -> str:
    """``key`` in its long form (``crowd.count`` → ``task.crowd.count``); as it is when ``grammar``
    takes no such config key."""
    found = _config_key(key, grammar)
    return key if found is None else f"{found[0]}.{found[1]}"


def parse(argv: Iterable[str], grammar: Grammar) -> Parsed:
    """Parse ``key=value`` tokens by ``grammar``.

    Raises:
        ArgsError: A token without ``=``, an empty or unknown key (named, with the known keys and
            the closest one), or a value of the wrong type.
    """
    hints = typing.get_type_hints(grammar.options)
    names = [f.name for f in dataclasses.fields(grammar.options)]
    values: dict[str, Any] = {}
    config: dict[str, list[str]] = {p: [] for p in PREFIXES}
    for token in argv:
        key, raw = _split(token)
        key = grammar.aliases.get(key, key)
        if key in names:
            values[key] = _value(key, raw, hints[key])
        elif (found := _config_key(key, grammar)) is not None:
            config[found[0]].append(f"{found[1]}={raw}")
        elif "." in key and key.partition(".")[0] not in names:
            raise _unknown_dotted(key, grammar)
        elif key in grammar.task_sections and "task" in grammar.prefixes:
            raise ArgsError(f"unknown key {key!r}: a task config field is set as task.{key}={raw}")
        else:
            raise unknown_key(key, [*names, *grammar.aliases], _forms(grammar))
    try:
        options = grammar.options(**values)
    except ValueError as err:
        raise ArgsError(str(err)) from None
    return Parsed(options, tuple(config["task"]), tuple(config["train"]), tuple(config["planner"]),
                  frozenset(values))


def _unknown_dotted(key: str, grammar: Grammar) -> ArgsError:
    """A dotted key whose first part is neither a prefix the verb takes nor a task section."""
    head = key.partition(".")[0]
    heads = [*grammar.prefixes, *(grammar.task_sections if "task" in grammar.prefixes else ())]
    if not heads:
        return ArgsError(f"unknown key {key!r}: this command takes no config overrides")
    near = closest(head, heads)
    hint = f"; did you mean {key.replace(head, near, 1)!r}?" if near else ""
    return ArgsError(f"unknown key {key!r}: {head!r} is not a config prefix or task section "
                     f"(known: {', '.join(heads)}){hint}")


def task_overrides(overrides: Mapping[str, Any] | Sequence[str], sections: Sequence[str]) -> Any:
    """``gym.make``'s and ``make_env``'s overrides in the command line's key forms.

    ``task.crowd.count`` and ``crowd.count`` mean the same (the prefix is dropped); a key whose
    first part is not a task config field is an :class:`ArgsError` naming the closest one.

    Args:
        overrides: ``["crowd.count=25"]`` tokens or a ``{"crowd.count": 25}`` mapping.
        sections: Field names of the task config.

    Returns:
        The overrides without the ``task.`` prefix, of the same kind (list or dict).
    """
    def strip(key: str) -> str:
        short = key.strip().removeprefix("task.")
        head = short.partition(".")[0]
        if head not in sections:
            near = closest(head, sections)
            hint = f"; did you mean {near!r}?" if near else ""
            raise ArgsError(f"unknown key {key!r}: {head!r} is not a task config field "
                            f"(known: {', '.join(sections)}){hint}")
        return short

    if isinstance(overrides, Mapping):
        return {strip(k): v for k, v in overrides.items()}
    out = []
    for token in overrides:
        key, raw = _split(token)
        out.append(f"{strip(key)}={raw}")
    return out


# ---------------------------------------------------------------------------- help from docstrings

_ATTRIBUTE = re.compile(r"^    (\w+)(?: \([^)]*\))?: (.*)$")


def attribute_docs(cls: type) -> dict[str, str]:
    """``{field: description}`` from the ``Attributes:`` section of a class's Google-style docstring
    (continuation lines joined)."""
    docs: dict[str, str] = {}
    inside, name = False, None
    for line in (inspect.getdoc(cls) or "").splitlines():
        if line.strip() == "Attributes:":
            inside = True
        elif inside and line and not line[0].isspace():
            inside = False  # the next section
        elif inside and (match := _ATTRIBUTE.match(line)):
            name = match.group(1)
            docs[name] = match.group(2).strip()
        elif inside and name and line.strip():
            docs[name] += " " + line.strip()
    return docs


def _first_sentence(text: str) -> str:
    return re.split(r"(?<=[.;])\s+(?=[A-Z(`])", text, maxsplit=1)[0]


def _default(field: dataclasses.Field) -> str:
    if field.default is not dataclasses.MISSING:
        value = field.default
    elif field.default_factory is not dataclasses.MISSING:
        value = field.default_factory()
    else:
        return "(required)"
    if dataclasses.is_dataclass(value):
        return "{...}"
    if isinstance(value, tuple):
        value = list(value)
    return "" if value is None else yaml.safe_dump(value, default_flow_style=True).strip().removesuffix("...").strip()


def describe_fields(cls: type, prefix: str = "", full: bool = False) -> list[str]:
    """One help line per field of dataclass ``cls``: ``prefix+name=default  description``.

    Args:
        cls: A documented dataclass (``Attributes:`` section).
        prefix: Printed before each name (``task.crowd.``).
        full: The whole description instead of its first sentence.
    """
    docs, hints = attribute_docs(cls), typing.get_type_hints(cls)
    for f in dataclasses.fields(cls):
        section = hints[f.name]
        if f.name not in docs and dataclasses.is_dataclass(section):  # a nested section: its class's summary
            summary = (inspect.getdoc(section) or "").splitlines()[0] if inspect.getdoc(section) else ""
            docs[f.name] = f"{summary} (its keys: --help {prefix}{f.name})"
    rows = [(f"{prefix}{f.name}={_default(f)}", docs.get(f.name, "")) for f in dataclasses.fields(cls)]
    width = min(max((len(k) for k, _ in rows), default=0), 40)
    lines = []
    for key, doc in rows:
        text = doc if full else _first_sentence(doc)
        pad = "\n" + " " * (width + 4) if len(key) > width else " " * (width - len(key) + 2)
        lines.append(f"  {key}{pad}{text}".rstrip())
    return lines
