"""Feed malformed input to every public entry point and print what each gets (docs/reliability.md).

    python scripts/bad_input.py

Runs the cases of ``tests/test_bad_input.py`` (the test asserts them) and prints one markdown
row per case: entry point, input, the exception type and its message.
"""

from __future__ import annotations

import dataclasses
import sys
from pathlib import Path

from mjnav.args import Parsed
from mjnav.cli import run_script


@dataclasses.dataclass(frozen=True)
class BadInputOptions:
    """``scripts/bad_input.py`` takes no keys.

    Attributes:
    """


def main(argv: list[str]) -> int:
    """Print the table (``--help``: usage); 1 if a case raised nothing."""
    return run_script(argv, "scripts/bad_input.py", "Feed malformed input to every public entry point; print a table.",
                      BadInputOptions, _table)


def _table(parsed: Parsed) -> int:
    """Print the table; 1 if a case raised nothing."""
    sys.path.insert(0, str(Path(__file__).resolve().parents[1]))
    from tests.test_bad_input import CASES

    print("| entry point | input | answer |\n|---|---|---|")
    silent = 0
    for entry, given, call, _, _ in CASES:
        try:
            call()
            answer, silent = "**no error**", silent + 1
        except Exception as err:  # every answer is reported, that is the point
            message = " ".join(str(err).split())
            answer = f"`{type(err).__name__}`: {message[:140]}{'…' if len(message) > 140 else ''}"
        print(f"| {entry} | {given} | {answer.replace('|', '/')} |")
    return 1 if silent else 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
