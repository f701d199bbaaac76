"""The imitation lab script behind the shipped goal-frame policies
(``experiments/imitation.py``): its teacher, written in Ours' action space, asks
Ours' layer for the long-term point ``mpc_gap`` would choose."""

from __future__ import annotations

import importlib.util
import math

import numpy as np
import pytest

from tests._scripts import ROOT

SCRIPT = ROOT / "experiments" / "imitation.py"


def _load(monkeypatch: pytest.MonkeyPatch):
    monkeypatch.setenv("IMIT_OVERRIDES", "action.heading=goal,observation.frame=goal")
    spec = importlib.util.spec_from_file_location("imitation", SCRIPT)
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


def test_teacher_action_maps_to_mpc_gaps_long_term_point(monkeypatch: pytest.MonkeyPatch) -> None:
    """Through map_action_values (goal heading) the teacher's logits give mpc_gap's Q_l."""
    from mjnav.control.action import map_action_values, radii
    from mjnav.planners.mpc_goal import MpcGapConfig, reference_points

    imitation = _load(monkeypatch)
    assert imitation.OVERRIDES[-2:] == ["action.heading=goal", "observation.frame=goal"]
    env = imitation.make_env("stage3")
    checked = 0
    try:
        env.reset(options={"episode_seed": 2**32 + 123})
        for _ in range(25):
            logits = imitation.teacher_action(env)
            p, v, a = env.task.sim.robot_state(env._env.physics)
            core = env.task.core
            goal = np.asarray(core.goal) - p
            _, q_l, inside = reference_points(core.region, goal, radii(v, a, core.config.action)[0], 0.9,
                                              MpcGapConfig())
            squashed = 1.0 / (1.0 + np.exp(-logits))
            points = map_action_values([*squashed.tolist(), *v, *a, *goal], core.region, core.config.action)
            if not inside and 0.021 < squashed[3] < 0.979:
                np.testing.assert_allclose(points.q_l, q_l, atol=1e-6)
                checked += 1
            _, _, term, trunc, _ = env.step(logits.astype(np.float32))
            if term or trunc:
                break
    finally:
        env.close()
    assert checked >= 5
    assert math.isclose(squashed[0], imitation.A_S, rel_tol=1e-6)
