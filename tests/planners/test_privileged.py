"""Privileged information is declared: a planner receives only the ground truth it names in
``privileged``, and nothing when it names none."""

from __future__ import annotations

import numpy as np
import pytest

from mjnav.planners import make_planner, resolve_planner
from mjnav.planners.base import PRIVILEGED_FIELDS, PlannerInput, declared_privileged


class _Recorder:
    """A planner that brakes and keeps every input it gets."""

    def __init__(self) -> None:
        self.inputs: list[PlannerInput] = []

    def reset(self, config, rng) -> None:
        self.inputs = []

    def act(self, inp: PlannerInput) -> np.ndarray:
        self.inputs.append(inp)
        return -np.asarray(inp.acceleration)


class _Blind(_Recorder):
    """Declares nothing and asserts it sees no pedestrian."""

    def act(self, inp: PlannerInput) -> np.ndarray:
        assert inp.pedestrian_positions is None and inp.pedestrian_velocities is None
        assert inp.pedestrian_radii is None and inp.pedestrian_goals is None
        assert inp.pedestrians.shape == (0, 3)
        return super().act(inp)


class _Oracle(_Recorder):
    privileged = PRIVILEGED_FIELDS


class _PositionsOnly(_Recorder):
    privileged = frozenset({"positions"})


def _run(planner: _Recorder, overrides: tuple[str, ...] = (), steps: int = 4) -> _Recorder:
    """``steps`` control steps of stage5 episode 3 with ``planner`` in place of the action layer."""
    from mjnav.envs.gym_env import NavGymEnv

    env = NavGymEnv("stage5", overrides=list(overrides) or None, seed=0)
    env.task.planner = planner
    env.reset(options={"episode_seed": 3})
    for _ in range(steps):
        env.step(np.zeros(4, np.float32))
    env.close()
    return planner


def test_a_planner_that_declares_nothing_gets_no_pedestrians():
    """No privileged attribute: every input's pedestrian fields are None (the planner asserts it)."""
    assert len(_run(_Blind()).inputs) == 4


def test_only_the_declared_fields_are_filled():
    """privileged={'positions'}: positions only (radii NaN in the [x, y, r] view), the rest None."""
    inp = _run(_PositionsOnly(), steps=1).inputs[0]
    assert inp.pedestrian_positions.shape == (10, 2) and inp.pedestrian_radii is None
    assert inp.pedestrian_velocities is None and inp.pedestrian_goals is None
    assert np.isnan(inp.pedestrians[:, 2]).all()


def test_an_oracle_gets_positions_velocities_radii_and_goals():
    """All four declared (random walk): positions and radii of the 10 pedestrians, velocities equal to
    their displacement over the period's last substep (speeds of a walking crowd), goals NaN (the
    random walk has none); every array is read-only."""
    inputs = _run(_Oracle()).inputs
    first, last = inputs[0], inputs[-1]
    assert first.pedestrian_positions.shape == (10, 2) and first.pedestrian_radii.shape == (10,)
    assert np.all((first.pedestrian_radii >= 0.1) & (first.pedestrian_radii <= 0.4))
    speeds = np.hypot(*last.pedestrian_velocities.T)
    assert np.all((speeds > 0.2) & (speeds < 0.7))
    mean_velocity = (last.pedestrian_positions - inputs[-2].pedestrian_positions) / 0.1
    assert np.allclose(last.pedestrian_velocities, mean_velocity, atol=0.15)
    assert np.isnan(last.pedestrian_goals).all()
    assert not any(a.flags.writeable for a in (first.pedestrian_positions, first.pedestrian_velocities,
                                               first.pedestrian_radii, first.pedestrian_goals))


def test_goals_come_from_a_crowd_model_with_goals():
    """Under social force the declared goals are the model's: finite points inside the arena."""
    inp = _run(_Oracle(), ("crowd.model=social_force",), steps=2).inputs[-1]
    assert inp.pedestrian_goals.shape == (10, 2) and np.isfinite(inp.pedestrian_goals).all()


def test_mpc_crowd_declares_positions_and_radii():
    """mpc_crowd reads positions and radii (it differences velocities itself); teb and mpc_goal read none."""
    assert resolve_planner("mpc_crowd").privileged == {"positions", "radii"}
    assert declared_privileged(make_planner("mpc_crowd")) == {"positions", "radii"}
    assert resolve_planner("teb").privileged == frozenset() == resolve_planner("mpc_goal").privileged


@pytest.mark.parametrize("claim", ["positions", frozenset({"ages"}), 3])
def test_a_bad_declaration_is_refused(claim):
    """A plain string, an unknown name or a non-set is a ValueError naming the known fields."""
    planner = type("Bad", (), {"privileged": claim})
    with pytest.raises(ValueError, match="privileged"):
        declared_privileged(planner)
