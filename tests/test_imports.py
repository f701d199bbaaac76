"""Every import inside a function says why it is deferred.

The house rule (issue 40, item 3): an import sits inside a function only where that saves measured
start-up time on a path that matters (``mjnav --help``, ``mjnav <verb> --help``, ``import mjnav``,
evaluating baselines without torch), or where it must wait (MuJoCo after the GL backend is chosen),
or where the package is optional. Such an import carries a ``# deferred: <why>`` comment on its own
line or in the comment block right above it (or above the run of imports it starts); every other
import goes to the top of its module. ``if TYPE_CHECKING:`` blocks are not deferred imports.
"""

from __future__ import annotations

import ast
import re
from collections.abc import Iterator
from pathlib import Path

PACKAGE = Path(__file__).resolve().parents[1] / "mjnav"
_REASON = re.compile(r"#.*\bdeferred\b\W*\w+", re.IGNORECASE)
_FUNCTIONS = (ast.FunctionDef, ast.AsyncFunctionDef, ast.Lambda)


def _is_type_checking(node: ast.AST) -> bool:
    return isinstance(node, ast.If) and "TYPE_CHECKING" in ast.unparse(node.test)


def _deferred(node: ast.AST, in_function: bool = False) -> Iterator[ast.Import | ast.ImportFrom]:
    """Import statements inside functions (at any depth), skipping ``if TYPE_CHECKING:`` blocks."""
    for child in ast.iter_child_nodes(node):
        if _is_type_checking(child):
            continue
        if in_function and isinstance(child, (ast.Import, ast.ImportFrom)):
            yield child
        yield from _deferred(child, in_function or isinstance(child, _FUNCTIONS))


def _has_reason(lines: list[str], node: ast.Import | ast.ImportFrom, covered: set[int]) -> bool:
    """A ``# deferred`` comment on the statement's lines or in the comment block above it or above
    the run of import statements (blank lines between them allowed) it belongs to (``covered``: the
    lines of all deferred imports)."""
    if any(_REASON.search(lines[i - 1]) for i in range(node.lineno, (node.end_lineno or node.lineno) + 1)):
        return True
    row = node.lineno - 1
    while row >= 1 and (row in covered or not lines[row - 1].strip()):
        row -= 1  # the statements (and blank lines) above in the same run of imports
    while row >= 1 and lines[row - 1].lstrip().startswith("#"):
        if _REASON.search(lines[row - 1]):
            return True
        row -= 1
    return False


def _unexplained(path: Path, root: Path = PACKAGE.parent) -> list[str]:
    """``file:line: statement`` of each deferred import of ``path`` without a reason."""
    source = path.read_text(encoding="utf-8")
    lines, nodes = source.splitlines(), list(_deferred(ast.parse(source)))
    covered = {row for node in nodes for row in range(node.lineno, (node.end_lineno or node.lineno) + 1)}
    return [f"{path.relative_to(root)}:{node.lineno}: {lines[node.lineno - 1].strip()}"
            for node in nodes if not _has_reason(lines, node, covered)]


def test_every_deferred_import_says_why() -> None:
    """An import inside a function has a ``# deferred: <why>`` comment on or above it."""
    found = [line for path in sorted(PACKAGE.rglob("*.py")) for line in _unexplained(path)]
    assert found == [], "imports inside functions without a '# deferred: <why>' comment (move them to the " \
                        "module top, or say what deferring saves):\n" + "\n".join(found)


def test_checker_flags_a_bare_deferred_import(tmp_path: Path) -> None:
    """The checker flags a bare in-function import, accepts commented ones and ignores TYPE_CHECKING."""
    module = tmp_path / "m.py"
    module.write_text(
        "from typing import TYPE_CHECKING\n"
        "if TYPE_CHECKING:\n    import json\n"
        "def a():\n    import os\n"
        "def b():\n    import os  # deferred: costs 1 s\n"
        "def c():\n    # deferred: costs 1 s\n    # (measured)\n    import os\n    import sys\n"
        "def d():\n    x = 1  # deferred\n    import os\n"
    )
    assert [line.split(": ", 1)[0] for line in _unexplained(module, tmp_path)] == ["m.py:5", "m.py:15"]


def test_cli_help_loads_no_heavy_module() -> None:
    """``mjnav --help`` imports neither MuJoCo, torch, matplotlib nor the config (numba, scipy)."""
    import subprocess
    import sys

    code = ("import sys, contextlib, io\nfrom mjnav.cli import main\n"
            "with contextlib.redirect_stdout(io.StringIO()): main(['--help'])\n"
            "print(sorted(m for m in ('mujoco', 'torch', 'matplotlib', 'numba', 'mjnav.config') if m in sys.modules))")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True,
                         cwd=PACKAGE.parent)
    assert out.stdout.strip() == "[]"
