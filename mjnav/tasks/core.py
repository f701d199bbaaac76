"""The MuJoCo-free logic of one navigation episode.

:class:`NavCore` turns a scan and the robot state into the observation, turns a
raw action into a jerk command through the action layer (region → reference
points → MPC), and scores the step (reward terms and :class:`Outcome`). The
composer task (:mod:`mjnav.tasks.nav`) only moves numbers between this and
``physics``.
"""

from __future__ import annotations

import dataclasses
import enum
import math
import time
from collections.abc import Mapping

import numpy as np

from mjnav.control.action import (ActionPoints, boundary_distance, goal_inside, heading_angle, map_action_values,
                                  radii)
from mjnav.control.crowd import shield_points
from mjnav.control.dynamics import Limits, escape, track_velocity
from mjnav.control.guarded import GuardedMpc
from mjnav.geometry.raycast import beam_angles
from mjnav.geometry.region import Region, RegionFinder, scan_polygon
from mjnav.perception.tracker import Tracker
from mjnav.planners.base import Planner, PlannerInput
from mjnav.planners.tracks import relative_tracks
from mjnav.tasks import observation as obs_lib
from mjnav.tasks import reward as reward_lib
from mjnav.tasks.design import get_design

__all__ = ["NavCore", "Outcome", "StepRecord", "sigmoid"]

_ORIGIN = np.zeros(2)


class Outcome(enum.Enum):
    """How an episode stands; decides discount, termination and metrics."""

    RUNNING = "running"
    SUCCESS = "success"
    COLLISION = "collision"
    TIMEOUT = "timeout"

    @property
    def terminal(self) -> bool:
        """Success or collision: the episode ends with discount 0."""
        return self in (Outcome.SUCCESS, Outcome.COLLISION)

    @property
    def done(self) -> bool:
        """Any outcome but running ends the episode."""
        return self is not Outcome.RUNNING


def sigmoid(x: np.ndarray) -> np.ndarray:
    """Logistic function, elementwise, numerically safe for large |x|."""
    return 0.5 * (1.0 + np.tanh(0.5 * np.asarray(x, dtype=np.float64)))


class StepRecord:
    """What the last control step decided (for info, logging and rendering).

    Positions are in the world frame, metres. ``q_l_target``, ``predicted`` and ``polygon`` are
    kept relative to the robot position and moved to the world frame when read (only rendering
    reads them).

    Attributes:
        q_s, q_l: (2,) short- and long-term reference points.
        q_l_target: (2,) the long-term point before the MPC's reachability limit.
        predicted: (N, 2) the MPC's predicted positions.
        polygon: (K, 2) the free-space polygon the plan used (vertices, or the fallback points).
        plan_ok: The MPC solved (no fallback).
        fallback: The fallback used, or None.
        solve_time_s: Wall-clock time of the MPC solve, seconds.
        region_ok: The region of this step was found.
    """

    __slots__ = ("_origin", "_relative", "fallback", "plan_ok", "q_l", "q_s", "region_ok", "solve_time_s")

    def __init__(self, origin: np.ndarray, q_s: np.ndarray, q_l: np.ndarray, q_l_target: np.ndarray,
                 predicted: np.ndarray, polygon: np.ndarray, plan_ok: bool, fallback: str | None,
                 solve_time_s: float, region_ok: bool) -> None:
        """``origin`` (2,) is the robot position; ``q_l_target``, ``predicted`` and ``polygon`` are
        relative to it, ``q_s`` and ``q_l`` are in the world frame."""
        self.q_s, self.q_l = q_s, q_l
        self.plan_ok, self.fallback, self.solve_time_s, self.region_ok = plan_ok, fallback, solve_time_s, region_ok
        self._origin, self._relative = origin, (q_l_target, predicted, polygon)

    @property
    def q_l_target(self) -> np.ndarray:
        """(2,) world frame, metres."""
        return self._origin + self._relative[0]

    @property
    def position(self) -> np.ndarray:
        """(2,) robot position the plan was made at, world frame, metres."""
        return self._origin

    @property
    def predicted(self) -> np.ndarray:
        """(N, 2) world frame, metres."""
        return self._origin + self._relative[1]

    @property
    def polygon(self) -> np.ndarray:
        """(K, 2) world frame, metres."""
        return self._origin + self._relative[2]


