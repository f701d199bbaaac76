"""Malformed input to every public entry point gets an error that names what was wrong.

``CASES`` is also what ``scripts/bad_input.py`` runs to print the table of docs/reliability.md.
Each case: (entry point, input, callable, expected exception type, regex the message must match).
"""

from __future__ import annotations

import functools
import tempfile
from collections.abc import Callable
from pathlib import Path

import gymnasium as gym
import numpy as np
import pytest

import mjnav  # noqa: F401 - registers the ids
from mjnav.config import load_task
from mjnav.control.mpc import Mpc
from mjnav.envs.factory import make_env
from mjnav.envs.gym_env import NavGymEnv
from mjnav.eval.policies import load_policy
from mjnav.export import export_world
from mjnav.geometry.region import compute_region
from mjnav.schema import ConfigError
from mjnav.shipped import resolve as resolve_shipped

ANGLES = np.linspace(0, 2 * np.pi, 360, endpoint=False)
STATE, Q_S, Q_L = np.zeros((3, 2)), np.array([0.5, 0.0]), np.array([1.0, 0.0])


@functools.cache
def _tmp() -> Path:
    folder = Path(tempfile.mkdtemp(prefix="mjnav-bad-input-"))
    (folder / "empty.yaml").write_text("")
    (folder / "broken.yaml").write_text("arena: {size: [10, ")
    (folder / "list.yaml").write_text("- 1\n- 2\n")
    (folder / "empty.pt").write_bytes(b"")
    for name, shipped in (("stage2_checkpoint.pt", "stage2_policy.weights"), ("stage2_policy.pt", "stage2_policy")):
        raw = resolve_shipped(shipped).read_bytes()
        (folder / f"truncated_{name}").write_bytes(raw[: len(raw) // 2])
    (folder / "file").write_text("not a folder")
    return folder


def _env() -> NavGymEnv:
    env = NavGymEnv("stage1", seed=0)
    env.reset(seed=0)
    return env


def _dm_env():
    env = make_env(load_task("stage1"), seed=0)
    env.reset()
    return env


def _polygon() -> np.ndarray:
    return compute_region(np.full(360, 3.0), ANGLES).vertices


def _mismatched_policy() -> None:
    agent = load_policy("stage2_policy")
    agent.begin(NavGymEnv("stage1", overrides=["design=design1"], seed=0).task, 0)


Case = tuple[str, str, Callable[[], object], type, str]
NAN4, ZERO4 = np.full(4, np.nan, np.float32), np.zeros(4, np.float32)

CASES: list[Case] = [
    ("Gymnasium step", "NaN action", lambda: _env().step(NAN4), ValueError, "action must be 4 finite"),
    ("Gymnasium step", "inf action", lambda: _env().step(np.array([np.inf, 0, 0, 0])), ValueError, "finite"),
    ("Gymnasium step", "action of shape (3,)", lambda: _env().step(np.zeros(3)), ValueError, "action must be 4"),
    ("Gymnasium step", "action of shape (2, 4)", lambda: _env().step(np.zeros((2, 4))), ValueError, "action must be 4"),
    ("Gymnasium step", "string action", lambda: _env().step(np.array(list("abcd"))), ValueError, "action: expected 4 numbers"),
    ("Gymnasium step", "None action", lambda: _env().step(None), ValueError, "action must be 4 finite"),
    ("Gymnasium step", "step before reset", lambda: NavGymEnv("stage1").step(ZERO4), RuntimeError, "call reset"),
    ("Gymnasium reset", "episode_seed=-1", lambda: NavGymEnv("stage1").reset(options={"episode_seed": -1}),
     ValueError, "episode_seed: expected an integer"),
    ("Gymnasium reset", "episode_seed='x'", lambda: NavGymEnv("stage1").reset(options={"episode_seed": "x"}),
     ValueError, "episode_seed: expected an integer"),
    ("Gymnasium reset", "seed=2**70", lambda: NavGymEnv("stage1").reset(seed=2**70), ValueError, "seed: expected"),
    ("gymnasium.make", "unknown override key", lambda: gym.make("mjnav/Stage1-v1", overrides=["crowd.bogus=1"]),
     ConfigError, "crowd.bogus: unknown key"),
    ("gymnasium.make", "out-of-range override", lambda: gym.make("mjnav/Stage1-v1", overrides=["crowd.count=-1"]),
     ConfigError, "crowd.count: must be >= 0"),
    ("gymnasium.make", "NaN override", lambda: gym.make("mjnav/Stage1-v1", overrides=["timing.control_period=nan"]),
     ConfigError, "expected a finite number"),
    ("gymnasium.make", "render_mode='human'", lambda: gym.make("mjnav/Stage1-v1", render_mode="human"),
     ValueError, "render_mode"),
    ("dm_env step", "NaN action", lambda: _dm_env().step(np.full(4, np.nan)), ValueError, "action must be 4 finite"),
    ("dm_env step", "action of shape (7,)", lambda: _dm_env().step(np.zeros(7)), ValueError, "action must be 4"),
    ("compute_region", "a NaN range", lambda: compute_region(np.where(np.arange(360) == 5, np.nan, 3.0), ANGLES),
     ValueError, r"non-finite values at beam indices \[5\]"),
    ("compute_region", "an inf range", lambda: compute_region(np.where(np.arange(360) == 5, np.inf, 3.0), ANGLES),
     ValueError, r"beam indices \[5\]"),
    ("compute_region", "100 ranges for 360 angles", lambda: compute_region(np.full(100, 3.0), ANGLES),
     ValueError, "shapes differ"),
    ("compute_region", "empty scan", lambda: compute_region(np.array([]), np.array([])), ValueError, "at least"),
    ("compute_region", "string ranges", lambda: compute_region(np.full(360, "3"), ANGLES), ValueError, "real numbers"),
    ("compute_region", "a NaN angle", lambda: compute_region(np.full(360, 3.0), np.where(np.arange(360) == 3, np.nan, ANGLES)),
     ValueError, "angles: non-finite"),
    ("Mpc.solve", "NaN state", lambda: Mpc().solve(np.full((3, 2), np.nan), Q_S, Q_L, _polygon()), ValueError, "non-finite"),
    ("Mpc.solve", "state of shape (6,)", lambda: Mpc().solve(np.zeros(6), Q_S, Q_L, _polygon()), ValueError, "shape"),
    ("Mpc.solve", "inf reference", lambda: Mpc().solve(STATE, np.array([np.inf, 0.0]), Q_L, _polygon()),
     ValueError, "non-finite"),
    ("Mpc.solve", "NaN polygon", lambda: Mpc().solve(STATE, Q_S, Q_L, np.full((60, 2), np.nan)), ValueError, "polygon"),
    ("Mpc.solve", "2-vertex polygon", lambda: Mpc().solve(STATE, Q_S, Q_L, _polygon()[:2]), ValueError, "K >= 3"),
    ("load_task", "empty YAML file", lambda: load_task(_tmp() / "empty.yaml"), ConfigError, "empty task file"),
    ("load_task", "truncated YAML file", lambda: load_task(_tmp() / "broken.yaml"), ConfigError, "not valid YAML"),
    ("load_task", "YAML list at top level", lambda: load_task(_tmp() / "list.yaml"), ConfigError, "must be a mapping"),
    ("load_task", "missing YAML file", lambda: load_task(_tmp() / "missing.yaml"), ConfigError, "does not exist"),
    ("load_task", "unknown stage", lambda: load_task("stage9"), ConfigError, "unknown task 'stage9'"),
    ("load_task", "override without '='", lambda: load_task("stage1", ["crowd.count"]), ConfigError, "expected key=value"),
    ("load_task", "override of wrong type", lambda: load_task("stage1", ["crowd.count=abc"]), ConfigError,
     "expected an integer"),
    ("load_task", "control_period=0", lambda: load_task("stage1", ["timing.control_period=0"]), ConfigError, "must be > 0"),
    ("load_policy", "empty file", lambda: load_policy(_tmp() / "empty.pt"), ValueError, "not a loadable"),
    ("load_policy", "truncated checkpoint", lambda: load_policy(_tmp() / "truncated_stage2_checkpoint.pt"),
     ValueError, "not a loadable"),
    ("load_policy", "truncated TorchScript policy", lambda: load_policy(_tmp() / "truncated_stage2_policy.pt"),
     ValueError, "not a loadable"),
    ("load_policy", "missing file", lambda: load_policy(_tmp() / "none.pt"), FileNotFoundError, "nor an existing path"),
    ("Agent.begin", "399-input policy on a 372-value design-1 task", _mismatched_policy, ValueError, "takes 399 observation values"),
    ("export_world", "steps=0", lambda: export_world(load_task("stage1"), 0, _tmp() / "out", steps=0), ValueError, "steps"),
    ("export_world", "seed=-1", lambda: export_world(load_task("stage1"), -1, _tmp() / "out", steps=2), ValueError, "seed"),
    ("export_world", "out is a file", lambda: export_world(load_task("stage1"), 0, _tmp() / "file", steps=2),
     FileExistsError, "is a file"),
]


@pytest.mark.parametrize("case", CASES, ids=[f"{c[0]}: {c[1]}" for c in CASES])
def test_bad_input_is_a_named_error(case: Case) -> None:
    """The call raises the expected type with a message naming the problem."""
    _, _, call, kind, pattern = case
    with pytest.raises(kind, match=pattern):
        call()
