"""Gymnasium adapter over the composer environment.

Environment card (Gymnasium style)

Description:
    An omni-directional disc robot must reach a goal in a walled room with static polygon
    obstacles and a crowd of moving cylinders, acting through a learned choice of two reference
    points inside the LiDAR's convex free-space polygon that an MPC tracks (spec §3-§5).
Action Space:
    ``Box(-inf, inf, (4,), float32)``: raw (α_s, β_s, α_l, β_l), squashed by a sigmoid inside
    (``design=design1|design2``: (v_x, v_y) before tanh; ``design3``: (α_l, β_l); see
    :mod:`mjnav.tasks.design`). A raw value with ``|a| >= 38`` saturates exactly (α = 0 or 1); a
    non-finite one (also a float64 beyond float32's range, as actions are rounded to float32) is a
    ``ValueError``. Bounded in ``-v2``: ``Box(-1, 1)``, α = (a + 1)/2 (:mod:`mjnav.envs.bounded`).
Observation Space:
    ``Box(-inf, inf, (399,), float32)``: 3 stacked frames of the 60-point polygon encoding and a
    13-value state block (spec §6); the designs keep 372 / 372 / 387 / 396 values.
Rewards:
    Σ weight·term over success, collision, proximity, approach, feasibility, change, slow,
    velocity_change (spec §7; variant by ``reward.variant``); ``info["reward_terms"]`` has each.
Starting State:
    A layout sampled from the episode seed (spec §9); the robot at rest at the start.
Episode End:
    ``terminated`` on success (goal within 0.7 m) or collision (MuJoCo contact);
    ``truncated`` after ``timing.episode_steps`` (300) control steps.
Arguments:
    ``gymnasium.make("mjnav/Stage6-v1", overrides=["crowd.count=25"], render_mode="rgb_array",
    render_size=(480, 480), render_camera="top", render_overlays=True)``. ``spec.max_episode_steps``
    is the task's ``timing.episode_steps`` (overrides included); ``metadata["render_fps"]`` is
    1 / control period; ``gymnasium.make_vec(..., vectorization_mode="sync"|"async")`` works. With
    ``observation.critic_pedestrians=K`` (training an asymmetric critic) ``info["critic"]`` holds
    ``critic_size`` = 6·K privileged values (:mod:`mjnav.tasks.privileged`); the observation is unchanged.
Version History:
    v1: first release. 2026-12-02, same id: a failed region is recovered (``region.on_failure``,
    default ``recover``; ``paper`` restores the first release's behaviour) and ``design`` selects
    the paper's ablation designs (default ``ours``, unchanged).
    v2 (2026-12-06, ``mjnav/StageK-v2`` next to each v1 id; v1 unchanged): bounded spaces for
    standard RL clients (Stable-Baselines3, Gymnasium's ``RescaleAction``): actions
    ``Box(-1, 1)`` = 2·(α_s, β_s, α_l, β_l) − 1, observations within bounds from the config;
    the same episodes as v1 (:mod:`mjnav.envs.bounded`; the env card of the documentation).
    2026-12-07, both, same episodes: :meth:`NavGymEnv.step_stages`; a step that raised after its
    action was accepted makes the next ``step`` raise until ``reset()``.
"""

from __future__ import annotations

from collections.abc import Generator
from typing import Any, TypeVar

import gymnasium as gym
import numpy as np

from mjnav.config import TaskConfig
from mjnav.envs.factory import make_env, resolve_config
from mjnav.tasks.privileged import critic_size
from mjnav.viz.gl import select_gl_backend
from mjnav.viz.scene import OffscreenView, RenderConfig, camera_ids, make_drawer

__all__ = ["NavGymEnv", "make_gym_env", "make_registered", "run_stages"]

_CAMERAS = ("top", "track")


