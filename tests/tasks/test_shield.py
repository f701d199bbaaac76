"""The action layer's crowd shield (``shield.enabled``): the paper's layer bit for bit without
tracks; with moving pedestrians it runs the tracker and replaces unsafe long-term points."""

from __future__ import annotations

import numpy as np
import pytest

from mjnav.config import load_task


def _rollout(stage: str, shield: bool, steps: int = 40, seed: int = 5):
    """Positions, the task's shield-override count and whether it ran the tracker, for a fixed
    action sequence (the same raw actions with and without the shield)."""
    from mjnav.envs.gym_env import NavGymEnv

    env = NavGymEnv(stage, overrides=[f"shield.enabled={str(shield).lower()}"], seed=0)
    env.reset(options={"episode_seed": seed})
    actions = np.random.default_rng(0).normal(0.0, 1.0, (steps, 4)).astype(np.float32)
    positions, tracked = [], env.task.tracks is not None
    for action in actions:
        env.step(action)
        positions.append(env.task.sim.robot_state(env.physics)[0].copy())
        if env.task.outcome.done:
            break
    overrides = env.task.core.counters["shield_overrides"]
    env.close()
    return np.array(positions), overrides, tracked


def test_the_shield_is_off_by_default():
    assert load_task("stage6").shield.enabled is False


def test_a_design_without_reference_points_cannot_be_shielded():
    """Designs 1-3 act with velocities or Q_l alone: a clear error, not a shield that never acts."""
    with pytest.raises(ValueError, match="shield.enabled: .*design 'design1'"):
        load_task("stage6", ["design=design1", "shield.enabled=true"])


def test_without_tracks_the_shielded_layer_is_the_papers():
    """Stage 2 (static obstacles only; this episode): the tracker confirms no moving track, nothing
    is replaced, and the robot moves exactly as without the shield."""
    plain, _, tracked_plain = _rollout("stage2", False)
    shielded, overrides, tracked = _rollout("stage2", True)
    assert tracked and not tracked_plain
    assert overrides == 0
    np.testing.assert_array_equal(shielded, plain)


def test_in_a_crowd_the_shield_replaces_unsafe_points():
    """Stage 6: random actions walk into pedestrians; the shield steps in and the path changes."""
    plain, _, _ = _rollout("stage6", False)
    shielded, overrides, _ = _rollout("stage6", True)
    assert overrides > 0
    n = min(len(plain), len(shielded))
    assert not np.array_equal(shielded[:n], plain[:n])
