"""Bounded spaces for standard RL clients: the ``mjnav/StageK-v2`` environments.

``-v1`` (:class:`mjnav.envs.gym_env.NavGymEnv`) takes pre-sigmoid actions in ``Box(-inf, inf)`` and
declares an unbounded observation space; Stable-Baselines3, Gymnasium's ``RescaleAction`` and the
environment checkers refuse or warn about that. ``-v2`` is the same environment,
:class:`BoundedNavGymEnv`, with only the two spaces changed:

Action, ``Box(-1, 1, (n,), float32)``:
    Design ``ours`` (and ``design4``): ``a = 2·(α_s, β_s, α_l, β_l) − 1``, the affine image of the
    paper's action ∈ [0, 1]⁴; ``design3``: ``a = 2·(α_l, β_l) − 1``; ``design1|design2``:
    ``a = (v_x, v_y) / v_max``. :func:`raw_action` maps ``a`` to v1's raw action
    (``logit((a + 1)/2)``, resp. ``artanh(a)``), rounded to float32 as v1 rounds every action, and
    steps the v1 environment with it. Equivalence, tested in ``tests/envs/test_rl_clients.py``:

    * **Bit for bit**: a v2 episode with actions ``a_t`` ∈ (−1, 1) is the v1 episode with actions
      ``float32(logit((a_t + 1)/2))`` (velocity designs: ``float32(artanh(a_t))``): same
      observations, rewards, flags and info, since v2 *is* that v1 step.
    * **Float tolerance**: the α the action layer then uses, ``sigmoid(float32(logit(α)))``,
      differs from ``α = (a + 1)/2`` by the float32 rounding of the logit only: at most
      :data:`ALPHA_TOLERANCE` (exact at a = 0).
    * **a = ±1** (α = 0 or 1, infinite logit): the raw value is clipped to ±:data:`RAW_LIMIT`,
      where v1's float64 sigmoid and tanh round to exactly 0, 1 and ±1 (as for every
      ``|raw| >= 38``), so α = 0 and 1 (velocity designs: ±v_max) are reached exactly and finitely.
      (v1 itself rejects a non-finite raw action with a ``ValueError``, which also catches a
      float64 value beyond float32's range, and saturates a huge finite one exactly.)
    * Outside [−1, 1] the action is clipped to it (what ``ClipAction`` would do); NaN is still a
      ``ValueError``.

Observation, ``Box(low, high, (size,), float32)`` with the bounds of :func:`observation_bounds`:
    the v1 observation, value for value, whose known ranges follow from the config (spec §6,
    :mod:`mjnav.tasks.observation`): r̂ ∈ [0, 1] and θ̂ ∈ [0, 1]; dθ/π and the polar angles ∈ [−1, 1];
    ρ/40 ∈ [0, arena diagonal / 40]; v/2.5 ∈ ±v_max/2.5 per axis (×√2 with
    ``observation.frame=goal``); region flag ∈ [0, 1]; (|Q| + R_inf)/10 ∈
    [R_inf/10, (D + R_inf)/10] with D the larger of ``lidar.max_range`` (a region and its
    points lie within the scan) and the MPC's kinematic reach √2·v_max·horizon·t_c (a plan
    without a region constraint); with ``observation.tracks=K`` the tracks' scaled offsets and
    velocities ∈ [−1, 1] (clipped there already) and their valid flags ∈ [0, 1]. The v1
    observation is clipped to these bounds, which changes
    nothing in free motion: only the step in which a contact ends the episode may push the
    robot's velocity beyond v_max.

The rsl-rl adapter (:mod:`mjnav.envs.vec_env`) and evaluation (:mod:`mjnav.eval`) keep the raw v1
path; use ``env.unwrapped`` for the task, physics and config.
"""

from __future__ import annotations

import math
from collections.abc import Generator
from typing import Any

import gymnasium as gym
import numpy as np
from scipy.special import logit

from mjnav.config import TaskConfig
from mjnav.envs.gym_env import NavGymEnv
from mjnav.tasks import observation as obs_lib
from mjnav.tasks.design import get_design

__all__ = ["ALPHA_TOLERANCE", "RAW_LIMIT", "BoundedNavGymEnv", "make_bounded", "observation_bounds", "raw_action"]

RAW_LIMIT = 40.0  # |raw action| at which v1's float64 sigmoid(raw) is exactly 0 or 1 and tanh(raw) exactly ±1
ALPHA_TOLERANCE = 3e-8  # max |sigmoid(float32(logit(α))) − α| over float32 actions in [-1, 1]


def raw_action(action: Any, kind: str = "points") -> np.ndarray:
    """v1's raw action for a v2 action (see the module docstring).

    Args:
        action: v2 action, values in [-1, 1] (clipped to it; NaN passes through).
        kind: The design's action kind (:attr:`mjnav.tasks.design.Design.action`): ``points`` and
            ``long_point`` (sigmoid-squashed) or ``velocity`` (tanh-squashed).

    Returns:
        float32 array of the same shape: ``logit((a + 1)/2)`` (resp. ``artanh(a)``), within ±RAW_LIMIT.
    """
    a = np.clip(np.asarray(action, dtype=np.float64), -1.0, 1.0)
    with np.errstate(divide="ignore"):
        raw = np.arctanh(a) if kind == "velocity" else logit(0.5 * (a + 1.0))
    return np.clip(raw, -RAW_LIMIT, RAW_LIMIT).astype(np.float32)


