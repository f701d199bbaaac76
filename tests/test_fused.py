"""Fused substeps: one compiled call per control period, bit-identical to the Python substep loop."""

from __future__ import annotations

import math

import numpy as np
import pytest

from mjnav import fused
from mjnav.config import load_task
from mjnav.sim import NavSim
from tests.test_sim import _replace


def test_supported_here():
    """This platform's MuJoCo library and mjData layout check out (else every period runs in Python)."""
    support = fused.fused_support()
    assert isinstance(support, tuple), support


def test_probe_rejects_a_wrong_field_offset():
    step, offset = fused.fused_support()
    with pytest.raises(RuntimeError, match="ncon offset"):
        fused._probe(step, offset + 4)


@pytest.mark.parametrize("x", [0.5, -3.0, 250.0, -250.0, math.inf, -math.inf, math.nan])
def test_clamp_is_pythons_min_max(x):
    expected = min(max(x, -200.0), 200.0)
    got = fused._clamp(x, 200.0)
    assert (math.isnan(got) and math.isnan(expected)) or got == expected


def _world(sim, physics, collided):
    data = physics.data.ptr
    return [data.qpos.copy(), data.qvel.copy(), data.ctrl.copy(), data.mocap_pos.copy(), collided,
            sim.robot.acceleration]


def _trace(config, fused_substeps: bool, periods: int = 150) -> tuple[list, int]:
    sim = NavSim(config, fused=fused_substeps)
    physics = sim.make_physics()
    rng, jerks = np.random.default_rng(4), np.random.default_rng(9).normal(scale=8.0, size=(periods, 2))
    sim.initialize_episode(physics, rng)
    trace, collisions = [], 0
    for jerk in jerks:
        sim.control_step(physics, jerk)
        collided = sim.robot_in_collision(physics)
        trace.append(_world(sim, physics, collided))
        if collided[0]:
            collisions += 1
            sim.initialize_episode(physics, rng)
    assert sim.fused is fused_substeps and sim.fused_unavailable is None
    return trace, collisions


@pytest.mark.parametrize("model", ["random_walk", "social_force"])
def test_fused_periods_equal_python_substeps(model):
    """Positions, velocities, forces, pedestrians and collisions match bit for bit, period by period."""
    config = _replace(load_task("stage7"), crowd={"model": model})
    ours, collisions = _trace(config, True)
    theirs, _ = _trace(config, False)
    assert collisions >= 2  # contacts (found mid-period) are part of the comparison
    for a, b in zip(ours, theirs, strict=True):
        for x, y in zip(a, b, strict=True):
            np.testing.assert_array_equal(x, y)


def test_unavailable_support_falls_back_to_python(monkeypatch):
    """Where the library or layout does not check out, the sim says why and steps in Python."""
    monkeypatch.setattr(fused, "fused_support", lambda: "RuntimeError: no MuJoCo shared library")
    config = load_task("stage6")
    sim = NavSim(config)
    physics = sim.make_physics()
    sim.initialize_episode(physics, np.random.default_rng(2))
    sim.control_step(physics, np.array([3.0, -1.0]))
    assert not sim.fused and "no MuJoCo shared library" in sim.fused_unavailable
    reference = NavSim(config, fused=False)
    twin = reference.make_physics()
    reference.initialize_episode(twin, np.random.default_rng(2))
    reference.control_step(twin, np.array([3.0, -1.0]))
    np.testing.assert_array_equal(physics.data.qpos, twin.data.qpos)


def test_installed_callback_means_python_substeps(monkeypatch):
    """While a MuJoCo callback is installed the period runs in Python, and the callback sees its steps."""
    import mujoco

    config = load_task("stage6")
    sim = NavSim(config)
    physics = sim.make_physics()
    sim.initialize_episode(physics, np.random.default_rng(2))
    sim.control_step(physics, np.array([3.0, -1.0]))  # fused

    def refuse(*args):
        raise AssertionError("fused substeps while a callback is installed")

    monkeypatch.setattr(fused.FusedStepper, "run", refuse)
    times = []
    mujoco.set_mjcb_control(lambda model, data: times.append(data.time))
    try:
        assert fused.callbacks_installed()
        assert isinstance(fused.fused_support(), str)
        sim.control_step(physics, np.array([3.0, -1.0]))
    finally:
        mujoco.set_mjcb_control(None)
    assert not fused.callbacks_installed() and sim.fused  # fused again from the next period
    assert len(set(times)) == config.timing.substeps + 1  # every physics step's start, and the sync


def test_period_without_a_command_runs_in_python():
    """Right after a reset (no apply_command: a one-step plan, no crowd rows) the period is the Python loop's."""
    config = load_task("stage7")
    states = []
    for fused_substeps in (True, False):
        sim = NavSim(config, fused=fused_substeps)
        physics = sim.make_physics()
        sim.initialize_episode(physics, np.random.default_rng(3))
        physics.data.qvel[:2] = 0.4, -0.2
        sim.run_period(physics)
        states.append((physics.data.qpos.copy(), physics.data.mocap_pos.copy(), physics.data.time))
    for a, b in zip(*states, strict=True):
        np.testing.assert_array_equal(a, b)