class NavGymEnv(gym.Env):
    """Gymnasium view of :class:`mjnav.tasks.nav.CrowdNavTask`."""

    metadata = {"render_modes": ["rgb_array"], "render_fps": 10}

    def __init__(
        self,
        task: str | TaskConfig = "stage6",
        overrides: dict | list[str] | None = None,
        seed: int | None = None,
        render_mode: str | None = None,
        timing_info: bool = False,
        task_steps: bool = True,
        render_size: tuple[int, int] = (480, 480),
        render_camera: str = "top",
        render_overlays: bool = False,
    ) -> None:
        """Build the composer environment (compiled once).

        Args:
            task: Stage name, YAML path or :class:`TaskConfig`.
            overrides: Dotted config overrides.
            seed: Seed of the environment's random state.
            render_mode: ``"rgb_array"`` (``render()`` returns a frame) or None (``render()``
                warns and returns None).
            timing_info: Add wall-clock MPC solve times (``info["mpc"]["solve_time_ms"]``); off by
                default so that ``info`` is a deterministic function of seed and actions.
            task_steps: Step through the task alone (``NavEnvironment.step_task``: the same
                hooks, results and errors, without composer's observation updater and
                ``TimeStep``, about a tenth of a step) whenever, at reset, nothing else takes
                part in a step; False: always ``composer.Environment.step``.
            render_size: (width, height) of ``render()`` frames, pixels (at most 640 x 480).
            render_camera: ``top`` (the room from above) or ``track`` (following the robot).
            render_overlays: Draw the goal, the convex region, Q^s, Q^l and the MPC prediction.

        Raises:
            ValueError: An unknown ``render_mode`` or ``render_camera``, or a bad ``render_size``.
        """
        if render_mode not in (None, *self.metadata["render_modes"]):
            modes = self.metadata["render_modes"]
            raise ValueError(f"render_mode: expected None or one of {modes}, got {render_mode!r}")
        if render_camera not in _CAMERAS:
            raise ValueError(f"render_camera: expected one of {_CAMERAS}, got {render_camera!r}")
        self._render_config = RenderConfig(render_camera, *(int(x) for x in render_size))  # checks the size
        self._render_overlays = bool(render_overlays)
        self._view = None
        self._timing_info = timing_info
        self._task_steps = task_steps
        self._step_task = False  # decided at every reset
        self._unfinished = False  # a step stopped part-way (see step_stages)
        self._episodes = 0  # resets so far (a step's stages refuse to go on past one)
        self.config = resolve_config(task, overrides)
        self._env = make_env(self.config, seed=seed)
        self.task = self._env.task
        size = self.task.core.observation_size
        self.observation_space = gym.spaces.Box(-np.inf, np.inf, (size,), np.float32)
        self.action_space = gym.spaces.Box(-np.inf, np.inf, (self.task.core.design.action_size,), np.float32)
        self.critic_size = critic_size(self.config.observation.critic_pedestrians)
        self.render_mode = render_mode
        self.metadata = {**self.metadata, "render_fps": round(1.0 / self.config.timing.control_period)}

    @property
    def physics(self):
        """The composer environment's physics."""
        return self._env.physics

    def reset(self, *, seed: int | None = None, options: dict[str, Any] | None = None):
        """Start an episode; ``options={"episode_seed": k}`` selects a fixed scenario.

        Raises:
            ValueError: ``seed`` outside [0, 2**32) or ``episode_seed`` outside [0, 2**63) or not an integer.
        """
        _check_seed("seed", seed, 2**32)
        episode_seed = (options or {}).get("episode_seed")
        _check_seed("episode_seed", episode_seed, 2**63)
        super().reset(seed=seed)
        if seed is not None:
            self._env.random_state.seed(seed)
        if episode_seed is not None:
            self.task.next_episode_seed = int(episode_seed)
        timestep = self._env.reset()
        self._step_task = self._task_steps and self._env.can_step_task()
        self._unfinished = False
        self._episodes += 1
        return timestep.observation["observation"].copy(), self._info()

    def step(self, action):
        """One control step (0.1 s).

        Raises:
            RuntimeError: If the episode has ended, or an earlier step did not finish (call
                ``reset()`` first).
        """
        return run_stages(self.step_stages(action))

    def step_stages(self, action) -> Generator[None, None, tuple]:
        """:meth:`step` in stages: each ``next()`` runs one; the last ends the generator with
        ``StopIteration`` carrying :meth:`step`'s return value (:func:`run_stages` runs them all).

        The stages of a task step (:meth:`mjnav.envs.environment.NavEnvironment.step_stages`), or
        one stage holding composer's whole step. The action is checked at the first ``next()``; a
        refused action changes nothing. A step that stops once its action was taken (a stage
        raised, or the generator was dropped) may leave the world part-way through a control
        period: the next step raises until ``reset()``, and the stages of a step cannot go on
        past a reset. Subclasses change a step here, not in :meth:`step` (:attr:`stages_are_step`).
        """
        if self.task.layout is None or self.task.outcome.done:
            raise RuntimeError("the episode has ended (or never started): call reset() before step()")
        if self._unfinished:
            raise RuntimeError("an earlier step stopped part-way (it raised, or its stages were not all run): "
                               "call reset() before step()")
        try:
            action = np.asarray(action, dtype=np.float32)
        except (TypeError, ValueError):
            raise ValueError(f"action: expected {self.action_space.shape[0]} numbers, got {action!r}") from None
        self.task.check_action(action)  # a refused action changes nothing
        self._unfinished, episode = True, self._episodes
        if self._step_task:
            for _ in self._env.step_stages(action):
                yield
                if self._episodes != episode:
                    raise RuntimeError("the environment was reset within this step: its other stages cannot run")
            obs, reward = self.task.observation, float(self.task.get_reward(None))
        else:
            timestep = self._env.step(action)
            obs, reward = timestep.observation["observation"].copy(), float(timestep.reward)
        self._unfinished = False
        outcome = self.task.outcome
        terminated = outcome.terminal
        truncated = outcome.done and not terminated
        return obs, reward, terminated, truncated, self._info()

    @property
    def stages_are_step(self) -> bool:
        """Whether :meth:`step_stages` does what :meth:`step` does: ``step`` is not overridden (by a
        subclass or on the instance), so stepping stage by stage (:func:`mjnav.envs.workers.step_in_stages`)
        skips nothing."""
        return type(self).step is NavGymEnv.step and "step" not in vars(self)

    def _info(self) -> dict[str, Any]:
        record = self.task.core.record
        mpc = {"region_success": float(self.task.core.region.success)}
        if record is not None:
            mpc["fallback"] = float(record.fallback is not None)  # this step's plan (baselines: never)
            mpc["plan_region_success"] = float(record.region_ok)  # the region that plan used
            if self._timing_info:
                mpc["solve_time_ms"] = 1e3 * record.solve_time_s
        info = {
            "outcome": self.task.outcome.value,
            "reward_terms": dict(self.task.terms),
            "mpc": mpc,
            "episode_seed": self.task.episode_seed,
            "collision_kind": self.task.contact_kind,
        }
        if self.critic_size:
            info["critic"] = self.task.critic_observation
        return info

    def render(self) -> np.ndarray | None:
        """An RGB frame (height, width, 3) uint8 of the current state with ``render_mode="rgb_array"``
        (needs an off-screen GL backend, :func:`mjnav.viz.gl.select_gl_backend`); None otherwise."""
        if self.render_mode is None:
            gym.logger.warn("render() without render_mode: pass render_mode='rgb_array' to the constructor or make()")
            return None
        cfg = self._render_config
        if self._view is None:
            self._view = OffscreenView(self.physics.model.ptr, cfg.width, cfg.height, select_gl_backend())
        draw = make_drawer(self.task, self.physics, rays=False) if self._render_overlays and self.task.layout is not None else None
        return self._view.render(self.physics.data.ptr, camera_ids(self.task, self.physics, cfg.view)[0], draw)

    def close(self) -> None:
        """Free the physics and the renderer; closing again does nothing (Gymnasium's contract)."""
        if not getattr(self, "_closed", False):
            self._closed = True
            if getattr(self, "_view", None) is not None:
                self._view.close()
            self._env.close()


