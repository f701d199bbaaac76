"""NavEnvironment steps exactly as composer.Environment and still reports an invalid physics state."""

import dm_env
import numpy as np
import pytest
from dm_control import composer
from dm_control.rl import control

from mjnav.config import load_task
from mjnav.envs.environment import NavEnvironment
from mjnav.tasks.nav import CrowdNavTask


def _make(cls, **kwargs):
    return cls(
        CrowdNavTask(load_task("stage7")),
        random_state=3,
        strip_singleton_obs_buffer_dim=True,
        recompile_mjcf_every_episode=False,
        legacy_step=kwargs.pop("legacy_step", False),
        **kwargs,
    )


def _rollout(env, steps: int = 40) -> list:
    """Step types, observations, rewards, discounts (across episode ends: composer resets after LAST)."""
    actions = np.random.default_rng(0).normal(size=(steps, 4)).astype(np.float32)
    out = [env.reset().observation["observation"].copy()]
    for a in actions:
        ts = env.step(a)
        out += [int(ts.step_type), ts.observation["observation"].copy(), ts.reward, ts.discount]
    out.append(env.physics.data.qpos.copy())
    return out


@pytest.mark.parametrize("legacy_step", [False, True])
def test_same_rollout_as_composer(legacy_step: bool) -> None:
    """Over several episodes, everything a step returns and the final state match composer's bit for bit."""
    ours = _rollout(_make(NavEnvironment, legacy_step=legacy_step), steps=240)
    theirs = _rollout(_make(composer.Environment, legacy_step=legacy_step), steps=240)
    assert ours[1:-1:4].count(int(dm_env.StepType.LAST)) >= 2  # episodes ended and restarted
    assert len(ours) == len(theirs)
    for a, b in zip(ours, theirs):
        np.testing.assert_array_equal(a, b)


def _poison_at_substep(env, substep: int) -> None:
    """The robot position turns NaN before physics substep ``substep`` of every control step."""
    task, original = env.task, env.task.before_substep
    count = {"k": 0}

    def before_substep(physics, action, random_state):
        original(physics, action, random_state)
        if count["k"] % task.physics_steps_per_control_step == substep:
            physics.data.qpos[0] = np.nan
        count["k"] += 1

    task.before_substep = before_substep


@pytest.mark.parametrize("cls", [NavEnvironment, composer.Environment])
def test_mid_step_warning_raises_physics_error(cls) -> None:
    """A MuJoCo warning at a middle substep raises PhysicsError naming it, as composer does."""
    env = _make(cls)
    env.reset()
    _poison_at_substep(env, 2)
    with pytest.raises(control.PhysicsError, match="mjWARN_BADQPOS"):
        env.step(np.zeros(4, dtype=np.float32))


def test_suppressed_warning_is_logged_not_raised(caplog) -> None:
    """Under Physics.suppress_physics_errors the warning is logged and the step completes."""
    env = _make(NavEnvironment)
    env.reset()
    _poison_at_substep(env, 1)
    with env.physics.suppress_physics_errors():
        ts = env.step(np.zeros(4, dtype=np.float32))
    assert np.all(np.isfinite(ts.observation["observation"]))
    assert "mjWARN_BADQPOS" in caplog.text


def test_substep_hooks_of_others_still_run() -> None:
    """An extra substep hook turns fused substeps off: it runs every substep, the rollout is composer's."""
    calls = []
    ours = _make(NavEnvironment)
    ours.add_extra_hook("before_substep", lambda physics, action, random_state: calls.append(1))
    theirs = _make(composer.Environment)
    theirs.add_extra_hook("before_substep", lambda physics, action, random_state: None)
    for a, b in zip(_rollout(ours, steps=10), _rollout(theirs, steps=10), strict=True):
        np.testing.assert_array_equal(a, b)
    assert len(calls) == 10 * ours.task.physics_steps_per_control_step
    assert not ours._can_fuse() and ours.task.fused_substeps


def test_step_stages_are_the_task_step() -> None:
    """Four stages (before-step hook, substeps, sense, score) with the state of ``step_task``."""
    staged, whole = _make(NavEnvironment), _make(NavEnvironment)
    staged.reset(), whole.reset()
    assert staged.can_step_task() and staged.task.splits_after_step
    for action in np.random.default_rng(1).normal(size=(5, 4)).astype(np.float32):
        assert sum(1 for _ in staged.step_stages(action)) == 3  # yields between four stages
        whole.step_task(action)
        np.testing.assert_array_equal(staged.task.observation, whole.task.observation)
        assert staged.task.get_reward(None) == whole.task.get_reward(None)
    np.testing.assert_array_equal(staged.physics.data.qpos, whole.physics.data.qpos)


def test_an_overridden_after_step_runs_whole() -> None:
    """A task whose after-step hook is replaced is not split into sense and score: the hook runs."""
    env = _make(NavEnvironment)
    env.reset()
    calls, original = [], env.task.after_step

    def after_step(physics, random_state):
        calls.append(1)
        original(physics, random_state)

    env.task.after_step = after_step
    assert not env.task.splits_after_step
    assert sum(1 for _ in env.step_stages(np.zeros(4, dtype=np.float32))) == 2
    assert calls == [1]
