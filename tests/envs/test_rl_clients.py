"""Standard RL clients on the ``-v2`` ids without wrappers of our own (issue 37, item 1).

Stable-Baselines3's and Gymnasium's ``check_env`` with warnings as errors, a short SB3 PPO run in a
``SubprocVecEnv``, Gymnasium's wrappers, the equivalence of a v2 episode with its v1 episode, and
the declared observation bounds over real episodes.
"""

from __future__ import annotations

import math
import warnings

import gymnasium as gym
import numpy as np
import pytest
from scipy.special import logit

import mjnav  # noqa: F401 - registers the ids
from mjnav.envs.bounded import ALPHA_TOLERANCE, RAW_LIMIT, BoundedNavGymEnv, observation_bounds, raw_action
from mjnav.envs.gym_env import NavGymEnv
from mjnav.envs.registration import ENV_IDS, V2_ENV_IDS, v2_id
from mjnav.viz.gl import probe_gl_backend

HAS_GL = any(probe_gl_backend(b) for b in ("egl", "osmesa"))
SHORT = ["timing.episode_steps=25"]  # episodes the wrapper tests run


def test_every_v1_id_has_a_v2_for_the_same_stage() -> None:
    """A ``-v2`` id is registered next to each ``-v1`` id, with the same task; v1's spaces are unchanged."""
    assert len(V2_ENV_IDS) == len(ENV_IDS)
    for v1, v2 in zip(ENV_IDS, V2_ENV_IDS, strict=True):
        assert v2 == v2_id(v1) and v2.endswith("-v2") and gym.spec(v2).kwargs == gym.spec(v1).kwargs
        assert gym.spec(v2).entry_point == "mjnav.envs.bounded:make_bounded"
    with pytest.warns(DeprecationWarning, match="out of date"):  # Gymnasium's hint when a newer version exists
        v1 = gym.make("mjnav/Stage5-v1")
    assert np.all(np.isinf(v1.action_space.high)) and np.all(np.isinf(v1.observation_space.low))
    v1.close()


def test_check_env_passes_without_warnings() -> None:
    """SB3's check_env on gym.make(...) and Gymnasium's on env.unwrapped, every warning an error."""
    from gymnasium.utils.env_checker import check_env as gym_check_env
    from stable_baselines3.common.env_checker import check_env as sb3_check_env

    env = gym.make("mjnav/Stage6-v2")
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        sb3_check_env(env)
        gym_check_env(env.unwrapped)
    assert env.action_space == gym.spaces.Box(-1.0, 1.0, (4,), np.float32)
    assert env.observation_space.dtype == np.float32 and np.all(np.isfinite(env.observation_space.low))
    assert np.all(np.isfinite(env.observation_space.high))
    env.close()


def test_raw_action_is_the_logit_of_the_affine_image() -> None:
    """raw = float32(logit((a+1)/2)); the squashed α is (a+1)/2 to ALPHA_TOLERANCE, exact at 0 and ±1;
    outside [-1, 1] the action is clipped, NaN stays NaN; velocity designs take artanh(a)."""
    a = np.concatenate([np.linspace(-1, 1, 200_001, dtype=np.float32),
                        np.nextafter(np.float32([-1, 1]), np.float32(0))])
    raw = raw_action(a)
    assert raw.dtype == np.float32
    interior = np.abs(a) < 1
    expected = logit(0.5 * (a[interior].astype(np.float64) + 1.0)).astype(np.float32)
    assert np.array_equal(raw[interior], expected)
    alpha = 0.5 * (1.0 + np.tanh(0.5 * raw.astype(np.float64)))  # v1's sigmoid
    assert np.max(np.abs(alpha - 0.5 * (a.astype(np.float64) + 1.0))) <= ALPHA_TOLERANCE
    assert raw_action(np.float32([-1, 0, 1])).tolist() == [-RAW_LIMIT, 0.0, RAW_LIMIT]
    sig = 0.5 * (1.0 + np.tanh(0.5 * np.array([-RAW_LIMIT, RAW_LIMIT])))
    assert sig.tolist() == [0.0, 1.0] and np.tanh(RAW_LIMIT) == 1.0
    assert raw_action([-7.0, 3.0, np.inf, -np.inf]).tolist() == [-RAW_LIMIT, RAW_LIMIT, RAW_LIMIT, -RAW_LIMIT]
    assert np.isnan(raw_action([np.nan])[0])
    velocity = raw_action(a, "velocity").astype(np.float64)
    assert np.max(np.abs(np.tanh(velocity) - a)) <= ALPHA_TOLERANCE and np.tanh(velocity[[0, -3]]).tolist() == [-1, 1]