def _state_bounds(config: TaskConfig) -> tuple[np.ndarray, np.ndarray]:
    """Low and high of the 13 state values of one frame (normalised units, see the module docstring)."""
    inflation = config.region.inflation
    speed = config.robot.v_max * (math.sqrt(2.0) if config.observation.frame == "goal" else 1.0)
    reach = math.sqrt(2.0) * config.robot.v_max * config.mpc.horizon * config.timing.control_period
    far = (max(config.lidar.max_range, reach) + inflation) / obs_lib.RANGE_SCALE
    near = inflation / obs_lib.RANGE_SCALE
    v = speed / obs_lib.SPEED_SCALE
    rho = math.hypot(*config.arena.size) / obs_lib.DISTANCE_SCALE
    #                   dθ   ρ    v_x v_y  ok  θQs  θQl  |Qs| |Ql| θQ1  θQN  |Q1| |QN|
    low = np.array([-1.0, 0.0, -v, -v, 0.0, -1.0, -1.0, near, near, -1.0, -1.0, near, near])
    high = np.array([1.0, rho, v, v, 1.0, 1.0, 1.0, far, far, 1.0, 1.0, far, far])
    return low, high


def observation_bounds(config: TaskConfig) -> tuple[np.ndarray, np.ndarray]:
    """Bounds of the stacked observation (float32, laid out as :class:`mjnav.tasks.observation.FrameStack`).

    Args:
        config: The environment's task config (design, frames, points, arena, robot, LiDAR, MPC).

    Returns:
        (low, high), each of length ``observation_size``: polygon blocks in [0, 1], then each
        frame's state values (the design's columns) bounded by :func:`_state_bounds`, then with
        ``observation.tracks=K`` K tracks' ``[dx, dy, vx, vy]`` in [-1, 1] and valid in [0, 1].
    """
    design = get_design(config.design)
    frames, points = config.observation.frames, config.region.num_points
    state_low, state_high = (b[list(design.state_columns)] for b in _state_bounds(config))
    tracks = config.observation.tracks  # [dx, dy, vx, vy] clipped to [-1, 1], valid in [0, 1]
    low = np.concatenate([np.zeros(frames * 2 * points), np.tile(state_low, frames),
                          np.tile([-1.0, -1.0, -1.0, -1.0, 0.0], tracks)])
    high = np.concatenate([np.ones(frames * 2 * points), np.tile(state_high, frames), np.ones(5 * tracks)])
    return low.astype(np.float32), high.astype(np.float32)


class BoundedNavGymEnv(NavGymEnv):
    """:class:`NavGymEnv` with the v2 spaces: actions in [-1, 1], observations within known bounds.

    Everything else (arguments, ``reset`` seeds and options, rewards, ``info``, rendering, the
    ``task``/``physics``/``config`` attributes) is v1's; ``env.unwrapped`` of a ``-v2`` id is this
    class, so Gymnasium's ``check_env(env.unwrapped)`` sees the bounded spaces.
    """

    def __init__(self, task: str | TaskConfig = "stage6", **kwargs: Any) -> None:
        """Build the v1 environment (same arguments as :class:`NavGymEnv`) and declare the v2 spaces."""
        super().__init__(task, **kwargs)
        self._kind = self.task.core.design.action
        self.action_space = gym.spaces.Box(-1.0, 1.0, self.action_space.shape, np.float32)
        self._low, self._high = observation_bounds(self.config)
        self.observation_space = gym.spaces.Box(self._low, self._high, dtype=np.float32)

    def reset(self, *, seed: int | None = None, options: dict[str, Any] | None = None):
        """v1's reset (same seeds and options); the observation within the bounds."""
        obs, info = super().reset(seed=seed, options=options)
        return self._bound(obs), info

    def step_stages(self, action: Any) -> Generator[None, None, tuple]:
        """v1's step (and :meth:`step`, which runs these stages) with :func:`raw_action` of
        ``action``; the observation within the bounds.

        Raises:
            ValueError: For a NaN or a wrongly sized action (v1's check).
            RuntimeError: If the episode has ended (call ``reset()`` first).
        """
        obs, reward, terminated, truncated, info = yield from super().step_stages(raw_action(action, self._kind))
        return self._bound(obs), reward, terminated, truncated, info

    def _bound(self, obs: np.ndarray) -> np.ndarray:
        """The observation clipped to the declared bounds (float32; unchanged in free motion)."""
        return np.clip(obs, self._low, self._high, dtype=np.float32)


def make_bounded(task: str | TaskConfig = "stage6", **kwargs: Any) -> gym.Env:
    """Entry point of the ``-v2`` ids: :class:`BoundedNavGymEnv` inside a ``TimeLimit`` of the
    task's ``timing.episode_steps`` (as v1's entry point, :func:`mjnav.envs.gym_env.make_registered`)."""
    env = BoundedNavGymEnv(task, **kwargs)
    return gym.wrappers.TimeLimit(env, env.config.timing.episode_steps)
