"""Every command line the documentation shows parses with its verb's grammar, so a page can never
show a key, a verb or a shipped name that does not exist.

Which lines: in ``README.md`` and ``docs/*.md`` (not ``docs/notebook/``, the dated record), every
line of a shell code block and every inline code span that starts with ``mjnav``, ``python -m
mjnav`` or ``python scripts/<name>.py``. A shell line ending in ``\\`` continues on the next one;
``# ...`` after a command is a comment.

Placeholders the pages may use (the convention this test reads them by):

* ``[key=value ...]``: an optional part (a ``[`` after a space). The line is parsed twice: with
  every optional part left out and with every one written in.
* ``key=a|b|c``: alternatives; the line is parsed once per alternative.
* ``...`` as a token: "more keys"; dropped.
* An upper-case value (``policy=P``, ``run=RUN_DIR``, ``out=DIR``) or one with ``<...>``
  (``policy=runs/<run>/policy.pt``): a value the reader fills in; text fields take it as written.
* ``<verb>`` (any ``<word>`` where a verb or sub-verb goes: ``mjnav bench <name> --help``): each
  verb there; followed by ``--help <section>``, each one that takes config keys.
* A name the page itself registers (``PLANNERS.register("straight", ...)`` or an entry point
  ``straight = "my_nav.planners:StraightToGoal"`` in its ``pyproject.toml`` block) is known on that
  page: ``policy=straight``, its ``planner.<field>=`` keys and ``crowd.model=bounce`` are not looked up
  (the "Extending mjnav" page's own test runs them).
* ``{stage}`` in a policy name stands for each stage of the command (``policies={stage}_policy``).

The lines are parsed, never run: each verb's ``run`` is replaced by a check that parses the
arguments with :func:`mjnav.args.parse` and then loads the config overrides (``task.``, ``train.``,
``planner.``) the way the verb would, so an unknown section field fails too. Policy names that are
neither paths nor placeholders must be shipped policies (``policies/manifest.yaml``) or planners;
``recipe=`` must name a shipped recipe and ``methods=`` methods of the table.
"""

from __future__ import annotations

import dataclasses
import re
import runpy
import shlex
import sys
import typing
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import pytest

from mjnav import cli, shipped
from mjnav.args import HELP_FLAGS, Parsed, parse
from mjnav.schema import ConfigError

ROOT = Path(__file__).resolve().parents[1]
PAGES = (ROOT / "README.md", *sorted((ROOT / "docs").glob("*.md")))
_START = re.compile(r"^(mjnav|python -m mjnav|python scripts/\w+\.py)(\s|$)")
_FENCE = re.compile(r"^```(\w*)\s*$")
_SHELL = {"", "bash", "sh", "shell", "console"}
_INLINE = re.compile(r"`([^`]+)`")
_OPTIONAL = re.compile(r"(?:(?<=\s)|^)\[([^\[\]]*)\]")
_COMMENT = re.compile(r"\s+#.*$")

#: README lines that fail today, kept until the lead's rewrite of the README (this branch may not
#: edit it): each is a known bad line, reported with the branch; delete an entry once its line is gone.
README_KNOWN_BAD: set[str] = set()  # README lines known not to parse (none since the README rewrite)


_REGISTERED = re.compile(r"""\.register\(\s*"(\w+)"|^(\w+)\s*=\s*"[\w.]+:\w+"\s*$""", re.MULTILINE)
#: Names registered by the page being checked (set per command; see the module docstring).
_page_names: frozenset[str] = frozenset()


def registered_names(page: Path) -> frozenset[str]:
    """The names a page registers in its own examples (``register("x"`` calls, ``x = "m:attr"`` entry points)."""
    return frozenset(a or b for a, b in _REGISTERED.findall(page.read_text(encoding="utf-8")))


@dataclasses.dataclass(frozen=True)
class Command:
    """One command line of a page.

    Attributes:
        page: The page, relative to the repository root.
        line: Its 1-based line number there.
        text: The command as written (continuations joined, comment dropped).
    """

    page: str
    line: int
    text: str


