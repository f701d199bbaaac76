"""NavVecEnv: the rsl-rl adapter over a fake navigation env (no MuJoCo)."""

from __future__ import annotations

import dataclasses
import os
import time
from pathlib import Path

import gymnasium as gym
import numpy as np
import pytest
import torch

from mjnav.envs.vec_env import OUTCOMES, EnvError, NavVecEnv, _blocks

OBS_DIM, ACT_DIM = 399, 4


class FakeNavEnv(gym.Env):
    """A point moving toward the origin; same spaces and info contract as the real env.

    The goal is reached when the point is within 0.3 of the origin (success); leaving the
    [-3, 3]² box is a collision; ``limit`` steps without either is a truncation.
    """

    def __init__(
        self, limit: int = 20, fail_step: int | None = None, die: bool = False, noise: float = 0.05,
        delay_s: float = 0.0, critic: int = 0, critic_info: bool = True,
    ) -> None:
        """Spaces as the real env; ``spec.max_episode_steps`` = ``limit``; each step sleeps ``delay_s``;
        ``critic`` > 0 reports that many privileged values ``[t, x, y, ...]`` (unless not ``critic_info``)."""
        self.critic_size, self.critic_info = critic, critic_info
        self.spec = gym.envs.registration.EnvSpec("FakeNav-v0", max_episode_steps=limit)
        self.observation_space = gym.spaces.Box(-np.inf, np.inf, (OBS_DIM,), np.float32)
        self.action_space = gym.spaces.Box(-np.inf, np.inf, (ACT_DIM,), np.float32)
        self.limit, self.fail_step, self.die, self.noise = limit, fail_step, die, noise
        self.delay_s = delay_s
        self._pos = np.zeros(2)
        self._t = 0
        self.total_steps = 0

    def _obs(self) -> np.ndarray:
        obs = np.zeros(OBS_DIM, np.float32)
        obs[:2] = self._pos
        obs[2] = self._t / self.limit
        obs[3:10] = self.np_random.random(7)
        return obs

    def reset(self, *, seed: int | None = None, options: dict | None = None) -> tuple[np.ndarray, dict]:
        """Start 1-2 units from the origin."""
        super().reset(seed=seed)
        angle, radius = self.np_random.uniform(-np.pi, np.pi), self.np_random.uniform(1.0, 2.0)
        self._pos = radius * np.array([np.cos(angle), np.sin(angle)])
        self._t = 0
        return self._obs(), self._with_critic({"outcome": "running", "episode_seed": 0})

    def _with_critic(self, info: dict) -> dict:
        if self.critic_size and self.critic_info:
            info["critic"] = np.resize(np.array([self._t, *self._pos], np.float32), self.critic_size)
        return info

    def step(self, action: np.ndarray) -> tuple[np.ndarray, float, bool, bool, dict]:
        """Move by the squashed action (plus noise); fail on request."""
        self.total_steps += 1
        time.sleep(self.delay_s)
        if self.fail_step is not None and self.total_steps >= self.fail_step:
            if self.die:
                os._exit(3)
            raise RuntimeError("fake env exploded on purpose")
        squashed = 1.0 / (1.0 + np.exp(-np.asarray(action, np.float64)))
        before = np.linalg.norm(self._pos)
        self._pos = self._pos + 0.6 * (squashed[:2] - 0.5) + self.noise * self.np_random.standard_normal(2)
        self._t += 1
        dist = np.linalg.norm(self._pos)
        outcome = "success" if dist < 0.3 else "collision" if np.abs(self._pos).max() > 3.0 else "running"
        terms = {"approach": before - dist, "success": 10.0 * (outcome == "success")}
        terms["collision"] = -5.0 * (outcome == "collision")
        truncated = outcome == "running" and self._t >= self.limit
        outcome = "timeout" if truncated else outcome
        info = {
            "outcome": outcome,
            "reward_terms": terms,
            "episode_seed": 0,
            "mpc": {"solve_time_ms": 1.0 + dist, "fallback": 0.0},
        }
        done = outcome in ("success", "collision")
        return self._obs(), float(sum(terms.values())), done, truncated, self._with_critic(info)


