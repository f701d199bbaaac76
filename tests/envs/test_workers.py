"""A worker's group of real environments: stepped stage by stage, with the results of stepping in turn."""

from __future__ import annotations

import time

import gymnasium as gym
import numpy as np
import pytest

from mjnav.envs.bounded import BoundedNavGymEnv
from mjnav.envs.gym_env import NavGymEnv
from mjnav.envs.workers import _EnvGroup, _layout, _views, rollout_parts, step_in_stages

#: Short episodes (timeouts), a wide goal (successes), a privileged critic block and a crowd.
OVERRIDES = ["timing.episode_steps=6", "reward.goal_tolerance=5.0", "observation.critic_pedestrians=2", "crowd.count=6"]


class InTurn(gym.Wrapper):
    """A NavGymEnv without ``step_stages`` (wrappers do not forward it): the group steps it in turn."""


def _group(staged: bool, count: int = 3, cls: type = NavGymEnv) -> _EnvGroup:
    def make(index: int) -> gym.Env:
        env = cls("stage5", overrides=OVERRIDES)
        return env if staged else InTurn(env)

    group = _EnvGroup(make, range(count), seed=11)
    env = group.envs[0]
    layout, size = _layout(count, env.observation_space.shape[0], env.action_space.shape[0],
                           env.unwrapped.critic_size)
    group.buf = _views(bytearray(size), layout)
    group.reset()
    return group


def _trace(group: _EnvGroup, steps: int, scale: float = 3.0) -> list:
    """Buffers and sums of ``steps`` group steps with ``scale``·N(0, 1) actions (clipped to [-1, 1]
    when ``scale`` < 1, for the bounded environment)."""
    rng = np.random.default_rng(5)
    out = []
    for k in range(steps):
        raw = scale * rng.normal(size=group.buf["actions"].shape)
        group.buf["actions"][:] = np.clip(raw, -1.0, 1.0) if scale < 1.0 else raw
        group.buf["force"][:] = False
        group.buf["force"][1] = k % 4 == 3  # the adapter's forced truncation
        terms, mpc_sum, mpc_count, _, _ = group.step()
        out.append(({name: array.copy() for name, array in group.buf.items()}, terms, mpc_sum, mpc_count))
    return out


@pytest.mark.parametrize("cls", [NavGymEnv, BoundedNavGymEnv])
def test_stages_give_the_results_in_turn(cls: type) -> None:
    """Observations, critic blocks, rewards, flags, outcomes and the summed terms match bit for bit
    (also for the bounded v2 environment, whose actions are mapped and observations clipped)."""
    staged, in_turn = _group(True, cls=cls), _group(False, cls=cls)
    assert staged.staged and not in_turn.staged
    scale = 0.9 if cls is BoundedNavGymEnv else 3.0
    ours, theirs = _trace(staged, 20, scale), _trace(in_turn, 20, scale)
    outcomes = np.array([buffers["outcome"] for buffers, *_ in ours])
    assert {0, 1, 3} <= set(outcomes.ravel().tolist())  # running, successes and timeouts (resets)
    for (buf_a, *sums_a), (buf_b, *sums_b) in zip(ours, theirs, strict=True):
        for name in buf_a:
            np.testing.assert_array_equal(buf_a[name], buf_b[name], err_msg=name)
        assert sums_a == sums_b


def test_a_failing_stage_names_its_environment() -> None:
    """An exception in one environment's stage surfaces with that environment's index."""
    group = _group(True)

    def refuse(*args, **kwargs):
        raise ValueError("planner refused")

    group.envs[1].task.core.plan = refuse
    with pytest.raises(ValueError, match="planner refused") as info:
        group.step()
    assert "(in environment 1)" in info.value.__notes__


def test_each_environment_times_its_own_physics() -> None:
    """The physics timer of a staged step leaves out the other environments' stages."""
    group = _group(True, count=2)
    plan = group.envs[1].task.core.plan

    def slow_plan(*args, **kwargs):
        time.sleep(0.2)
        return plan(*args, **kwargs)

    group.envs[1].task.core.plan = slow_plan
    for env in group.envs:
        env.task.timers["physics"] = 0.0
    start = time.perf_counter()
    group.step()
    assert time.perf_counter() - start >= 0.2
    assert all(0.0 < env.task.timers["physics"] < 0.1 for env in group.envs)


def test_an_overridden_step_is_stepped_in_turn() -> None:
    """A subclass (or instance) whose ``step`` differs from its stages is never stepped in stages."""

    class Halved(NavGymEnv):
        def step(self, action):
            return super().step(0.5 * np.asarray(action))

    assert not _group(True, count=1, cls=Halved).staged
    group = _group(True, count=2)
    group.envs[1].step = lambda action: NavGymEnv.step(group.envs[1], action)
    assert not group.staged