def _shell_lines(lines: list[str]) -> Iterator[tuple[int, str]]:
    """(line number, text) of each command in the shell code blocks, continuations joined."""
    block, shell, pending, start = False, False, "", 0
    for number, line in enumerate(lines, 1):
        fence = _FENCE.match(line.strip())
        if fence:
            block = not block
            shell = block and fence.group(1) in _SHELL
            continue
        if not shell:
            continue
        if not pending:
            start = number
        pending += line.rstrip().removesuffix("\\") + " "
        if not line.rstrip().endswith("\\"):
            yield start, _COMMENT.sub("", pending).strip()
            pending = ""


def _inline_lines(lines: list[str]) -> Iterator[tuple[int, str]]:
    """(line number, text) of each inline code span outside code blocks (a span may wrap a line)."""
    prose, inside = [], False
    for line in lines:
        if _FENCE.match(line.strip()):
            inside = not inside
        prose.append("" if inside or _FENCE.match(line.strip()) else line)
    text = "\n".join(prose)
    for match in _INLINE.finditer(text):
        yield text.count("\n", 0, match.start()) + 1, " ".join(match.group(1).split())


def commands(page: Path) -> list[Command]:
    """Every command line of ``page`` that this test checks."""
    lines = page.read_text(encoding="utf-8").splitlines()
    found = [*_shell_lines(lines), *_inline_lines(lines)]
    name = page.relative_to(ROOT).as_posix()
    return [Command(name, number, text) for number, text in sorted(found)
            if _START.match(text) and text not in ("mjnav", "python -m mjnav")]  # the bare name is prose


def variants(text: str) -> list[list[str]]:
    """The argument lists a line stands for (optional parts out and in, each alternative once)."""
    without = _OPTIONAL.sub("", text)
    with_all = _OPTIONAL.sub(lambda m: m.group(1), text)
    out = []
    for line in dict.fromkeys([without, with_all]):
        tokens = [t for t in shlex.split(line) if t != "..."]
        choices = [t.split("=", 1)[1].split("|") if "=" in t and "|" in t else [None] for t in tokens]
        for i in range(max(len(c) for c in choices) if choices else 1):
            out.append([t if c == [None] else f"{t.split('=', 1)[0]}={c[min(i, len(c) - 1)]}"
                        for t, c in zip(tokens, choices, strict=True)])
    return out


def _placeholder(value: str) -> bool:
    """A value the reader fills in or a path (not a name to look up)."""
    return (value.isupper() or "<" in value or "/" in value or value.endswith((".pt", ".onnx"))
            or value in ("", "..."))


def _stages(options: Any) -> list[str]:
    """The stages a command names (``task=`` or ``tasks=``), else ``stage6``."""
    from mjnav.stages import stage_names

    named = [s for s in str(getattr(options, "tasks", "") or "").split(",") if s]
    named = named or [str(getattr(options, "task", "") or "")]
    known = [s for s in named if s in stage_names()]
    return known or ["stage6"]


def _check_names(options: Any) -> None:
    """Policy, recipe and method names of a parsed line exist."""
    from mjnav.eval.tables import TABLES, planner_method
    from mjnav.planners import PLANNERS

    known = {"random", *_page_names, *shipped.names(), *PLANNERS.names(),
             *(f"{n}{shipped.WEIGHTS_SUFFIX}" for n in shipped.names() if shipped.get(n).weights)}
    specs = [spec for field in ("policy", "policies") for spec in str(getattr(options, field, "") or "").split(",")]
    for spec in filter(None, specs):
        for name in {spec.replace("{stage}", stage) for stage in _stages(options)}:
            assert _placeholder(name) or name in known, f"policy {name!r}: not shipped and not a planner"
    recipe = str(getattr(options, "recipe", "") or "")
    assert not recipe or _placeholder(recipe) or recipe in shipped.names(), f"recipe {recipe!r} is not shipped"
    methods = [m for m in str(getattr(options, "methods", "") or "").split(",") if m]
    if methods:
        added = [planner_method(p).name for p in str(getattr(options, "planners", "") or "").split(",") if p]
        table = {m.name for m in TABLES[options.table].methods} | set(added)
        assert set(methods) <= table, f"methods {methods}: not in table {options.table} ({sorted(table)})"