@dataclasses.dataclass(frozen=True)
class FakeFactory:
    """Picklable ``env_fn(index)``; ``fail_env`` raises (or dies) at its ``fail_step``-th step.

    ``fail_step=0`` fails while building; ``slow_env`` sleeps ``delay_s`` in every step.
    """

    limit: int = 20
    fail_env: int | None = None
    fail_step: int = 3
    die: bool = False
    noise: float = 0.05
    slow_env: int | None = None
    delay_s: float = 0.0
    critic: int = 0
    critic_info: bool = True

    def __call__(self, index: int) -> FakeNavEnv:
        """Build env ``index``."""
        failing = index == self.fail_env
        if failing and self.fail_step == 0:
            raise ValueError(f"fake env {index} refused to build")
        delay = self.delay_s if index == self.slow_env else 0.0
        return FakeNavEnv(self.limit, self.fail_step if failing else None, self.die, self.noise, delay,
                          self.critic, self.critic_info)


def _rollout(env: NavVecEnv, steps: int, seed: int = 0) -> list[tuple]:
    gen = torch.Generator().manual_seed(seed)
    out = []
    for _ in range(steps):
        actions = torch.randn(env.num_envs, env.num_actions, generator=gen)
        obs, rew, dones, extras = env.step(actions)
        out.append((obs["policy"].clone(), rew.clone(), dones.clone(), extras["time_outs"].clone()))
    return out


LAYOUTS = {
    "inprocess": {"workers": 0},
    "main+1process": {"workers": 2},
    "2processes": {"workers": 2, "step_in_main": False},
}


@pytest.fixture(params=list(LAYOUTS), ids=list(LAYOUTS))
def workers(request: pytest.FixtureRequest) -> dict:
    """Adapter layouts: in-process, this process plus one worker process, two worker processes."""
    return LAYOUTS[request.param]


def test_shapes_and_dtypes(workers: dict) -> None:
    """Observations, rewards, dones and time_outs have the rsl-rl shapes and dtypes."""
    with NavVecEnv(FakeFactory(), num_envs=4, seed=1, **workers) as env:
        obs = env.get_observations()
        assert obs["policy"].shape == (4, OBS_DIM) and obs["policy"].dtype == torch.float32
        assert env.num_actions == ACT_DIM and env.max_episode_length == 20
        obs, rew, dones, extras = env.step(torch.zeros(4, ACT_DIM))
        assert obs["policy"].shape == (4, OBS_DIM) and rew.shape == (4,) and rew.dtype == torch.float32
        assert dones.shape == (4,) and dones.dtype == torch.long
        assert extras["time_outs"].shape == (4,) and extras["time_outs"].dtype == torch.bool


def test_privileged_critic_group(workers: dict) -> None:
    """Envs with ``critic_size`` > 0 add a ``critic`` group; after an auto-reset it is the new episode's."""
    with NavVecEnv(FakeFactory(limit=3), num_envs=4, seed=1, **workers) as env:
        assert env.critic_dim == 0 and list(env.get_observations().keys()) == ["policy"]
    with NavVecEnv(FakeFactory(limit=3, critic=5), num_envs=4, seed=1, **workers) as env:
        assert env.critic_dim == 5
        obs = env.get_observations()
        assert obs["critic"].shape == (4, 5) and obs["critic"].dtype == torch.float32
        assert not obs["critic"][:, 0].any()  # t = 0
        for step in (1, 2, 3):
            obs, _, dones, _ = env.step(torch.zeros(4, ACT_DIM))
            expected = torch.where(dones.bool(), 0.0, float(step))
            torch.testing.assert_close(obs["critic"][:, 0], expected)
            torch.testing.assert_close(obs["critic"][:, 1:3], obs["policy"][:, :2])
        assert dones.all()  # the limit: every env reset, its critic row from the new episode


def test_missing_critic_info_is_a_clear_error() -> None:
    """An env that declares ``critic_size`` but reports no ``info['critic']`` fails naming the entry."""
    with pytest.raises(EnvError, match="info has no 'critic' entry"):
        NavVecEnv(FakeFactory(critic=3, critic_info=False), num_envs=2, seed=1, workers=0)


def test_get_observations_never_resets() -> None:
    """get_observations returns the same observation twice and does not advance the clock."""
    with NavVecEnv(FakeFactory(), num_envs=2, seed=1, workers=0) as env:
        env.step(torch.zeros(2, ACT_DIM))
        first, second = env.get_observations(), env.get_observations()
        assert torch.equal(first["policy"], second["policy"])
        assert env.episode_length_buf.tolist() == [1, 1]