def _check_seed(name: str, value: Any, bound: int) -> None:
    if value is None:
        return
    if isinstance(value, bool) or not isinstance(value, (int, np.integer)) or not 0 <= int(value) < bound:
        raise ValueError(f"{name}: expected an integer in [0, {bound}), got {value!r}")


_T = TypeVar("_T")


def run_stages(stages: Generator[None, None, _T]) -> _T:
    """Run a staged step (:meth:`NavGymEnv.step_stages`) to its end; its return value."""
    try:
        while True:
            next(stages)
    except StopIteration as done:
        return done.value


def make_gym_env(config: TaskConfig | str, seed: int | None = None, **kwargs: Any) -> NavGymEnv:
    """Factory used by the vectorised rsl-rl adapter and scripts."""
    return NavGymEnv(config, seed=seed, **kwargs)


def make_registered(task: str | TaskConfig = "stage6", **kwargs: Any) -> gym.Env:
    """Entry point of the registered ids: the environment inside a ``TimeLimit`` of its own
    ``timing.episode_steps``, so ``spec.max_episode_steps`` reports the episode length that the
    overrides give (a fixed registration value would cut a longer episode short)."""
    env = NavGymEnv(task, **kwargs)
    return gym.wrappers.TimeLimit(env, env.config.timing.episode_steps)
