"""``mjnav bench evalscale``: one run prints episodes/s per worker count, the ratio, and whether the
records are the same episode for episode."""

from __future__ import annotations

import re

import pytest

from mjnav.cli import main

SHORT = ["episodes=3", "timing.episode_steps=10"]


@pytest.mark.parametrize("backend", ["local", "ray"])
def test_one_run_prints_the_ratio_and_same_records(backend, capsys) -> None:
    if backend == "ray":
        pytest.importorskip("ray")
    assert main(["bench", "evalscale", f"backend={backend}", "workers=1,2", *SHORT]) == 0
    out = capsys.readouterr().out
    assert re.search(r"\n2 workers / 1: \d+\.\d\dx episodes/s \(\d+\.\d\dx with start-up\)", out)
    assert out.count("| yes |") == 2


def test_bad_input_is_one_error_line(capsys) -> None:
    assert main(["bench", "evalscale", "workers=0,2", *SHORT]) == 2
    assert capsys.readouterr().err.startswith("error: workers:")
    assert main(["bench", "evalscale", "backend=local", "task=stage99", *SHORT]) == 2
    assert capsys.readouterr().err.startswith("error:")