def _v1_counterpart(a: np.ndarray, kind: str) -> np.ndarray:
    """The v1 action of the module docstring, computed here independently: logit((a+1)/2) (velocity:
    artanh(a)) rounded to float32; at a = ±1 any raw value that saturates (here ±1e4)."""
    a64 = np.asarray(a, dtype=np.float64)
    with np.errstate(divide="ignore"):
        raw = np.arctanh(a64) if kind == "velocity" else logit(0.5 * (a64 + 1.0))
    return np.where(a64 == 1.0, 1e4, np.where(a64 == -1.0, -1e4, raw)).astype(np.float32)


def _same_info(a: dict, b: dict) -> bool:
    """``info`` dicts equal value for value (arrays byte for byte)."""
    if a.keys() != b.keys():
        return False
    for key in a:
        x, y = a[key], b[key]
        if isinstance(x, dict):
            if not _same_info(x, y):
                return False
        elif isinstance(x, np.ndarray):
            if x.tobytes() != np.asarray(y).tobytes():
                return False
        elif x != y:
            return False
    return True


@pytest.mark.parametrize(("task", "design"), [("stage6", "ours"), ("stage5", "design1"), ("stage5", "design3")])
def test_v2_episode_is_the_v1_episode_bit_for_bit(task: str, design: str) -> None:
    """A v2 episode with actions a_t (some exactly ±1) equals, bit for bit, the v1 episode with
    float32(logit((a_t+1)/2)) (velocity designs: artanh) and a saturating raw value where a = ±1."""
    overrides = [f"design={design}", "timing.episode_steps=60"]
    v1, v2 = NavGymEnv(task, overrides=overrides), BoundedNavGymEnv(task, overrides=overrides)
    kind = v1.task.core.design.action
    rng = np.random.default_rng(7)
    for seed in (0, 1):
        o1, i1 = v1.reset(seed=seed)
        o2, i2 = v2.reset(seed=seed)
        assert o1.tobytes() == o2.tobytes() and _same_info(i1, i2)
        done = False
        while not done:
            a = rng.uniform(-1, 1, v2.action_space.shape).astype(np.float32)
            a[rng.random(a.shape) < 0.15] = rng.choice(np.float32([-1, 1]))
            s1 = v1.step(_v1_counterpart(a, kind))
            s2 = v2.step(a)
            assert s1[0].tobytes() == s2[0].tobytes() and s1[1:4] == s2[1:4] and _same_info(s1[4], s2[4])
            done = s2[2] or s2[3]
    v1.close()
    v2.close()


def test_non_finite_actions() -> None:
    """v1 rejects ±inf (and a float64 beyond float32's range); v2 clips ±inf to α = 0/1; NaN is a ValueError."""
    v1, v2 = NavGymEnv("stage5"), BoundedNavGymEnv("stage5")
    v1.reset(seed=0)
    v2.reset(seed=0)
    for bad in (np.float64([np.inf, 0, 0, 0]), np.float64([1e300, 0, 0, 0])):
        with pytest.raises(ValueError, match="finite"), np.errstate(over="ignore"):
            v1.step(bad)
    obs, *_ = v2.step(np.float32([np.inf, -np.inf, 0.5, 2.0]))
    assert v2.observation_space.contains(obs)
    with pytest.raises(ValueError, match="finite"):
        v2.step(np.float32([np.nan, 0, 0, 0]))
    v1.close()
    v2.close()


BOUND_CASES = [
    ("stage1", []), ("stage5", []), ("stage6", []), ("stage7", []),
    ("stage5", ["design=design1"]), ("stage5", ["design=design4"]),
    ("stage5", ["observation.frame=goal", "action.heading=goal"]),
    ("stage7", ["observation.frame=goal", "action.heading=goal", "observation.tracks=6"]),
]


@pytest.mark.parametrize(("task", "overrides"), BOUND_CASES)
def test_real_observations_lie_within_the_declared_bounds(task: str, overrides: list[str]) -> None:
    """Over real episodes (random raw actions, until success, collision or timeout) every v1
    observation already lies within the v2 bounds: the v2 clip changes nothing there."""
    env = NavGymEnv(task, overrides=[*overrides, "timing.episode_steps=150"])
    low, high = observation_bounds(env.config)
    assert low.shape == high.shape == env.observation_space.shape and low.dtype == np.float32
    rng = np.random.default_rng(3)
    for seed in range(3):
        obs, _ = env.reset(seed=seed)
        done = False
        while not done:
            assert np.all(obs >= low) and np.all(obs <= high), np.flatnonzero((obs < low) | (obs > high))
            obs, _, terminated, truncated, _ = env.step(rng.normal(0, 2, env.action_space.shape).astype(np.float32))
            done = terminated or truncated
        assert np.all(obs >= low) and np.all(obs <= high), np.flatnonzero((obs < low) | (obs > high))
    env.close()