def test_auto_reset_and_time_outs_on_truncation() -> None:
    """Zero actions never finish: every env truncates at the env's limit, reports time_outs, restarts."""
    with NavVecEnv(
        FakeFactory(limit=5, noise=0.0), num_envs=3, seed=2, workers=0, max_episode_length=100
    ) as env:
        for _ in range(4):
            _, _, dones, extras = env.step(torch.zeros(3, ACT_DIM))
            assert not dones.any() and not extras["time_outs"].any()
        obs, _, dones, extras = env.step(torch.zeros(3, ACT_DIM))
        assert dones.tolist() == [1, 1, 1] and extras["time_outs"].all()
        assert extras["outcomes"].tolist() == [OUTCOMES.index("timeout")] * 3
        assert (obs["policy"][:, 2] == 0).all(), "the observation after a done starts the next episode"
        assert env.episode_length_buf.tolist() == [0, 0, 0]
        assert extras["log"]["episode/length"].tolist() == [5.0, 5.0, 5.0]


def test_episode_length_buf_is_honoured() -> None:
    """An overwritten episode_length_buf makes the adapter truncate at max_episode_length."""
    with NavVecEnv(
        FakeFactory(limit=1000, noise=0.0), num_envs=2, seed=3, workers=0, max_episode_length=10
    ) as env:
        env.episode_length_buf = torch.tensor([8, 0])
        _, _, dones, _ = env.step(torch.zeros(2, ACT_DIM))
        assert dones.tolist() == [0, 0]
        obs, _, dones, extras = env.step(torch.zeros(2, ACT_DIM))
        assert dones.tolist() == [1, 0] and extras["time_outs"].tolist() == [True, False]
        assert env.episode_length_buf.tolist() == [0, 2]
        assert obs["policy"][0, 2] == 0.0 and obs["policy"][1, 2] > 0.0
        assert extras["log"]["episode/length"].tolist() == [2.0], "true steps, not the clock"


def test_log_keys(workers: dict) -> None:
    """extras['log'] carries episode/, reward/ and mpc/ keys with finite values."""
    seen: dict[str, list[float]] = {}
    with NavVecEnv(FakeFactory(limit=8), num_envs=4, seed=4, **workers) as env:
        gen = torch.Generator().manual_seed(0)
        for _ in range(20):
            _, _, _, extras = env.step(3.0 * torch.randn(4, ACT_DIM, generator=gen))
            for key, value in extras["log"].items():
                seen.setdefault(key, []).extend(torch.as_tensor(value).flatten().tolist())
    episode = {f"episode/{k}" for k in ("success", "collision", "timeout", "length", "return")}
    assert episode | {"reward/approach", "reward/success", "mpc/solve_time_ms", "mpc/fallback"} <= set(seen)
    assert all(np.isfinite(v).all() for v in seen.values())
    rates = [np.mean(seen[f"episode/{k}"]) for k in ("success", "collision", "timeout")]
    assert abs(sum(rates) - 1.0) < 1e-6
    assert all(k.count("/") == 1 and not k.startswith("/") for k in seen)


@pytest.mark.parametrize("slow_env", [0, 1])
def test_step_time_split_names_the_slow_side(slow_env: int) -> None:
    """perf/own_block_ms covers this process's block, perf/wait_ms the wait for the worker's.

    Environment 0 is stepped here, environment 1 by the worker process; one of them sleeps 40 ms.
    """
    factory = FakeFactory(limit=1000, slow_env=slow_env, delay_s=0.04)
    with NavVecEnv(factory, num_envs=2, seed=0, workers=2) as env:
        logs = [env.step(torch.zeros(2, ACT_DIM))[3]["log"] for _ in range(4)]
    own, wait, total = (np.median([log[f"perf/{k}_ms"] for log in logs]) for k in ("own_block", "wait", "env_step"))
    slow, fast = (own, wait) if slow_env == 0 else (wait, own)
    assert slow >= 30.0 and fast < 20.0
    assert own + wait <= total


def test_step_time_split_in_process() -> None:
    """With every environment in this process, a step is its own block and no wait."""
    with NavVecEnv(FakeFactory(slow_env=1, delay_s=0.02), num_envs=2, seed=0, workers=0) as env:
        log = env.step(torch.zeros(2, ACT_DIM))[3]["log"]
    assert log["perf/own_block_ms"] >= 15.0 and log["perf/wait_ms"] < 1.0


