"""The "Extending mjnav" page runs: its stage file, modules, entry points and examples work as written.

The page's code blocks are read in order:

* a ``yaml`` block whose first line is ``# tasks/<name>.yaml`` is written into a copy of the tasks
  folder, made the tasks folder through ``MJNAV_TASKS_DIR`` (:mod:`mjnav.resources`);
* a ``python`` block whose first line is ``# my_nav/<module>.py`` is written into the package
  ``my_nav`` in a temporary folder on ``PYTHONPATH``;
* the ``toml`` block (``# pyproject.toml ...``) is installed as the entry points of a distribution
  ``my_nav`` (a ``.dist-info``, what ``pip install`` leaves), on the path of the command-line test only;
* every other ``python`` block runs, in page order and each in a namespace of its own, in one fresh
  interpreter in the temporary folder, so its registrations never reach this test process.
"""

from __future__ import annotations

import os
import re
import shutil
import subprocess
import sys
import tomllib
from pathlib import Path

import pytest

from mjnav.entities import ROBOTS
from mjnav.planners import PLANNERS
from mjnav.resources import TASKS_ENV, tasks_dir
from mjnav.sensors import LIDAR_BACKENDS
from mjnav.stages import STAGES
from mjnav.tasks.design import DESIGNS
from mjnav.world import PEDESTRIAN_MODELS

ROOT = Path(__file__).resolve().parents[1]
PAGE = ROOT / "docs" / "extending.md"
_BLOCK = re.compile(r"^```(\w+)\n(.*?)^```$", re.MULTILINE | re.DOTALL)
_FILE = re.compile(r"#\s*(\S+\.(?:py|yaml))\b")

# Runs the page's examples one after another, each in a namespace of its own; names the failing one.
_RUNNER = """
import sys, traceback
blocks = {blocks!r}
for line, code in blocks:
    try:
        exec(compile(code, f"docs/extending.md:{{line}}", "exec"), {{"__name__": "__docs__"}})
    except Exception:
        traceback.print_exc()
        sys.exit(f"the example at docs/extending.md:{{line}} failed")
print(f"{{len(blocks)}} examples ran")
"""


def blocks(kind: str) -> list[tuple[int, str]]:
    """(line, text) of every ``kind`` code block of the page, in order."""
    text = PAGE.read_text(encoding="utf-8")
    return [(text[:m.start()].count("\n") + 2, m.group(2)) for m in _BLOCK.finditer(text) if m.group(1) == kind]


def _target(code: str) -> str | None:
    """The file a block is (``my_nav/crowd.py``, ``tasks/stage8.yaml``), from its first line; else None."""
    match = _FILE.match(code.splitlines()[0]) if code.strip() else None
    return match.group(1) if match else None


def _entry_points() -> dict[str, dict[str, str]]:
    """The page's ``[project.entry-points."group"]`` tables."""
    (_, text), = blocks("toml")
    return tomllib.loads(text)["project"]["entry-points"]


@pytest.fixture(scope="module")
def workspace(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """A folder with the page's package, its entry points and a tasks folder holding its stage file."""
    root = tmp_path_factory.mktemp("extending")
    shutil.copytree(tasks_dir(), root / "tasks", ignore=shutil.ignore_patterns("recipes"))
    for _, code in [*blocks("yaml"), *blocks("python")]:
        if (target := _target(code)) is not None:
            path = root / target
            path.parent.mkdir(parents=True, exist_ok=True)
            if path.suffix == ".py":
                (path.parent / "__init__.py").touch()
            path.write_text(code, encoding="utf-8")
    info = root / "installed" / "my_nav-0.1.dist-info"  # on the path of the command-line test only
    info.mkdir(parents=True)
    (info / "METADATA").write_text("Metadata-Version: 2.1\nName: my_nav\nVersion: 0.1\n", encoding="utf-8")
    sections = [f"[{group}]\n" + "".join(f"{k} = {v}\n" for k, v in entries.items())
                for group, entries in _entry_points().items()]
    (info / "entry_points.txt").write_text("\n".join(sections), encoding="utf-8")
    return root


def _run(argv: list[str], workspace: Path, installed: bool = False, timeout: float = 300
         ) -> subprocess.CompletedProcess[str]:
    """``argv`` in a fresh interpreter in ``workspace`` with the page's package and stage on its paths
    (and, if ``installed``, the package's entry points)."""
    paths = [str(workspace), *([str(workspace / "installed")] if installed else []), str(ROOT),
             os.environ.get("PYTHONPATH", "")]
    env = {**os.environ, TASKS_ENV: str(workspace / "tasks"), "PYTHONPATH": os.pathsep.join(paths)}
    return subprocess.run(argv, cwd=workspace, env=env, capture_output=True, text=True, timeout=timeout)


def test_the_page_has_every_kind_of_block() -> None:
    """A stage file, the three modules, the examples and the entry points are all on the page."""
    assert _target(blocks("yaml")[0][1]) == "tasks/stage8.yaml"
    modules = {_target(code) for _, code in blocks("python")}
    assert {"my_nav/planners.py", "my_nav/crowd.py", "my_nav/robot.py"} <= modules
    assert len([code for _, code in blocks("python") if _target(code) is None]) >= 5


def test_the_examples_run(workspace: Path) -> None:
    """Every Python example of the page runs as written (stage 8, planner, crowd, robot, design, LiDAR)."""
    examples = [(line, code) for line, code in blocks("python") if _target(code) is None]
    done = _run([sys.executable, "-c", _RUNNER.format(blocks=examples)], workspace)
    assert done.returncode == 0, done.stdout[-3000:] + done.stderr[-6000:]


def test_the_page_documents_every_entry_point_group() -> None:
    """The page names every registry's entry-point group, and its own entry points use them."""
    groups = {r.group for r in (PLANNERS, PEDESTRIAN_MODELS, DESIGNS, LIDAR_BACKENDS, ROBOTS, STAGES)}
    text = PAGE.read_text(encoding="utf-8")
    assert all(f"`{group}`" in text for group in groups)
    assert set(_entry_points()) <= groups


def test_the_command_line_finds_the_entry_points(workspace: Path) -> None:
    """With the page's package installed, ``mjnav evaluate policy=straight planner.speed=...`` runs it."""
    out = workspace / "evals"
    done = _run([sys.executable, "-m", "mjnav", "evaluate", "task=stage1", "policy=straight", "planner.speed=1.5",
                 "episodes=1", "workers=0", f"out={out}", "layout.start_goal_max_distance=6.0"], workspace, True)
    assert done.returncode == 0, done.stderr[-4000:]
    assert (out / "stage1.jsonl").is_file()
    names = _run([sys.executable, "-c", "from mjnav.world import PEDESTRIAN_MODELS as P; "
                  "from mjnav.entities import ROBOTS as R; print(P.get('bounce').source, R.get('omni_mast').source)"],
                 workspace, True)
    assert names.stdout.split() == ["entry", "point", "my_nav", "entry", "point", "my_nav"], names.stderr[-2000:]
