"""Outside planners: ``module:Class``, ``file.py:Class`` and entry points resolve through one resolver,
fail with clear messages, and the documented example runs through evaluate, render and plot."""

from __future__ import annotations

import json
import os
import re
import shutil
import subprocess
import sys
from pathlib import Path

import pytest

from mjnav.eval.policies import load_policy
from mjnav.planners import PlannerError, is_planner_spec, make_planner, planner_config, resolve_planner
from mjnav.schema import ConfigError

ROOT = Path(__file__).resolve().parents[2]
EXAMPLE = ROOT / "docs" / "examples" / "goal_seeker.py"
CHEAP = ("task.timing.episode_steps=15",)

PLANNER_FILE = '''
import dataclasses
import numpy as np


@dataclasses.dataclass(frozen=True)
class StillConfig:
    gain: float = 1.0


class Still:
    config_class = StillConfig

    def __init__(self, config=None):
        self.config = config or StillConfig()

    def reset(self, config, rng):
        pass

    def act(self, inp):
        return -self.config.gain * np.asarray(inp.acceleration)


class NotAPlanner:
    pass
'''


def _write(folder: Path, name: str, text: str) -> Path:
    path = folder / name
    path.write_text(text, encoding="utf-8")
    return path


def _mjnav(args: list[str], cwd: Path, extra_path: str = "") -> subprocess.CompletedProcess:
    """``python -m mjnav ARGS`` in ``cwd`` with this checkout first on the path."""
    env = {**os.environ, "PYTHONPATH": os.pathsep.join(p for p in (str(ROOT), extra_path) if p)}
    return subprocess.run([sys.executable, "-m", "mjnav", *args], cwd=cwd, env=env, capture_output=True,
                          text=True, timeout=600)


def test_file_spec_loads_under_a_stable_module_name(tmp_path):
    """dir/file.py:Class loads the file once per process under a name from its absolute path; the
    source is the absolute path, parameters and overrides come from its config class."""
    path = _write(tmp_path, "still.py", PLANNER_FILE)
    first = resolve_planner(f"{path}:Still")
    again = resolve_planner(f"{os.path.relpath(path)}:Still")
    assert first.factory is again.factory and first.factory.__module__ in sys.modules
    assert first.factory.__module__.startswith("mjnav_planner_file_") and first.source == f"{path.resolve()}:Still"
    assert first.name == "still.py:Still" and first.files == (path.resolve(),)
    assert first.params(["gain=2.5"]) == {"gain": 2.5} and first.privileged == frozenset()
    assert make_planner(f"{path}:Still", ["gain=3"]).config.gain == 3.0
    agent = load_policy(f"{path}:Still", planner=("gain=2",))
    assert agent.kind == "planner" and agent.planner.planner.config.gain == 2.0 and agent.privileged == frozenset()


def test_module_spec_and_overrides(tmp_path, monkeypatch):
    """package.module:Class is imported from the path; planner.<field>= sets its config; a bad field fails."""
    _write(tmp_path, "outside_still_mod.py", PLANNER_FILE)
    monkeypatch.syspath_prepend(str(tmp_path))
    spec = "outside_still_mod:Still"
    assert is_planner_spec(spec) and resolve_planner(spec).source == spec
    assert planner_config(spec, ["gain=0.5"]).gain == 0.5
    with pytest.raises(ConfigError, match="nope"):
        planner_config(spec, ["nope=1"])
    sys.modules.pop("outside_still_mod", None)


@pytest.mark.parametrize(("spec", "match"), [
    ("{dir}/missing.py:Still", "no such file"),
    ("{dir}/still.py:Nope", r"has no 'Nope' \(its classes: NotAPlanner, Still, StillConfig\)"),
    ("{dir}/still.py:NotAPlanner", "NotAPlanner is not a Planner"),
    ("{dir}/broken.py:Still", "importing .*broken.py' failed: ZeroDivisionError: division by zero"),
    ("no_such_module_xyz:Thing", "importing module 'no_such_module_xyz' failed: ModuleNotFoundError"),
    ("{dir}/bad_claim.py:Peeker", r"unknown privileged \['ages'\]"),
])
def test_errors_are_clear(tmp_path, spec, match):
    """A missing file, an absent class, a non-planner, a failing import and a bad privileged declaration
    each raise a PlannerError (a ValueError) that names the problem."""
    _write(tmp_path, "still.py", PLANNER_FILE)
    _write(tmp_path, "broken.py", "x = 1 / 0\n")
    _write(tmp_path, "bad_claim.py", PLANNER_FILE.replace("class Still:", "class Peeker:\n    privileged = "
                                                                         "frozenset({'positions', 'ages'})\n"))
    with pytest.raises(PlannerError, match=match):
        load_policy(spec.format(dir=tmp_path))


def test_a_python_file_without_class_says_how_to_name_it(tmp_path):
    """policy=file.py (no :Class) answers with the form to use instead of 'not a baseline'."""
    path = _write(tmp_path, "still.py", PLANNER_FILE)
    with pytest.raises(FileNotFoundError, match="name its class"):
        load_policy(str(path))


