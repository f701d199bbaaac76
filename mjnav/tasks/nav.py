"""``CrowdNavTask``: the dm_control composer task for every stage.

One control step (``timing.control_period``, 0.1 s) is: the previous step's scan
and free-space polygon → the action (4 raw values, squashed by a sigmoid here)
→ reference points → MPC jerk → the robot tracks it over the physics substeps
while the pedestrians move → scan, outcome, reward and the next observation.

Stages differ only by their :class:`mjnav.config.TaskConfig`.
"""

from __future__ import annotations

import time

import numpy as np
from dm_control import composer
from dm_control.composer.observation import observable
from dm_env import specs

from mjnav.geometry.raycast import beam_angles, cast_rays
from mjnav.planners.base import declared_privileged, declared_tracks
from mjnav.sim import NavSim
from mjnav.tasks.core import NavCore, Outcome
from mjnav.tasks.privileged import CrowdTracker, critic_size, pedestrian_features

__all__ = ["TRAINING_SEED_LIMIT", "CrowdNavTask"]

TRAINING_SEED_LIMIT = 2**31 - 1
"""Episode seeds drawn from the environment's random state lie in [0, TRAINING_SEED_LIMIT)."""


class CrowdNavTask(composer.Task):
    """Reach the goal through static obstacles and a crowd, acting through convex MPC."""

    def __init__(self, config) -> None:
        """Build the world once (fixed slots) for a :class:`mjnav.config.TaskConfig`."""
        self.config = config
        self.sim = NavSim(config, rangefinders=config.lidar.rangefinders)
        self.core = NavCore(config)
        self.set_timesteps(config.timing.control_period, config.timing.physics_timestep)
        self._obs = np.zeros(self.core.observation_size, dtype=np.float32)
        self._critic = np.zeros(critic_size(config.observation.critic_pedestrians), dtype=np.float32)
        self._tracker = CrowdTracker()
        self._reward = 0.0
        self.terms: dict[str, float] = {}
        self.next_episode_seed: int | None = None
        self.episode_seed: int | None = None
        self.layout = None
        self.contact_kind: str | None = None  # wall, obstacle or pedestrian after a contact
        self.planner = None  # a mjnav.planners.base.Planner replaces the learned action layer when set
        self._scan = None
        self.timers = {"physics": 0.0, "lidar": 0.0}  # seconds, accumulated; NavCore has the rest
        self._t_physics: float | None = None  # start of composer's own substeps (None: run_substeps timed them)
        self._physics_time = 0.0  # seconds of this period's physics so far
        self._sensed: tuple | None = None  # what sense() read, for score()
        self._observable = observable.Generic(lambda physics: self._obs)
        self._observable.enabled = True

    @property
    def root_entity(self):
        """The arena, with the robot and the crowd attached."""
        return self.sim.root_entity

    @property
    def task_observables(self):
        """One observable, ``observation`` (spec §6, float32)."""
        return {"observation": self._observable}

    def action_spec(self, physics) -> specs.Array:
        """The design's raw action: four pre-sigmoid values α_s, β_s, α_l, β_l for ``ours`` and
        Design 4, (α_l, β_l) for Design 3, (v_x, v_y) before tanh for Designs 1-2."""
        del physics
        names = {"points": "alpha_s,beta_s,alpha_l,beta_l", "long_point": "alpha_l,beta_l", "velocity": "vx,vy"}
        design = self.core.design
        return specs.Array(shape=(design.action_size,), dtype=np.float32, name=names[design.action])

    def get_reward_spec(self) -> specs.Array:
        """A float64 scalar."""
        return specs.Array(shape=(), dtype=np.float64, name="reward")

    # ------------------------------------------------------------------ episode
    def initialize_episode(self, physics, random_state: np.random.RandomState) -> None:
        """Draw the episode seed, place everything by binding and compute the first observation."""
        seed = self.next_episode_seed
        self.next_episode_seed = None
        if seed is None:
            seed = int(random_state.randint(0, TRAINING_SEED_LIMIT))
        self.episode_seed = seed
        self.rng = np.random.default_rng(seed)
        self.layout = self.sim.initialize_episode(physics, self.rng)
        p, v, _ = self.sim.robot_state(physics)
        scan = self._scan = self.sim.scan(physics, self.rng)
        self.core.use_tracks(self.tracks_enabled)
        self._obs[:] = self.core.reset(self.layout.goal, p, v, scan)
        self._tracker.reset()
        self._observe_crowd(physics, p)
        if self.planner is not None:
            self.planner.reset(self.config, np.random.default_rng([seed, 1]))  # own stream: scenario stays paired
        self._reward = 0.0
        self.terms = {}
        self.contact_kind = None

    @property
    def tracks_enabled(self) -> bool:
        """Whether the LiDAR tracker runs this episode: ``tracks.enabled``, a planner declaring
        ``uses_tracks``, an observation holding tracks (``observation.tracks`` > 0) or the action
        layer's crowd shield (``shield.enabled``); decided at each episode start."""
        return (self.config.tracks.enabled or self.config.observation.tracks > 0 or self.config.shield.enabled
                or declared_tracks(self.planner))

    @property
    def tracks(self) -> np.ndarray | None:
        """(T, 5) ``[x, y, vx, vy, r]`` the tracker's confirmed moving pedestrians after the last scan,
        world frame (metres, m/s), nearest first, read-only (:attr:`NavCore.tracks`); None when off.

        Updated right after each scan (episode start and every step), so the planner of the next
        step and the observation of this one see the same tracks. Made from the robot's noisy scan
        and its position only: no simulator ground truth, no random draw.
        """
        return self.core.tracks

    def check_action(self, action) -> None:
        """Raises ``ValueError`` for an action :meth:`before_step` would refuse (:meth:`NavCore.check_action`;
        none while a planner acts), before anything changes."""
        if self.planner is None:
            self.core.check_action(action)

    def before_step(self, physics, action, random_state) -> None:
        """Turn the action into a jerk command for the coming control period."""
        del random_state
        state = p, v, a = self.sim.robot_state(physics)
        if self.planner is None:
            jerk = self.core.plan(action, p, v, a)
        else:
            jerk = self.core.plan_with(self.planner, self._scan, p, v, a, self._crowd_truth())
        t0 = time.perf_counter()  # the command starts the period (crowd, tracking)
        self.sim.apply_command(physics, jerk, state)
        self._t_physics = t1 = time.perf_counter()  # composer's own substeps run from here to after_step
        self._physics_time = t1 - t0

    def _crowd_truth(self) -> dict[str, np.ndarray]:
        """The pedestrians' ground truth the planner declared (``privileged``), read-only copies."""
        declared = declared_privileged(self.planner)
        if not declared:
            return {}
        circles = self.sim.pedestrian_circles()
        truth = {"positions": circles[:, :2], "radii": circles[:, 2]}
        if "velocities" in declared:
            truth["velocities"] = self.sim.pedestrian_velocities()
        if "goals" in declared:
            truth["goals"] = self.sim.pedestrian_goals()
        chosen = {key: truth[key] for key in declared}
        for value in chosen.values():
            value.flags.writeable = False  # the planner reads them; writing would change nothing anyway
        return chosen

    def before_substep(self, physics, action, random_state) -> None:
        """Move the pedestrians and apply the tracking force."""
        del action, random_state
        self.sim.before_substep(physics)

    @property
    def fused_substeps(self) -> bool:
        """Whether :meth:`run_substeps` may stand in for the substep hooks (not overridden, ``sim.fused``)."""
        before = getattr(self.before_substep, "__func__", None)  # an instance attribute may replace it
        after = getattr(self.after_substep, "__func__", None)
        return before is CrowdNavTask.before_substep and after is composer.Task.after_substep and self.sim.fused

    def run_substeps(self, physics) -> None:
        """All of the step's substeps (hooks and ``mj_step``) at once: :meth:`NavSim.run_period`.

        Timed on its own: a staged step (:meth:`mjnav.envs.environment.NavEnvironment.step_stages`)
        runs other environments' stages between this and :meth:`before_step` or :meth:`sense`.
        """
        t0 = time.perf_counter()
        self.sim.run_period(physics)
        self._physics_time += time.perf_counter() - t0
        self._t_physics = None

    def after_step(self, physics, random_state) -> None:
        """Scan, score the step and build the next observation: :meth:`sense`, then :meth:`score`."""
        del random_state
        self.sense(physics)
        self.score(physics)

    @property
    def splits_after_step(self) -> bool:
        """Whether :meth:`sense` then :meth:`score` may stand in for :meth:`after_step` (not overridden)."""
        return getattr(self.after_step, "__func__", None) is CrowdNavTask.after_step

    def sense(self, physics) -> None:
        """First half of :meth:`after_step`: the robot state, the scan and the contacts after the period."""
        t_sync = time.perf_counter()
        self.sim.sync(physics)
        t0 = time.perf_counter()
        substeps = 0.0 if self._t_physics is None else t_sync - self._t_physics  # composer's own substeps
        self.timers["physics"] += self._physics_time + substeps + (t0 - t_sync)
        p, v, _ = self.sim.robot_state(physics)
        scan = self._scan = self.sim.scan(physics, self.rng)
        self.timers["lidar"] += time.perf_counter() - t0
        contact, self.contact_kind = self.sim.robot_in_collision(physics)
        self._sensed = (p, v, scan, contact)

    def score(self, physics) -> None:
        """Second half of :meth:`after_step`: reward, outcome and observation from what :meth:`sense` read."""
        if self._sensed is None:
            raise RuntimeError("score() without sense() in this step")
        p, v, scan, contact = self._sensed
        self._sensed = None
        obs, self._reward, self.terms = self.core.finish_step(p, v, scan, contact)
        self._obs[:] = obs
        self._observe_crowd(physics, p)

    def _observe_crowd(self, physics, position: np.ndarray) -> None:
        """Refresh the privileged critic input (``observation.critic_pedestrians`` > 0)."""
        count = self.config.observation.critic_pedestrians
        if not count:
            return
        circles = self.sim.pedestrian_circles()
        velocities = self._tracker.update(float(physics.data.time), circles[:, :2])
        rotation = self.core.frame_rotation(position)
        self._critic[:] = pedestrian_features(position, circles, velocities, count, rotation)

    def scan_hit_kind(self, physics) -> str | None:
        """What the shortest beam of the last scan hit: ``wall``, ``obstacle``, ``pedestrian`` or None.

        The kind of a collision under the paper's rule (``collision=scan``: shrunk scan <= 0). That
        beam is cast again from the robot centre, exactly and without noise, against the walls, the
        obstacle edges and the pedestrians; the nearest hit names the kind (None when the beam hits
        nothing in range: only noise made it short). Reads the state only (no random draw).
        """
        if self._scan is None:
            return None
        angle = beam_angles(len(self._scan))[int(np.argmin(self._scan))]
        origin, _, _ = self.sim.robot_state(physics)
        segments, walls, reach = self.sim.segments, 4, self.config.lidar.max_range  # wall_segments: 4 faces first
        ranges = [cast_rays(origin, np.array([angle]), segments[:walls], None, reach)[0],
                  cast_rays(origin, np.array([angle]), segments[walls:], None, reach)[0],
                  cast_rays(origin, np.array([angle]), None, self.sim.pedestrian_circles(), reach)[0]]
        nearest = int(np.argmin(ranges))
        return ("wall", "obstacle", "pedestrian")[nearest] if ranges[nearest] < reach else None

    # ------------------------------------------------------------------ scoring
    @property
    def outcome(self) -> Outcome:
        """The episode's current :class:`Outcome`."""
        return self.core.outcome

    @property
    def observation(self) -> np.ndarray:
        """The current observation (spec §6, float32), a copy."""
        return self._obs.copy()

    @property
    def critic_observation(self) -> np.ndarray:
        """The privileged critic input (:mod:`mjnav.tasks.privileged`; empty when off), a copy."""
        return self._critic.copy()

    def get_reward(self, physics) -> float:
        """Σ weight·term of the last step (spec §7)."""
        del physics
        return self._reward

    def get_discount(self, physics) -> float:
        """0 on success or collision, 1 otherwise (a timeout is a truncation)."""
        del physics
        return 0.0 if self.core.outcome.terminal else 1.0

    def should_terminate_episode(self, physics) -> bool:
        """Ends on success, collision or timeout."""
        del physics
        return self.core.outcome.done
