"""Gymnasium adapter over the composer environment.

Environment card (Gymnasium style)

Description:
    An omni-directional disc robot must reach a goal in a walled room with static polygon
    obstacles and a crowd of moving cylinders, acting through a learned choice of two reference
    points inside the LiDAR's convex free-space polygon that an MPC tracks (spec §3-§5).
Action Space:
    ``Box(-inf, inf, (4,), float32)``: raw (α_s, β_s, α_l, β_l), squashed by a sigmoid inside
    (``design=design1|design2``: (v_x, v_y) before tanh; ``design3``: (α_l, β_l); see
    :mod:`mjnav.tasks.design`).
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
    ``gymnasium.make("mjnav/Stage6-v1", overrides=["crowd.count=25"])``.
Version History:
    v1: first release. 2026-12-02, same id: a failed region is recovered (``region.on_failure``,
    default ``recover``; ``paper`` restores the first release's behaviour) and ``design`` selects
    the paper's ablation designs (default ``ours``, unchanged).
"""

from __future__ import annotations

from typing import Any

import gymnasium as gym
import numpy as np

from mjnav.config import TaskConfig
from mjnav.envs.factory import make_env, resolve_config

__all__ = ["NavGymEnv", "make_gym_env"]


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
    ) -> None:
        """Build the composer environment (compiled once).

        Args:
            task: Stage name, YAML path or :class:`TaskConfig`.
            overrides: Dotted config overrides.
            seed: Seed of the environment's random state.
            render_mode: ``"rgb_array"`` or None.
            timing_info: Add wall-clock MPC solve times (``info["mpc"]["solve_time_ms"]``); off by
                default so that ``info`` is a deterministic function of seed and actions.
            task_steps: Step through the task alone (``NavEnvironment.step_task``: the same
                hooks, results and errors, without composer's observation updater and
                ``TimeStep``, about a tenth of a step) whenever, at reset, nothing else takes
                part in a step; False: always ``composer.Environment.step``.
        """
        self._timing_info = timing_info
        self._task_steps = task_steps
        self._step_task = False  # decided at every reset
        self.config = resolve_config(task, overrides)
        self._env = make_env(self.config, seed=seed)
        self.task = self._env.task
        size = self.task.core.observation_size
        self.observation_space = gym.spaces.Box(-np.inf, np.inf, (size,), np.float32)
        self.action_space = gym.spaces.Box(-np.inf, np.inf, (self.task.core.design.action_size,), np.float32)
        self.render_mode = render_mode

    @property
    def physics(self):
        """The composer environment's physics."""
        return self._env.physics

    def reset(self, *, seed: int | None = None, options: dict[str, Any] | None = None):
        """Start an episode; ``options={"episode_seed": k}`` selects a fixed scenario."""
        super().reset(seed=seed)
        if seed is not None:
            self._env.random_state.seed(seed)
        if options and "episode_seed" in options:
            self.task.next_episode_seed = int(options["episode_seed"])
        timestep = self._env.reset()
        self._step_task = self._task_steps and self._env.can_step_task()
        return timestep.observation["observation"].copy(), self._info()

    def step(self, action):
        """One control step (0.1 s).

        Raises:
            RuntimeError: If the episode has ended (call ``reset()`` first).
        """
        if self.task.layout is None or self.task.outcome.done:
            raise RuntimeError("the episode has ended (or never started): call reset() before step()")
        action = np.asarray(action, dtype=np.float32)
        if self._step_task:
            self._env.step_task(action)
            obs, reward = self.task.observation, float(self.task.get_reward(None))
        else:
            timestep = self._env.step(action)
            obs, reward = timestep.observation["observation"].copy(), float(timestep.reward)
        outcome = self.task.outcome
        terminated = outcome.terminal
        truncated = outcome.done and not terminated
        return obs, reward, terminated, truncated, self._info()

    def _info(self) -> dict[str, Any]:
        record = self.task.core.record
        mpc = {"region_success": float(self.task.core.region.success)}
        if record is not None:
            mpc["fallback"] = float(record.fallback is not None)  # this step's plan (baselines: never)
            mpc["plan_region_success"] = float(record.region_ok)  # the region that plan used
            if self._timing_info:
                mpc["solve_time_ms"] = 1e3 * record.solve_time_s
        return {
            "outcome": self.task.outcome.value,
            "reward_terms": dict(self.task.terms),
            "mpc": mpc,
            "episode_seed": self.task.episode_seed,
            "collision_kind": self.task.contact_kind,
        }

    def render(self):
        """Top-down RGB frame (needs an off-screen GL backend)."""
        return self._env.physics.render(height=480, width=480, camera_id=0)

    def close(self) -> None:
        """Free the physics; closing again does nothing (Gymnasium's contract)."""
        if not getattr(self, "_closed", False):
            self._closed = True
            self._env.close()


def make_gym_env(config: TaskConfig | str, seed: int | None = None, **kwargs: Any) -> NavGymEnv:
    """Factory used by the vectorised rsl-rl adapter and scripts."""
    return NavGymEnv(config, seed=seed, **kwargs)