def test_entry_point_planner_in_another_process(tmp_path):
    """A package's ``mjnav.planners`` entry point is found by name in a fresh process (as every
    evaluation worker is), with its config class."""
    site = tmp_path / "site"
    (site / "outside_pkg").mkdir(parents=True)
    _write(site / "outside_pkg", "__init__.py", "")
    _write(site / "outside_pkg", "still.py", PLANNER_FILE)
    info = site / "outside_pkg-0.1.dist-info"
    info.mkdir()
    _write(info, "METADATA", "Metadata-Version: 2.1\nName: outside-pkg\nVersion: 0.1\n")
    _write(info, "entry_points.txt", "[mjnav.planners]\nstill_ep = outside_pkg.still:Still\n")
    code = ("from mjnav.planners import PLANNERS, resolve_planner;"
            "found = resolve_planner('still_ep');"
            "print(found.source, found.config_class.__name__, found.make(['gain=2']).config.gain,"
            " PLANNERS.get('still_ep').source)")
    env = {**os.environ, "PYTHONPATH": os.pathsep.join([str(ROOT), str(site)])}
    done = subprocess.run([sys.executable, "-c", code], env=env, capture_output=True, text=True, timeout=300)
    assert done.returncode == 0, done.stderr
    assert done.stdout.split() == ["still_ep", "StillConfig", "2.0", "entry", "point", "outside-pkg"]


def test_the_documented_example_is_the_example_file():
    """docs/planners.md shows docs/examples/goal_seeker.py in full, as it is."""
    text = (ROOT / "docs" / "planners.md").read_text(encoding="utf-8")
    blocks = re.findall(r"```python\n(.*?)```", text, flags=re.S)
    assert EXAMPLE.read_text(encoding="utf-8") in blocks


@pytest.fixture(scope="module")
def example_dir(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """An empty folder outside the package holding only the example planner file."""
    folder = tmp_path_factory.mktemp("outside")
    shutil.copy(EXAMPLE, folder / "goal_seeker.py")
    return folder


def test_example_evaluates_in_workers(example_dir):
    """`mjnav evaluate policy=goal_seeker.py:GoalSeeker planner.speed=1.2` with two worker processes
    writes every episode with the planner's source, hash, parameters and (no) privileged data."""
    done = _mjnav(["evaluate", "task=stage5", "policy=goal_seeker.py:GoalSeeker", "episodes=3", "workers=2",
                   "out=ev", "planner.speed=1.2", *CHEAP], example_dir)
    assert done.returncode == 0, done.stderr
    records = [json.loads(line) for line in (example_dir / "ev" / "stage5.jsonl").read_text().splitlines()]
    assert [r["index"] for r in records] == [0, 1, 2]
    first = records[0]
    assert first["planner_source"] == f"{(example_dir / 'goal_seeker.py').resolve()}:GoalSeeker"
    assert first["planner_params"]["speed"] == 1.2 and first["planner_privileged"] == []
    assert first["planner_sha256"] == resolve_planner(str(example_dir / "goal_seeker.py") + ":GoalSeeker").sha256()
    assert "slowed" in first["planner_stats"] and "goal_seeker.py:GoalSeeker |" in done.stdout
    assert "(privileged)" not in done.stdout


def test_example_plots(example_dir):
    """`mjnav plot episode policy=goal_seeker.py:GoalSeeker` writes the figure."""
    done = _mjnav(["plot", "episode", "task=stage5", "policy=goal_seeker.py:GoalSeeker", "out=episode.png",
                   "planner.speed=0.8", *CHEAP], example_dir)
    assert done.returncode == 0, done.stderr
    assert (example_dir / "episode.png").stat().st_size > 0


def test_example_renders(example_dir):
    """`mjnav render policy=goal_seeker.py:GoalSeeker frames=5` writes an MP4 (skipped without off-screen GL)."""
    from mjnav.viz.gl import probe_gl_backend

    if not any(probe_gl_backend(b) for b in ("egl", "osmesa")):
        pytest.skip("no off-screen GL backend (needs libegl1 + libgl1-mesa-dri, or libosmesa6)")
    done = _mjnav(["render", "task=stage5", "policy=goal_seeker.py:GoalSeeker", "frames=5", "width=160",
                   "height=160", "out=episode.mp4"], example_dir)
    assert done.returncode == 0, done.stderr
    assert (example_dir / "episode.mp4").stat().st_size > 0


def test_cli_reports_a_bad_planner_in_one_line(example_dir):
    """A class that does not exist: exit code 2 and one error line naming it, no traceback."""
    done = _mjnav(["evaluate", "task=stage5", "policy=goal_seeker.py:Nope", "episodes=1", "workers=0", "out=bad"],
                  example_dir)
    assert done.returncode == 2 and "has no 'Nope'" in done.stderr and "Traceback" not in done.stderr