def _check_config(parsed: Parsed) -> None:
    """The config overrides of a parsed line load (every field exists, every value fits)."""
    from mjnav.config import load_task
    from mjnav.planners import PLANNERS, planner_config
    from mjnav.train.config import load_train

    task = [t for t in parsed.task if t.partition("=")[2] not in _page_names]
    for stage in _stages(parsed.options):
        load_task(stage, task)
    load_train(list(parsed.train))
    policy = str(getattr(parsed.options, "policy", "") or "")
    if parsed.planner and policy not in _page_names:
        assert policy in PLANNERS, f"planner.* keys need policy=<planner> (got {policy!r})"
        planner_config(policy, list(parsed.planner))


def _typed_placeholders_dropped(argv: list[str], options: type) -> list[str]:
    """``argv`` without ``key=K`` tokens whose field is not text (``table=K``: any table)."""
    hints = typing.get_type_hints(options)
    text = (str, str | None)
    return [t for t in argv if not (t.partition("=")[0] in hints and hints[t.partition("=")[0]] not in text
                                    and _placeholder(t.partition("=")[2]))]


def _parse_only(verb: cli.Verb, argv: list[str], prog: str = "mjnav") -> int:
    """Stands in for :func:`mjnav.cli.run_verb`: parse and check, never run."""
    del prog
    grammar = cli._load(verb.grammar)()
    for i, token in enumerate(argv):
        if token in HELP_FLAGS:
            if i + 1 < len(argv) and "=" not in argv[i + 1]:
                cli.section_help(argv[i + 1], grammar.prefixes)  # a section the verb takes
            return 0
    parsed = parse(_typed_placeholders_dropped(argv, grammar.options), grammar)
    _check_config(parsed)
    _check_names(parsed.options)
    return 0


def check(argv: list[str], monkeypatch: pytest.MonkeyPatch) -> None:
    """Parse one argument list (``mjnav ...``, ``python -m mjnav ...``, ``python scripts/x.py ...``)."""
    monkeypatch.setattr(cli, "run_verb", _parse_only)
    if argv[0] == "mjnav" or argv[:3] == ["python", "-m", "mjnav"]:
        rest = argv[1:] if argv[0] == "mjnav" else argv[3:]
        assert cli.main(rest) == 0, f"mjnav {' '.join(rest)}: not a command"
        return
    script = ROOT / argv[1]
    assert script.is_file(), f"{argv[1]}: no such script"
    monkeypatch.setattr(sys, "argv", [str(script), *argv[2:]])
    with pytest.raises(SystemExit) as exit_:
        runpy.run_path(str(script), run_name="__main__")
    assert exit_.value.code in (0, None), f"{' '.join(argv)}: exit code {exit_.value.code}"


def _leaf_words(verbs: dict[str, cli.Verb]) -> list[list[str]]:
    """The words of every runnable verb under ``verbs`` (``["plot", "episode"]``, ``["train"]``)."""
    return [[name, *rest] for name, verb in verbs.items()
            for rest in (_leaf_words(dict(verb.subverbs)) if verb.subverbs else [[]])]


def _takes_config(words: list[str]) -> bool:
    """Whether the verb named by ``words`` takes config keys (has sections to list)."""
    verb = cli.VERBS[words[0]]
    for word in words[1:]:
        verb = verb.subverbs[word]
    return bool(cli._load(verb.grammar)().prefixes)


def _each_verb(argv: list[str]) -> list[list[str]]:
    """``argv`` with a ``<verb>`` (any ``<word>`` where a verb or sub-verb goes) replaced by each
    verb there; with ``--help <section>`` after it, each such verb that takes config keys."""
    i = 1 if argv[0] == "mjnav" else 3 if argv[:3] == ["python", "-m", "mjnav"] else None
    if i is None:
        return [argv]
    verbs: dict[str, cli.Verb] = cli.VERBS
    while i < len(argv) and argv[i] in verbs and verbs[argv[i]].subverbs:
        verbs, i = dict(verbs[argv[i]].subverbs), i + 1
    if i >= len(argv) or not re.fullmatch(r"<\w+>", argv[i]):
        return [argv]
    words = _leaf_words(verbs)
    if any(t in HELP_FLAGS for t in argv[i + 1:-1]):
        head = argv[1:i] if argv[0] == "mjnav" else argv[3:i]
        words = [w for w in words if _takes_config([*head, *w])]
    return [[*argv[:i], *w, *argv[i + 1:]] for w in words]