def test_same_seed_same_rollouts(workers: dict) -> None:
    """Two adapters with the same seed produce identical rollouts; another seed differs."""
    runs = []
    for seed in (7, 7, 8):
        with NavVecEnv(FakeFactory(limit=6), num_envs=4, seed=seed, **workers) as env:
            runs.append(_rollout(env, 15))
    pairs = zip(runs[0], runs[1], strict=True)
    same = all(torch.equal(a[0], b[0]) and torch.equal(a[1], b[1]) for a, b in pairs)
    assert same
    assert not all(torch.equal(a[0], b[0]) for a, b in zip(runs[0], runs[2], strict=True))


def test_worker_count_does_not_change_rollouts() -> None:
    """Every adapter layout with the same seed produces identical rollouts, this process's share
    (``main_envs``) included."""
    runs = []
    for layout in [*LAYOUTS.values(), {"workers": 2, "main_envs": 1}, {"workers": 3, "main_envs": 3}]:
        with NavVecEnv(FakeFactory(limit=6), num_envs=5, seed=11, **layout) as env:
            runs.append(_rollout(env, 12))
    for other in runs[1:]:
        assert all(torch.equal(a[0], b[0]) and torch.equal(a[2], b[2]) for a, b in zip(runs[0], other, strict=True))


def test_main_process_steps_the_first_block() -> None:
    """With step_in_main, W workers are this process and W - 1 processes (blocks 1..W-1)."""
    with NavVecEnv(FakeFactory(), num_envs=6, seed=0, workers=3) as env:
        processes = [h for h in env._handles if hasattr(h, "process")]
        assert [h.indices for h in processes] == [range(2, 4), range(4, 6)]
        assert all(h.process.is_alive() for h in processes)
    with NavVecEnv(FakeFactory(), num_envs=6, seed=0, workers=3, step_in_main=False) as env:
        assert sum(hasattr(h, "process") for h in env._handles) == 3


def test_main_envs_sets_this_process_block() -> None:
    """main_envs is the size of this process's block; the worker processes share the rest evenly."""
    with NavVecEnv(FakeFactory(), num_envs=6, seed=0, workers=3, main_envs=1) as env:
        assert env.blocks == [range(0, 1), range(1, 4), range(4, 6)]
        assert [h.indices for h in env._handles if hasattr(h, "process")] == [range(1, 4), range(4, 6)]
    assert _blocks(6, 1, 2) == [range(0, 6)]  # one worker: one block, main_envs ignored
    assert _blocks(7, 2) == [range(0, 4), range(4, 7)]  # the default even split


@pytest.mark.parametrize(("kwargs", "match"), [
    ({"workers": 3, "main_envs": 0}, r"main_envs must be in \[1, 4\]"),
    ({"workers": 3, "main_envs": 5}, r"main_envs must be in \[1, 4\]"),
    ({"workers": 2, "main_envs": 2, "step_in_main": False}, "needs step_in_main"),
])
def test_bad_main_envs_is_refused(kwargs: dict, match: str) -> None:
    with pytest.raises(ValueError, match=match):
        NavVecEnv(FakeFactory(), num_envs=6, seed=0, **kwargs)


def test_main_block_exception_stops_the_worker_processes() -> None:
    """An env of this process's block that raises surfaces as EnvError and stops the processes."""
    env = NavVecEnv(FakeFactory(fail_env=0, fail_step=2), num_envs=4, seed=0, workers=2)
    process = next(h.process for h in env._handles if hasattr(h, "process"))
    env.step(torch.zeros(4, ACT_DIM))
    with pytest.raises(EnvError, match="fake env exploded on purpose") as info:
        env.step(torch.zeros(4, ACT_DIM))
    assert "(in environment 0)" in str(info.value)
    process.join(10.0)
    assert not process.is_alive()


def test_worker_exception_surfaces(workers: dict) -> None:
    """An env that raises surfaces as EnvError with the env's message and traceback."""
    env = NavVecEnv(FakeFactory(fail_env=3, fail_step=2), num_envs=4, seed=0, **workers)
    env.step(torch.zeros(4, ACT_DIM))
    with pytest.raises(EnvError, match="fake env exploded on purpose") as info:
        env.step(torch.zeros(4, ACT_DIM))
    assert "Traceback" in str(info.value) and "(in environment 3)" in str(info.value)
    env.close()