def test_observation_bounds_follow_the_config() -> None:
    """ρ's bound is the arena diagonal / 40; the point distances' the LiDAR range (+ R_inf) / 10."""
    env = NavGymEnv("stage5", overrides=["lidar.max_range=8.0"])
    low, high = observation_bounds(env.config)
    state = high[-13:]
    assert state[1] == pytest.approx(math.hypot(*env.config.arena.size) / 40.0)
    assert state[7] == pytest.approx((8.0 + env.config.region.inflation) / 10.0)
    assert low[-13:][7] == pytest.approx(env.config.region.inflation / 10.0)
    assert state[2] == pytest.approx(env.config.robot.v_max / 2.5)
    env.close()


def _run_episode(env: gym.Env, seed: int = 0) -> int:
    """Steps of one episode with sampled actions; every observation within the space."""
    env.action_space.seed(seed)
    obs, _ = env.reset(seed=seed)
    steps, done = 0, False
    while not done:
        obs, reward, terminated, truncated, _ = env.step(env.action_space.sample())
        assert env.observation_space.contains(obs) and math.isfinite(reward)
        steps, done = steps + 1, terminated or truncated
    return steps


@pytest.mark.parametrize("wrap", [
    # RescaleAction to [0, 1]: the agent acts with the paper's α directly
    lambda env: gym.wrappers.RescaleAction(env, np.zeros(4, np.float32), np.ones(4, np.float32)),
    gym.wrappers.ClipAction,
    gym.wrappers.NormalizeObservation,
    gym.wrappers.RecordEpisodeStatistics,
], ids=["RescaleAction", "ClipAction", "NormalizeObservation", "RecordEpisodeStatistics"])
def test_gymnasium_wrappers_run_an_episode(wrap) -> None:
    """Gymnasium's action and observation wrappers take v2 as it is."""
    env = wrap(gym.make("mjnav/Stage5-v2", overrides=SHORT))
    steps = _run_episode(env)
    assert 0 < steps <= 25
    if isinstance(env, gym.wrappers.RecordEpisodeStatistics):
        assert env.episode_count == 1 and len(env.length_queue) == 1
    env.close()


def test_rescale_action_to_alpha_is_the_v1_action() -> None:
    """RescaleAction(v2, 0, 1) takes the paper's α: its first step equals v1's with logit(α)."""
    alpha = np.float32([0.25, 0.75, 0.5, 0.125])  # exact in float32 through 2α − 1
    rescaled = gym.wrappers.RescaleAction(BoundedNavGymEnv("stage5"), np.zeros(4, np.float32),
                                          np.ones(4, np.float32))
    v1 = NavGymEnv("stage5")
    rescaled.reset(seed=4)
    v1.reset(seed=4)
    a = rescaled.step(alpha)
    b = v1.step(logit(alpha.astype(np.float64)).astype(np.float32))
    assert a[0].tobytes() == b[0].tobytes() and a[1] == b[1]
    rescaled.close()
    v1.close()


@pytest.mark.skipif(not HAS_GL, reason="no off-screen GL backend (needs libegl1 + libgl1-mesa-dri, or libosmesa6)")
def test_record_video(tmp_path) -> None:
    """RecordVideo writes an MP4 of a v2 episode rendered with render_mode="rgb_array"."""
    pytest.importorskip("moviepy")
    env = gym.make("mjnav/Stage5-v2", overrides=SHORT, render_mode="rgb_array", render_size=(64, 64))
    env = gym.wrappers.RecordVideo(env, str(tmp_path / "videos"), episode_trigger=lambda _: True, disable_logger=True)
    _run_episode(env)
    env.close()
    videos = list((tmp_path / "videos").glob("*.mp4"))
    assert len(videos) == 1 and videos[0].stat().st_size > 0


def _make_v2() -> gym.Env:
    return gym.make("mjnav/Stage5-v2")


def test_sb3_ppo_trains_in_a_subproc_vec_env() -> None:
    """SB3 PPO on gym.make(...) in a SubprocVecEnv of 2: a few hundred steps and one update."""
    from stable_baselines3 import PPO
    from stable_baselines3.common.vec_env import SubprocVecEnv

    venv = SubprocVecEnv([_make_v2, _make_v2])
    try:
        model = PPO("MlpPolicy", venv, n_steps=64, batch_size=64, n_epochs=1, seed=0, device="cpu")
        model.learn(total_timesteps=256)
        assert model.num_timesteps >= 256
        action, _ = model.predict(venv.reset(), deterministic=True)
        assert action.shape == (2, 4) and np.all(np.abs(action) <= 1)
    finally:
        venv.close()