ALL = [c for page in PAGES for c in commands(page)]


def _param(command: Command) -> Any:
    marks = ([pytest.mark.xfail(reason="README line, fixed by the lead's rewrite", strict=True)]
             if command.page == "README.md" and command.text in README_KNOWN_BAD else [])
    return pytest.param(command, id=f"{command.page}:{command.line}", marks=marks)


def test_the_pages_show_commands() -> None:
    """The extraction finds the results page's table commands and the README's quick start."""
    pages = {c.page for c in ALL}
    assert {"README.md", "docs/results.md", "docs/performance.md"} <= pages
    assert any(c.text == "mjnav tables table=3" for c in ALL)


@pytest.mark.parametrize("command", [_param(c) for c in ALL])
def test_documented_command_parses(command: Command, monkeypatch: pytest.MonkeyPatch) -> None:
    """Each documented command (each optional part and alternative) parses with its verb's grammar."""
    monkeypatch.setattr(sys.modules[__name__], "_page_names", registered_names(ROOT / command.page))
    for argv in variants(command.text):
        for each in _each_verb(argv):
            check(each, monkeypatch)


@pytest.mark.parametrize(("text", "expected"), [
    ("mjnav tables table=2 [action=mean|sample] [episodes=1000]",
     [["mjnav", "tables", "table=2"], ["mjnav", "tables", "table=2", "action=mean", "episodes=1000"],
      ["mjnav", "tables", "table=2", "action=sample", "episodes=1000"]]),
    ("mjnav export out=DIR [task.crowd.count=25 ...]",
     [["mjnav", "export", "out=DIR"], ["mjnav", "export", "out=DIR", "task.crowd.count=25"]]),
    ("mjnav train task.crowd.speed=[0.3,0.6]", [["mjnav", "train", "task.crowd.speed=[0.3,0.6]"]]),
])
def test_placeholder_convention(text: str, expected: list[list[str]]) -> None:
    """Optional parts are parsed left out and written in, alternatives one by one, ``...`` dropped."""
    assert variants(text) == expected


@pytest.mark.parametrize("bad", [
    "mjnav tables table=2 acton=sample",
    "mjnav evaluate policy=teb task.crowd.cont=3",
    "mjnav evaluate policy=stage9_policy",
    "mjnav plot histogram",
    "python scripts/evaluate.py policy=teb train.lr=1",
])
def test_a_wrong_command_is_caught(bad: str, monkeypatch: pytest.MonkeyPatch) -> None:
    """A misspelt key, an unknown config field, an unshipped name or an unknown verb fails the check."""
    with pytest.raises((AssertionError, ConfigError, KeyError)):
        check(variants(bad)[0], monkeypatch)


def test_known_bad_readme_lines_are_still_there() -> None:
    """Every README exception names a line the README still has (else delete the entry)."""
    readme = {c.text for c in ALL if c.page == "README.md"}
    assert README_KNOWN_BAD <= readme, f"gone from the README: {sorted(README_KNOWN_BAD - readme)}"



def test_a_verb_placeholder_stands_for_each_verb_there() -> None:
    """``mjnav bench <name> --help`` is each benchmark; ``mjnav <verb> --help task.crowd`` each verb with sections."""
    assert [a[2] for a in _each_verb(["mjnav", "bench", "<name>", "--help"])] == list(cli.VERBS["bench"].subverbs)
    with_sections = _each_verb(["mjnav", "<verb>", "--help", "task.crowd"])
    assert ["mjnav", "train", "--help", "task.crowd"] in with_sections
    assert all(a[1:3] != ["bench", "sim"] for a in with_sections)


def test_names_a_page_registers_are_known_there() -> None:
    """The extending page's planner, crowd model and robot names count as known on that page only."""
    names = registered_names(ROOT / "docs" / "extending.md")
    assert {"straight", "bounce", "omni_mast"} <= names
    assert not registered_names(ROOT / "docs" / "results.md")