def test_dead_worker_surfaces() -> None:
    """A worker process that dies is reported with its exit code instead of hanging."""
    env = NavVecEnv(FakeFactory(fail_env=1, fail_step=1, die=True), num_envs=2, seed=0, workers=2)
    with pytest.raises(EnvError, match=r"worker 1 .*died \(exit code 3\)"):
        env.step(torch.zeros(2, ACT_DIM))
    env.close()


def test_construction_error_surfaces() -> None:
    """A factory that raises while building fails the constructor with the worker's message."""
    with pytest.raises(EnvError, match="fake env 1 refused to build"):
        NavVecEnv(FakeFactory(fail_env=1, fail_step=0), num_envs=2, seed=0, workers=2)


def test_nan_actions_rejected() -> None:
    """NaN actions raise a ValueError naming the env before anything is stepped."""
    with NavVecEnv(FakeFactory(), num_envs=2, seed=0, workers=0) as env:
        actions = torch.zeros(2, ACT_DIM)
        actions[1, 2] = float("nan")
        with pytest.raises(ValueError, match=r"envs \[1\]"):
            env.step(actions)


def test_dispatch_then_step_gives_the_step_alone(workers: dict) -> None:
    """A step started with dispatch() and finished by step() returns what step() alone returns."""
    runs = []
    for early in (False, True):
        gen = torch.Generator().manual_seed(5)
        out = []
        with NavVecEnv(FakeFactory(limit=6), num_envs=4, seed=9, **workers) as env:
            for _ in range(14):
                actions = torch.randn(env.num_envs, env.num_actions, generator=gen)
                if early:
                    env.dispatch(actions)
                obs, rew, dones, extras = env.step(actions.clone())  # equal values, another tensor
                out.append((obs["policy"], rew, dones, extras["time_outs"], extras["outcomes"]))
        runs.append(out)
    for plain, early in zip(*runs, strict=True):
        assert all(torch.equal(a, b) for a, b in zip(plain, early, strict=True))


def test_dispatch_misuse_is_refused() -> None:
    """A second dispatch or a reset before step() is a RuntimeError (the step still finishes); step()
    with other actions than the dispatched ones closes the adapter; bad actions start nothing."""
    with NavVecEnv(FakeFactory(), num_envs=4, seed=0, workers=2) as env:
        actions = torch.zeros(4, ACT_DIM)
        with pytest.raises(ValueError, match="non-finite"):
            env.dispatch(torch.full((4, ACT_DIM), float("nan")))
        env.dispatch(actions)
        with pytest.raises(RuntimeError, match="dispatched step"):
            env.dispatch(actions)
        with pytest.raises(RuntimeError, match="dispatched step"):
            env.reset()
        env.step(actions)
        env.dispatch(actions)
        with pytest.raises(ValueError, match="other actions than dispatch"):
            env.step(actions + 1.0)
        assert env._closed
        for call in (lambda: env.step(actions), lambda: env.dispatch(actions), env.reset):  # said so, not KeyError
            with pytest.raises(RuntimeError, match="on a closed adapter"):
                call()


@pytest.mark.parametrize("dispatched", [False, True])
def test_the_timed_parts_of_a_step_fit_in_the_step(dispatched: bool) -> None:
    """Own block, wait and transfers (the send counted once) add up to no more than the whole step."""
    with NavVecEnv(FakeFactory(), num_envs=4, seed=0, workers=2) as env:
        actions = torch.zeros(4, ACT_DIM)
        for _ in range(5):
            if dispatched:
                env.dispatch(actions)
            log = env.step(actions)[3]["log"]
            parts = log["perf/own_block_ms"] + log["perf/wait_ms"] + log["perf/transfer_ms"]
            assert 0.0 < parts <= log["perf/env_step_ms"]


@pytest.mark.skipif(not Path("/dev/shm").is_dir(), reason="POSIX shared memory in /dev/shm")
def test_the_shared_memory_has_no_name_once_the_workers_mapped_it() -> None:
    """Nothing is left in /dev/shm when every process is SIGKILLed (no close() runs): the segment's
    name is removed as soon as the workers have mapped it, and the steps go on through the mapping."""
    before = set(os.listdir("/dev/shm"))
    with NavVecEnv(FakeFactory(), num_envs=4, seed=0, workers=2) as env:
        assert set(os.listdir("/dev/shm")) - before == set()
        env.step(torch.zeros(4, ACT_DIM))
    assert set(os.listdir("/dev/shm")) - before == set()