def test_a_step_stopped_part_way_must_be_reset() -> None:
    """After one environment's stage raises, those left within their step refuse to step until
    reset; the one whose action was refused before anything changed, and those not yet started,
    step on."""
    envs = [NavGymEnv("stage5", seed=k) for k in range(3)]
    for env in envs:
        env.reset(seed=7)
    actions = [np.zeros(4, np.float32), np.full(4, np.nan, np.float32), np.zeros(4, np.float32)]
    with pytest.raises(ValueError, match="finite") as info:
        step_in_stages(envs, actions)
    assert "(in environment 1)" in info.value.__notes__
    with pytest.raises(RuntimeError, match="part-way"):
        envs[0].step(np.zeros(4, np.float32))  # its first stage ran: the crowd moved on, the physics did not
    for k in (1, 2):
        envs[k].step(np.zeros(4, np.float32))
    twin = NavGymEnv("stage5", seed=0)
    for env in (envs[0], twin):
        env.reset(seed=7)
    np.testing.assert_array_equal(envs[0].step(np.zeros(4, np.float32))[0], twin.step(np.zeros(4, np.float32))[0])


def test_a_dropped_step_must_be_reset() -> None:
    """Stages left unfinished (the generator dropped after its first stage) count as a stopped step."""
    env = NavGymEnv("stage5", seed=0)
    env.reset(seed=3)
    stages = env.step_stages(np.zeros(4, np.float32))
    next(stages)
    next(stages)
    del stages
    with pytest.raises(RuntimeError, match="part-way"):
        env.step(np.zeros(4, np.float32))
    env.reset(seed=3)
    assert len(env.step(np.zeros(4, np.float32))) == 5


def test_a_forwarding_wrapper_is_stepped_in_turn() -> None:
    """A wrapper that forwards attribute reads to the environment (old gym style) does not pass
    for one that steps in stages: its own ``step`` runs."""

    class Forwarding(gym.Wrapper):
        def __getattr__(self, name):
            return getattr(self.env, name)

        def step(self, action):
            obs, reward, terminated, truncated, info = self.env.step(action)
            return obs, 100.0 * reward, terminated, truncated, info

    group = _EnvGroup(lambda i: Forwarding(NavGymEnv("stage5", overrides=OVERRIDES)), range(1), seed=11)
    assert group.envs[0].stages_are_step and not group.staged


@pytest.mark.parametrize("task_steps", [True, False])
def test_a_step_that_raised_after_taking_its_action_must_be_reset(task_steps: bool) -> None:
    """Through the task's stages or composer's step: a failure once the action was taken (here in
    the crowd's advance, inside the first stage, and in the after-step hook) leaves the step
    refused until reset; a refused action does not."""
    env = NavGymEnv("stage5", seed=0, task_steps=task_steps)
    env.reset(seed=3)
    assert env._step_task is task_steps
    with pytest.raises(ValueError, match="finite"):
        env.step(np.full(4, np.nan, np.float32))
    env.step(np.zeros(4, np.float32))  # still usable
    for part, owner in (("apply_command", env.task.sim), ("score", env.task)):
        original = getattr(owner, part)

        def fail(*args, **kwargs):
            raise FloatingPointError(f"{part} failed")

        setattr(owner, part, fail)
        with pytest.raises(FloatingPointError, match=part):
            env.step(np.zeros(4, np.float32))
        setattr(owner, part, original)
        with pytest.raises(RuntimeError, match="part-way"):
            env.step(np.zeros(4, np.float32))
        env.reset(seed=3)
        env.step(np.zeros(4, np.float32))


def test_the_stages_of_a_step_do_not_go_on_past_a_reset() -> None:
    """A step's generator kept across ``reset()`` refuses to run its other stages on the new episode."""
    env = NavGymEnv("stage5", seed=0)
    env.reset(seed=3)
    stages = env.step_stages(np.zeros(4, np.float32))
    next(stages)
    env.reset(seed=3)
    with pytest.raises(RuntimeError, match="reset within this step"):
        next(stages)
    assert env.task.core.steps == 0
    assert len(env.step(np.zeros(4, np.float32))) == 5


def test_rollout_parts_split_a_block_evenly() -> None:
    """Contiguous parts of at most the size, as even as possible; 0 or a larger size: one part."""
    assert rollout_parts(range(4, 14), 4) == [range(4, 8), range(8, 11), range(11, 14)]
    assert rollout_parts(range(0, 32), 8) == [range(0, 8), range(8, 16), range(16, 24), range(24, 32)]
    assert rollout_parts(range(3, 6), 0) == [range(3, 6)] == rollout_parts(range(3, 6), 8)