class _LongPoint:
    """Design 3's action points in the shape :meth:`NavCore._remember` reads (Q_s unused: origin)."""

    def __init__(self, q_l: np.ndarray, q_l_ref: np.ndarray) -> None:
        self.q_s, self.q_l, self.q_l_ref = _ORIGIN, q_l, q_l_ref


class NavCore:
    """Observation, action layer, reward and outcome of one environment."""

    def __init__(self, config) -> None:
        """Build the action layer for a :class:`mjnav.config.TaskConfig`."""
        self.config = config
        self._inflation = config.region.inflation
        self.design = get_design(config.design)
        self._angles = beam_angles(config.lidar.beams)
        self._find_region = RegionFinder(self._angles, config.region)
        self._mpc = GuardedMpc(config.mpc, config.region, self.design.polygon_constraint)
        self._columns = np.array(self.design.state_columns)
        self._limits = Limits.from_task(config)
        self._stack = obs_lib.FrameStack(config.observation.frames, config.region.num_points, self.design.state_size,
                                         config.observation.frame_stride)
        self._aligned = (obs_lib.RegionHistory(config.observation.frames, config.observation.frame_stride,
                                               config.region.num_points)
                         if config.observation.history == "aligned" else None)
        self._reward_terms = reward_lib.weighted_terms(config.reward)
        self.counters = {"region_failures": 0, "region_recoveries": 0, "escapes": 0, "fallbacks": 0, "steps": 0,
                         "shield_overrides": 0}
        self.timers = dict.fromkeys(("region", "action", "mpc", "reward", "observation"), 0.0)  # seconds
        self._tracker: Tracker | None = None  # the LiDAR tracker, built by use_tracks(True)
        self._tracks_on = False
        self._tracks: np.ndarray | None = None

    # ------------------------------------------------------------------ tracks
    def use_tracks(self, enabled: bool) -> None:
        """Run the LiDAR pedestrian tracker from the next :meth:`reset` on (or stop it).

        The tracker (:class:`mjnav.perception.Tracker`, ``config.tracks``) is built on first use
        and reset with every episode; it reads only the scans and positions given to
        :meth:`reset` and :meth:`finish_step` and draws no random number.
        """
        self._tracks_on = bool(enabled)
        if self._tracks_on and self._tracker is None:
            lidar = self.config.lidar
            self._tracker = Tracker(self.config.tracks, beams=lidar.beams, max_range=lidar.max_range)

    @property
    def tracks(self) -> np.ndarray | None:
        """(T, 5) ``[x, y, vx, vy, r]`` confirmed moving-pedestrian tracks from the last scan (world
        frame, metres, m/s), nearest to the robot first (read-only); None when the tracker is off."""
        return self._tracks if self._tracks_on else None

    def _update_tracks(self, scan: np.ndarray, position: np.ndarray) -> None:
        """One tracker step on the scan just taken at ``position`` (metres); no-op when off."""
        if not self._tracks_on:
            self._tracks = None
            return
        self._tracker.step(scan, position, self.config.timing.control_period)
        found = self._tracker.track_array()[:, :5]
        order = np.argsort(np.hypot(found[:, 0] - position[0], found[:, 1] - position[1]), kind="stable")
        self._tracks = np.ascontiguousarray(found[order])
        self._tracks.flags.writeable = False

    # ------------------------------------------------------------------ episode
    def reset(self, goal: np.ndarray, position: np.ndarray, velocity: np.ndarray, scan: np.ndarray) -> np.ndarray:
        """Start an episode; returns the first (stacked) observation."""
        self.goal = np.asarray(goal, dtype=np.float64).copy()
        self._goal = tuple(self.goal.tolist())  # plain floats for the per-step arithmetic
        self.steps = 0
        self.outcome = Outcome.RUNNING
        self.min_scan = math.inf  # the last step's shrunk scan minimum (the paper's rule collides at <= 0)
        self._mpc.reset()
        self._plan: obs_lib.Plan | None = None
        self._prev = {"q_s": None, "q_l": None, "plan_ok": False, "distance": None, "velocity": velocity.copy()}
        self.record: StepRecord | None = None
        if self._tracks_on:
            self._tracker.reset()
        self._update_tracks(scan, position)
        self.region = self._region(scan)  # not timed: part of reset
        polygon, state = self._frame(position, velocity)
        obs = self._stack.reset(polygon, state)
        if self._aligned is not None:
            self._aligned.reset(self.region.boundary_xy, position)
            obs = self._align(obs, position)
        return self._with_tracks(obs, position)

    def _with_tracks(self, obs: np.ndarray, position: np.ndarray) -> np.ndarray:
        """``observation.tracks=K``: the stack followed by the K nearest of :attr:`tracks` (float32;
        the task runs the tracker for it); else ``obs``."""
        count = self.config.observation.tracks
        if not count:
            return obs
        block = obs_lib.tracks_block(self.tracks, position, count, self.frame_rotation(position))
        return np.concatenate([obs, block.astype(np.float32)])

    def _align(self, obs: np.ndarray, position: np.ndarray) -> np.ndarray:
        """``observation.history='aligned'``: re-read the older polygon blocks from ``position``."""
        return self._aligned.rewrite(obs, self.region.boundary, position, self._inflation,
                                     self.frame_rotation(position))

    def _region(self, scan: np.ndarray) -> Region:
        """The scan's convex region, or (designs that see the scan) its scan' polygon."""
        self._scan = scan
        if self.design.observe == "scan":
            return scan_polygon(scan, self._angles, self.config.region)
        region = self._find_region(scan)
        if not region.success:
            self.counters["region_failures"] += 1
            self.counters["region_recoveries"] += int(region.recovered)
        return region

    def frame_rotation(self, position: np.ndarray) -> float:
        """Angle (rad) of the observation's x axis in the world at ``position`` (metres): the goal's
        direction with ``observation.frame=goal``, else 0."""
        if self.config.observation.frame != "goal":
            return 0.0
        return math.atan2(self._goal[1] - position[1], self._goal[0] - position[0])

    def _frame(self, position: np.ndarray, velocity: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        rotation = self.frame_rotation(position)
        polygon = obs_lib.polygon_block(self.region.boundary, self._inflation, rotation)
        state = obs_lib.state_block(
            position, velocity, self.goal, self.region.success, self._plan, self._inflation,
            self.config.observation.angle, rotation,
        )
        return polygon, (state if self.design.name == "ours" else state[self._columns])

    # ------------------------------------------------------------------ action
    def check_action(self, action: np.ndarray) -> np.ndarray:
        """The raw action as ``design.action_size`` float64 values (what :meth:`plan` reads).

        Raises:
            ValueError: If the action has the wrong shape or a non-finite value.
        """
        action = np.asarray(action, dtype=np.float64).reshape(-1)
        size = self.design.action_size
        if action.shape != (size,) or not all(map(math.isfinite, action.tolist())):
            raise ValueError(f"action must be {size} finite values ({self.design.name}), got {action!r}")
        return action

    def plan(self, action: np.ndarray, position: np.ndarray, velocity: np.ndarray, accel: np.ndarray) -> np.ndarray:
        """Map a raw action (``design.action_size`` values) to the jerk over the next period (m/s³).

        Raises:
            ValueError: If the action has the wrong shape or a non-finite value.
        """
        action = self.check_action(action)
        (px, py), (gx, gy) = position.tolist(), self._goal
        motion = [*velocity.tolist(), *accel.tolist(), gx - px, gy - py]
        if not all(map(math.isfinite, motion)):  # checked once here, so the action layer need not
            raise ValueError(f"robot state is not finite: p={position}, v={velocity}, a={accel}")
        if self._mpc.must_escape(self.region):
            return self._plan_escape(position, velocity, accel)
        if self.design.action == "velocity":
            return self._plan_velocity(action, position, velocity, accel)
        if self.design.action == "long_point":
            return self._plan_long_point(action, position, velocity, accel)
        t0 = time.perf_counter()
        squashed = [0.5 * (1.0 + t) for t in np.tanh(0.5 * action).tolist()]  # sigmoid(action), on floats
        points = map_action_values(squashed + motion, self.region, self.config.action)
        if self.config.shield.enabled:
            points = self._shield(points, position, velocity)
        state = np.array((_ORIGIN, velocity, accel), dtype=np.float64)
        t1 = time.perf_counter()
        result = self._mpc.solve(state, points.q_s, points.q_l_ref, self.region, points.goal_inside)
        self.timers["action"] += t1 - t0
        self.timers["mpc"] += time.perf_counter() - t1
        plan_ok = result.fallback is None
        self.counters["fallbacks"] += int(not plan_ok)
        self._remember(points, result, position, plan_ok)
        return np.asarray(result.u0, dtype=np.float64)

    def _shield(self, points: ActionPoints, position: np.ndarray, velocity: np.ndarray) -> ActionPoints:
        """``shield.enabled``: the action's points, or the crowd shield's in their place (counted in
        ``shield_overrides``) when the motion towards its ``Q_l`` would come too close to a track
        (:func:`mjnav.control.crowd.shield_points`); ``Q_s`` then lies towards the new ``Q_l``."""
        if points.goal_inside or self.tracks is None or not len(self.tracks):
            return points
        tracks = relative_tracks(self.tracks, position)
        q_l = shield_points(self.region, self.goal - position, velocity, points.q_l_ref, tracks[:, [0, 1, 4]],
                            tracks[:, 2:4], self._inflation, self.config.action.long_time, self.config.shield)
        if q_l is None:
            return points
        self.counters["shield_overrides"] += 1
        length = math.hypot(*q_l.tolist())
        q_s = q_l * (min(points.r_s, length) / length) if length > 1e-9 else np.zeros(2)
        return dataclasses.replace(points, q_s=q_s, q_l=q_l, q_l_ref=q_l)

    def _plan_velocity(self, action: np.ndarray, position: np.ndarray, velocity: np.ndarray,
                       accel: np.ndarray) -> np.ndarray:
        """Designs 1-2: v = v_max·tanh(a) per axis, followed by the jerk-limited velocity tracker.

        With ``action.heading='velocity'`` the two axes are those of the velocity heading (x along
        v; heading of a zero vector 0), the frame the observation's dθ is measured in, as Ours'
        angles are; ``'absolute'`` reads them as world axes (the paper's equation taken literally);
        ``'goal'`` as along and across the goal direction.
        """
        command = self._limits.v_max * np.tanh(action)
        heading = self._action_heading(velocity, position)
        c, s = math.cos(heading), math.sin(heading)
        command = np.array((c * command[0] - s * command[1], s * command[0] + c * command[1]))
        self._no_plan(position, command * self.config.timing.control_period, None)
        return track_velocity(velocity, accel, command, self._limits)

    def _action_heading(self, velocity: np.ndarray, position: np.ndarray) -> float:
        """Angle (rad) the action's frame is turned by (``action.heading``, see
        :func:`~mjnav.control.action.heading_angle`)."""
        return heading_angle(self.config.action.heading, velocity.tolist(), (self.goal - position).tolist())

    def _plan_escape(self, position: np.ndarray, velocity: np.ndarray, accel: np.ndarray) -> np.ndarray:
        """No region even after recovery (``on_failure='recover'``): back away from the nearest returns."""
        self.counters["fallbacks"] += 1
        self.counters["escapes"] += 1
        self._no_plan(position, np.zeros(2), "escape")
        return escape(self._scan, self._angles, velocity, accel, self._limits, self.config.region.escape_speed)

    def _no_plan(self, position: np.ndarray, step: np.ndarray, fallback: str | None) -> None:
        """Pending reward inputs and record of a step without an MPC plan (``step``: commanded motion)."""
        here = position.copy()
        self._pending = {"plan": None, "q_s": here, "q_l": here, "q1": here, "qn": here, "plan_ok": False}
        self.record = StepRecord(here, here, here + step, np.zeros(2), np.zeros((1, 2)), self.region.boundary_xy,
                                 False, fallback, 0.0, bool(self.region.success))

    def _plan_long_point(self, action: np.ndarray, position: np.ndarray, velocity: np.ndarray,
                         accel: np.ndarray) -> np.ndarray:
        """Design 3: Q_l sampled like Q_s of spec §4 but in the long-term action space; the MPC
        tracks p_N only (``mpc.track_short`` is False for this design)."""
        t0 = time.perf_counter()
        alpha, beta = sigmoid(action).tolist()
        cfg = self.config.action
        theta = 2.0 * math.pi * alpha + self._action_heading(velocity, position)
        direction = np.array((math.cos(theta), math.sin(theta)))
        _, r_l = radii(velocity, accel, cfg)
        q_l = beta * min(boundary_distance(self.region, _ORIGIN, direction), r_l) * direction
        goal = self.goal - position
        inside = goal_inside(self.region, goal)
        state = np.array((_ORIGIN, velocity, accel), dtype=np.float64)
        t1 = time.perf_counter()
        result = self._mpc.solve(state, _ORIGIN, goal if inside else q_l, self.region, inside)
        self.timers["action"] += t1 - t0
        self.timers["mpc"] += time.perf_counter() - t1
        plan_ok = result.fallback is None
        self.counters["fallbacks"] += int(not plan_ok)
        points = _LongPoint(q_l, goal if inside else q_l)
        self._remember(points, result, position, plan_ok)
        self._pending["q_s"] = None  # Design 3 has no short-term point: its reward terms drop out
        return np.asarray(result.u0, dtype=np.float64)

    def _remember(self, points, result, position: np.ndarray, plan_ok: bool) -> None:
        q1, qn = result.positions[0], result.positions[-1]
        q_s, q_l, q1_world, qn_world = np.array((points.q_s, points.q_l, q1, qn)) + position  # world frame
        self._pending = {
            "plan": obs_lib.Plan(points.q_s, points.q_l, q1, qn, q1_world, qn_world) if plan_ok else None,
            "q_s": q_s,
            "q_l": q_l,
            "q1": q1_world,
            "qn": qn_world,
            "plan_ok": plan_ok,
        }
        region = self.region
        self.record = StepRecord(
            position.copy(), q_s, q_l, points.q_l_ref, result.positions,
            region.vertices if region.has_polygon else region.boundary_xy,
            plan_ok, result.fallback, result.solve_time_s, bool(region.success),
        )  # fmt: skip

    def plan_with(self, planner: Planner, scan: np.ndarray, position: np.ndarray, velocity: np.ndarray,
                  accel: np.ndarray, truth: Mapping[str, np.ndarray] | None = None) -> np.ndarray:
        """Jerk from a baseline planner (its action points are recorded as the robot position);
        ``truth``: the pedestrians' ground truth the planner declared (``positions``, ``velocities``,
        ``radii``, ``goals``: :attr:`PlannerInput.pedestrian_positions` ...), nothing else. The
        planner gets :attr:`tracks` as :attr:`PlannerInput.tracks` (None while the tracker is off)."""
        crowd = {f"pedestrian_{key}": value for key, value in (truth or {}).items()}
        inp = PlannerInput(scan, self._angles, position.copy(), velocity.copy(), accel.copy(), self.goal.copy(),
                           self.region, self.steps * self.config.timing.control_period, **crowd,
                           tracks=self.tracks)
        jerk = np.asarray(planner.act(inp), dtype=np.float64).reshape(2)
        if not np.all(np.isfinite(jerk)):
            raise ValueError(f"planner {type(planner).__name__} returned a non-finite jerk {jerk!r}")
        self._no_plan(position, np.zeros(2), None)
        return np.clip(jerk, -self._limits.j_max, self._limits.j_max)

    # ------------------------------------------------------------------ scoring
    def finish_step(
        self, position: np.ndarray, velocity: np.ndarray, scan: np.ndarray, contact: bool
    ) -> tuple[np.ndarray, float, dict[str, float]]:
        """Score the step that just ran and build the next observation.

        Args:
            position: Robot position after the step, metres.
            velocity: Robot velocity after the step, m/s.
            scan: LiDAR ranges after the step, metres.
            contact: A MuJoCo contact between the robot and the world happened.

        Returns:
            (observation, reward, weighted reward terms).
        """
        self.steps += 1
        self.counters["steps"] += 1
        pending, prev = self._pending, self._prev
        (px, py), (gx, gy) = position.tolist(), self._goal
        distance = math.hypot(gx - px, gy - py)
        self.min_scan = min_scan = max(float(scan.min()) - self._inflation, 0.0)
        collision = contact if self.config.collision == "contact" else min_scan <= 0.0
        success = distance < self.config.reward.goal_tolerance and not collision
        self.outcome = self._outcome(success, collision)
        inputs = reward_lib.RewardInputs(
            success=success, collision=collision, min_scan=min_scan, distance=distance,
            prev_distance=prev["distance"], plan_ok=pending["plan_ok"], prev_plan_ok=prev["plan_ok"],
            q_s=pending["q_s"], q_l=pending["q_l"], q1=pending["q1"], qn=pending["qn"],
            prev_q_s=prev["q_s"], prev_q_l=prev["q_l"], velocity=velocity, prev_velocity=prev["velocity"],
            control_period=self.config.timing.control_period,
        )
        t0 = time.perf_counter()
        reward, terms = reward_lib.total(inputs, self.config.reward, self._reward_terms)
        self.timers["reward"] += time.perf_counter() - t0
        self._plan = pending["plan"]
        self._prev = {"q_s": pending["q_s"], "q_l": pending["q_l"], "plan_ok": pending["plan_ok"],
                      "distance": distance, "velocity": velocity.copy()}
        self._update_tracks(scan, position)
        t0 = time.perf_counter()
        self.region = self._region(scan)
        self.timers["region"] += time.perf_counter() - t0
        t0 = time.perf_counter()
        polygon, state = self._frame(position, velocity)
        obs = self._stack.push(polygon, state)
        if self._aligned is not None:
            self._aligned.push(self.region.boundary_xy, position)
            obs = self._align(obs, position)
        obs = self._with_tracks(obs, position)
        self.timers["observation"] += time.perf_counter() - t0
        return obs, reward, terms

    def _outcome(self, success: bool, collision: bool) -> Outcome:
        if collision:
            return Outcome.COLLISION
        if success:
            return Outcome.SUCCESS
        if self.steps >= self.config.timing.episode_steps:
            return Outcome.TIMEOUT
        return Outcome.RUNNING

    @property
    def observation_size(self) -> int:
        """Length of the stacked observation."""
        return obs_lib.observation_size(self.config.observation.frames, self.config.region.num_points,
                                        self.design.state_size, self.config.observation.tracks)