@dataclasses.dataclass(frozen=True)
class TablePolicy:
    """A picklable rollout policy: actions from the observations, the step and a fixed noise table
    (per step and environment); ``aux`` holds the first two observations, tripled; ``nan_at``:
    (step, environment) whose actions are NaN."""

    noise: np.ndarray
    nan_at: tuple[int, int] | None = None

    def __call__(self, t: int, indices: range, obs: np.ndarray, critic: np.ndarray | None) -> tuple:
        actions = np.tanh(obs[:, :ACT_DIM]) * 2.0 + self.noise[t, indices.start : indices.stop]
        if critic is not None:
            actions[:, 0] += critic[:, 0] * 0.01
        if self.nan_at is not None and self.nan_at[0] == t and self.nan_at[1] in indices:
            actions[self.nan_at[1] - indices.start, 1] = np.nan
        return actions.astype(np.float32), 3.0 * obs[:, :2]


def _table(steps: int, num_envs: int, seed: int = 3) -> TablePolicy:
    return TablePolicy(np.random.default_rng(seed).normal(size=(steps, num_envs, ACT_DIM)).astype(np.float32))


def _served(env: NavVecEnv, steps: int, policy: TablePolicy, rollout: bool) -> list[tuple]:
    """``steps`` steps with ``policy``'s actions, through a rollout or step by step."""
    if rollout:
        env.rollout(policy, steps, aux_dim=2)
    out = []
    for t in range(steps):
        obs = env.get_observations()
        critic = obs["critic"].numpy() if "critic" in obs.keys() else None
        actions, aux = policy(t, range(env.num_envs), obs["policy"].numpy(), critic)
        if rollout:
            recorded, recorded_aux = env.recorded()
            assert np.array_equal(recorded.numpy(), actions) and np.array_equal(recorded_aux.numpy(), aux)
        obs, rew, dones, extras = env.step(torch.from_numpy(actions))
        log = {k: v for k, v in extras["log"].items() if not k.startswith("perf/")}
        out.append((obs, rew, dones, extras["time_outs"], extras["outcomes"], log, env.episode_length_buf.clone()))
    return out


@pytest.mark.parametrize(("critic", "parts"), [(0, 0), (3, 0), (0, 2)])
def test_a_rollout_serves_what_stepping_gives(workers: dict, critic: int, parts: int) -> None:
    """rollout() then step() through it returns, step for step, what step() with the policy's actions
    returns: observations, rewards, dones, time-outs, outcomes, logs and the episode clock (truncations
    forced by a short limit and by a preset clock), over two rollouts in a row; also when each worker
    runs its block in parts of 2 environments (the logged sums then add up per part)."""
    runs = []
    for rollout in (False, True):
        factory = FakeFactory(limit=50, critic=critic)
        with NavVecEnv(factory, num_envs=5, seed=4, max_episode_length=7, rollout_envs=parts, **workers) as env:
            env.episode_length_buf = torch.tensor([0, 3, 6, 5, 1])
            runs.append(_served(env, 9, _table(9, 5), rollout) + _served(env, 4, _table(4, 5, seed=8), rollout))
            assert not env.replaying
    for plain, served in zip(*runs, strict=True):
        assert torch.equal(plain[0]["policy"], served[0]["policy"])
        assert critic == 0 or torch.equal(plain[0]["critic"], served[0]["critic"])
        assert all(torch.equal(a, b) for a, b in zip(plain[1:5], served[1:5], strict=True))
        assert plain[5].keys() == served[5].keys()
        for key in plain[5]:  # sums over parts of a block: equal to rounding
            assert torch.allclose(torch.as_tensor(plain[5][key]), torch.as_tensor(served[5][key]), rtol=1e-12), key
        assert torch.equal(plain[6], served[6])


def test_a_rollout_splits_the_step_time_like_a_step() -> None:
    """Served steps report this process's own block, its policy calls and the worker processes' step times."""
    with NavVecEnv(FakeFactory(), num_envs=4, seed=0, workers=2) as env:
        env.rollout(_table(3, 4), 3, aux_dim=2)
        for t in range(3):
            log = env.step(env.recorded()[0])[3]["log"]
            assert log["perf/own_block_ms"] > 0.0 and log["perf/worker_step_ms"] > 0.0
            assert log["perf/rollout_policy_ms"] > 0.0 and log["perf/wait_ms"] >= 0.0


def test_rollout_misuse_is_refused() -> None:
    """While a rollout is served, dispatch() and rollout() are RuntimeErrors and reset() drops it;
    step() with other actions than the recorded ones closes the adapter."""
    with NavVecEnv(FakeFactory(), num_envs=4, seed=0, workers=2) as env:
        with pytest.raises(RuntimeError, match="without a rollout"):
            env.recorded()
        with pytest.raises(ValueError, match="steps must be"):
            env.rollout(_table(1, 4), 0)
        env.rollout(_table(3, 4), 3, aux_dim=2)
        assert env.replaying
        for call in (lambda: env.dispatch(torch.zeros(4, ACT_DIM)), lambda: env.rollout(_table(3, 4), 3, 2)):
            with pytest.raises(RuntimeError, match="3 remaining steps"):
                call()
        env.reset()
        assert not env.replaying
        env.rollout(_table(2, 4), 2, aux_dim=2)
        env.step(env.recorded()[0])
        with pytest.raises(ValueError, match="other actions than the rollout's step 1"):
            env.step(env.recorded()[0] + 1.0)
        assert env._closed


def test_non_finite_rollout_actions_close_the_adapter(workers: dict) -> None:
    """A policy that gives NaN in a rollout: ValueError naming the step and environment, adapter closed."""
    with NavVecEnv(FakeFactory(), num_envs=4, seed=0, **workers) as env:
        with pytest.raises(ValueError, match=r"rollout step 2 for envs \[3\]"):
            env.rollout(dataclasses.replace(_table(4, 4), nan_at=(2, 3)), 4, aux_dim=2)
        assert env._closed


def test_an_environment_failing_in_a_rollout_surfaces(workers: dict) -> None:
    """An environment raising within a rollout is an EnvError carrying its traceback; adapter closed."""
    with NavVecEnv(FakeFactory(fail_env=3, fail_step=2), num_envs=4, seed=0, **workers) as env:
        with pytest.raises(EnvError, match="exploded on purpose"):
            env.rollout(_table(4, 4), 4, aux_dim=2)
        assert env._closed


def test_a_rollout_too_large_for_the_shared_memory_is_refused(monkeypatch: pytest.MonkeyPatch) -> None:
    """A record larger than the free space of /dev/shm: can_record() says so and rollout() refuses
    with a clear error before anything starts; the adapter goes on stepping."""
    with NavVecEnv(FakeFactory(), num_envs=4, seed=0, workers=2) as env:
        assert env.can_record(3, 2)
        full = os.statvfs_result((4096, 4096, 10, 0, 0, 0, 0, 0, 0, 255))  # no block free
        monkeypatch.setattr("mjnav.envs.vec_env.os.statvfs", lambda path: full)
        monkeypatch.setattr("mjnav.envs.vec_env.os.path.isdir", lambda path: True)
        assert not env.can_record(3, 2)
        with pytest.raises(ValueError, match="MB of shared memory"):
            env.rollout(_table(3, 4), 3, aux_dim=2)
        assert not env.replaying and not env._closed
        env.step(torch.zeros(4, ACT_DIM))


@dataclasses.dataclass(frozen=True)
class NarrowPolicy(TablePolicy):
    """Gives one aux column too few."""

    def __call__(self, t: int, indices: range, obs: np.ndarray, critic: np.ndarray | None) -> tuple:
        actions, aux = super().__call__(t, indices, obs, critic)
        return actions, aux[:, :1]


def test_rollout_policy_outputs_of_another_shape_are_refused(workers: dict) -> None:
    """A policy giving ``aux`` of another width is an error naming the shapes, not broadcast."""
    with NavVecEnv(FakeFactory(), num_envs=4, seed=0, **workers) as env:
        with pytest.raises(EnvError, match=r"aux \(\d, 1\).*expected \(\d, 4\) and \(\d, 2\)"):
            env.rollout(NarrowPolicy(_table(2, 4).noise), 2, aux_dim=2)
