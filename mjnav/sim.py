"""``NavSim``: the MuJoCo world of one task, compiled once and re-populated every episode.

NavSim owns the entities (arena with obstacle slots, robot, pedestrian slots), the pedestrian
motion model and the LiDAR backends, and moves numbers between them and a ``physics``
(``dm_control.mjcf.Physics``, or the composer physics of a Task whose ``root_entity`` is
:attr:`NavSim.root_entity`). Nothing is recompiled after the first build: a new episode writes
poses, mesh ids and radii into the compiled model and data.

Per control period (``timing.control_period``, ``timing.substeps`` physics steps):

1. :meth:`apply_command` sets the robot's triple-integrator reference from its state and jerk
   and moves the crowd through the period, one step per physics substep (a crowd that ignores
   the robot is computed :data:`CROWD_LOOKAHEAD` periods at a time);
2. before every physics step, :meth:`before_substep` places the pedestrians of that substep
   (mocap positions, so their motion is smooth) and writes the tracking force;
   :meth:`run_period` does this and the ``mj_step`` calls for the whole period, by default in one
   compiled call (:mod:`mjnav.fused`, bit-identical);
3. after the period, :meth:`scan` (once) and :meth:`robot_in_collision` read the world.

:meth:`control_step` runs 1-3 without composer. Randomness: the generator given to
:meth:`initialize_episode` draws the layout and then seeds the crowd's own stream (so the crowd
does not depend on how many noisy scans are taken); noise uses the generator given to
:meth:`scan`. The same seed gives bit-identical worlds, trajectories and scans.
"""

from __future__ import annotations

from typing import TYPE_CHECKING

import mujoco
import numpy as np
from dm_control import mjcf

from mjnav.entities import make_robot
from mjnav.entities.arena import NavArena
from mjnav.entities.crowd import Crowd
from mjnav.entities.robot import integrator_value
from mjnav.fused import FusedStepper, callbacks_installed
from mjnav.geometry.raycast import add_noise, polygon_segments, wall_segments
from mjnav.sensors import make_lidars
from mjnav.world import make_pedestrian_model
from mjnav.world.layout import Layout, sample_layout
from mjnav.world.shapes import make_shape_bank

if TYPE_CHECKING:
    from mjnav.config import TaskConfig

__all__ = ["COLLISION_KINDS", "NavSim"]

#: Kinds reported by :meth:`NavSim.robot_in_collision` (index = code in the geom lookup table).
COLLISION_KINDS = (None, "wall", "obstacle", "pedestrian")

#: Control periods of crowd motion computed in one call when the pedestrian model ignores the
#: robot (the same steps, fewer calls); a model that reacts to the robot advances period by period.
CROWD_LOOKAHEAD = 10


class NavSim:
    """Arena + robot + crowd of one :class:`~mjnav.config.TaskConfig`, built once."""

    def __init__(self, config: TaskConfig, integrator: str | None = None, lidar_method: str = "multiray",
                 rangefinders: bool = True, contact_pairs: bool = True, fused: bool = True) -> None:
        """Builds the entities (not compiled yet).

        Args:
            config: A ``TaskConfig`` (uses arena, obstacles, crowd, robot, lidar, timing, layout and
                ``region.inflation``).
            integrator: MuJoCo integrator, default ``config.timing.integrator``; the robot's
                tracking plan is exact for each (see :mod:`mjnav.entities.robot`).
            lidar_method: Evaluation method of the ``mujoco`` LiDAR backend (``multiray``, or
                ``sensor``, which needs the rangefinders).
            rangefinders: Compile the robot's 360 rangefinder sites and sensors (spec §2). False
                saves ~40% of each bare mj_step; the ``mujoco`` backend then casts with mj_multiRay.
            contact_pairs: List the robot's contacts with the walls, obstacle slots and pedestrians
                as explicit ``<pair>`` elements (default parameters, which equal the mix of the
                geoms' defaults) and take those geoms out of MuJoCo's dynamic collision search
                (conaffinity 0): the same contacts, with no broadphase, about a quarter of each
                mj_step. False: contype/conaffinity filtering (robot contype 1, scene conaffinity 1).
            fused: Run a period's substeps in one compiled call (:meth:`run_period`, same results).
                It turns itself off, with the reason in ``fused_unavailable``, where MuJoCo's
                library or struct layout does not check out (:mod:`mjnav.fused`).
        """
        _check_heights(config)
        self.config = config
        self.bank = make_shape_bank(config.obstacles)
        self.arena = NavArena(config.arena, config.obstacles, self.bank)
        if lidar_method == "sensor" and not rangefinders:
            raise ValueError("lidar_method='sensor' needs the rangefinders")
        self.robot = make_robot(config.robot, config.lidar, rangefinders=rangefinders)
        self.arena.attach(self.robot)
        self.crowd = Crowd(config.crowd)
        self.crowd.attach_to(self.arena)
        if contact_pairs:
            self._pair_contacts()
        option = self.arena.mjcf_model.option
        option.timestep = config.timing.physics_timestep
        integrator = config.timing.integrator if integrator is None else integrator
        integrator_value(integrator)  # validates the name
        option.integrator = integrator
        option.noslip_iterations = 0
        self.integrator = integrator
        self.pedestrians = make_pedestrian_model(config.crowd)
        self.lidars = make_lidars(config.lidar, self.robot, lidar_method)
        self.lidar = self.lidars[config.lidar.backend]
        self._dt = config.timing.physics_timestep
        self._model = None
        self._segments = wall_segments(config.arena.size)
        self._circles = np.zeros((0, 3))  # [x, y, r] rows for the LiDAR, refilled at every scan
        self._num_peds = 0
        self._substep = 0
        self._sticky = 0
        self._crowd_track = np.zeros((0, 0, 2))  # this period's pedestrian positions, one row a substep
        self._ahead, self._ahead_at = np.zeros((0, 0, 2)), 0  # crowd steps computed ahead, next row to use
        self._crowd_now = np.zeros((0, 2))  # the pedestrians' positions now (the last row used)
        self._crowd_before: np.ndarray | None = None  # their positions one substep earlier
        self._ped_xy, self._ped_xy_data = np.zeros((0, 2)), None  # mocap x, y view and its MjData
        self._state_views: tuple = (None, None, None)  # (MjData, qpos view, qvel view) of the robot
        self.fused = fused
        self.fused_unavailable: str | None = None  # why fused substeps turned themselves off
        self._fused: FusedStepper | None = None
        self._ped_rows = np.zeros(0, dtype=np.int64)  # mocap rows of the active pedestrians
        self.layout: Layout | None = None

    # ------------------------------------------------------------------ building
    @property
    def root_entity(self) -> NavArena:
        """The arena (robot and crowd attached): the composer root entity."""
        return self.arena

    @property
    def mjcf_model(self) -> mjcf.RootElement:
        """The whole scene's MJCF."""
        return self.arena.mjcf_model

    @property
    def scene_geoms(self) -> list[mjcf.Element]:
        """The geoms the robot can collide with: walls, obstacle slots, pedestrian slots."""
        return [*self.arena.walls, *self.arena.obstacle_slots, *self.crowd.geoms]

    def _pair_contacts(self) -> None:
        contact = self.arena.mjcf_model.contact
        for geom in self.scene_geoms:
            geom.conaffinity = 0
            contact.add("pair", geom1=self.robot.geom, geom2=geom)

    def make_physics(self) -> mjcf.Physics:
        """Compiles the scene (once per environment)."""
        return mjcf.Physics.from_mjcf_model(self.arena.mjcf_model)

    def _bind(self, physics: mjcf.Physics) -> None:
        """Caches ids and index arrays for ``physics`` (once per compiled model)."""
        model = physics.model.ptr
        if self._model is model:
            return
        model.opt.disableflags |= int(mujoco.mjtDisableBit.mjDSBL_SENSOR)  # scans run on demand
        self._qpos = _as_index(physics.bind(self.robot.joints).qposadr)
        self._qvel = _as_index(physics.bind(self.robot.joints).dofadr)
        self._robot_geom = self.robot.geom_id(physics)
        kind = np.zeros(model.ngeom, dtype=np.int64)
        kind[physics.bind(self.arena.walls).element_id] = 1
        if self.arena.obstacle_slots:
            kind[physics.bind(self.arena.obstacle_slots).element_id] = 2
        kind[self.crowd.geom_ids(physics)] = 3
        self._geom_kind = kind
        self._mocap = self.crowd.mocap_ids(physics)
        self._model = model

    # ------------------------------------------------------------------ episode
    def initialize_episode(self, physics: mjcf.Physics, rng: np.random.Generator) -> Layout:
        """Samples a layout and places everything by binding (no recompiling).

        Args:
            physics: The compiled physics (its data is reset here).
            rng: Episode generator: draws the layout, then seeds the crowd's stream.

        Returns:
            The episode's :class:`~mjnav.world.layout.Layout`.
        """
        self._bind(physics)
        cfg = self.config
        model, data = physics.model.ptr, physics.data.ptr
        mujoco.mj_resetData(model, data)
        layout = sample_layout(
            cfg.arena, cfg.obstacles, cfg.crowd, cfg.layout, cfg.lidar, self.bank, rng,
            inflation=cfg.region.inflation, robot_radius=cfg.robot.radius,
        )
        crowd_rng = np.random.default_rng(rng.integers(0, 2**63))
        self.arena.set_obstacles(physics, layout.obstacle_shapes, layout.obstacle_poses)
        self.crowd.set_radii(physics, layout.ped_radii)
        self._num_peds = len(layout.ped_radii)
        self._circles = np.zeros((self._num_peds, 3))
        self._circles[:, 2] = layout.ped_radii
        if self._num_peds:
            hx, hy = 0.5 * cfg.arena.size[0], 0.5 * cfg.arena.size[1]
            self.pedestrians.reset(
                layout.ped_positions, layout.ped_radii, layout.ped_speeds, layout.ped_headings,
                bounds=(-hx, -hy, hx, hy), obstacles=list(layout.obstacle_polygons), rng=crowd_rng,
            )
            self._ped_index = _as_index(self._mocap[: self._num_peds])
            data.mocap_pos[self._ped_index, :2] = self.pedestrians.positions
            consecutive = isinstance(self._ped_index, slice)  # then keep a view for the substeps
            self._ped_xy = data.mocap_pos[self._ped_index, :2] if consecutive else np.zeros((0, 2))
            self._ped_xy_data = data if consecutive else None
        self._ped_rows = np.asarray(self._mocap[: self._num_peds], dtype=np.int64)
        self.robot.set_state(physics, layout.start)
        self.robot.reset_reference(layout.start)
        data.ctrl[:] = 0.0
        mujoco.mj_forward(model, data)
        polygons = self.arena.obstacle_polygons(physics, cfg.lidar.height)
        self._segments = np.vstack([wall_segments(cfg.arena.size), polygon_segments(polygons)])
        self._substep, self._sticky = 0, 0
        self._crowd_track = np.zeros((0, self._num_peds, 2))
        self._ahead, self._ahead_at = np.zeros((0, self._num_peds, 2)), 0
        self._crowd_now = self.pedestrians.positions if self._num_peds else np.zeros((0, 2))
        self._crowd_before = None  # positions one substep before _crowd_now (None: none moved yet)
        self.layout = layout
        return layout

    # ------------------------------------------------------------------ stepping
    def apply_command(self, physics: mjcf.Physics, jerk: np.ndarray,
                      state: tuple[np.ndarray, np.ndarray, np.ndarray] | None = None) -> None:
        """Starts a control period: reference from the robot state under ``jerk`` (2,), m/s³.

        Also moves the crowd through the whole period in one call (pedestrians that react to
        the robot see its planned position at each substep, which is its free-space position).

        Args:
            physics: The physics.
            jerk: (2,) jerk for the period, m/s³.
            state: :meth:`robot_state` of this moment if the caller already has it (read otherwise).
        """
        p, v, a = self.robot_state(physics) if state is None else state
        substeps = self.config.timing.substeps
        self.robot.set_reference(p, v, a, jerk, substeps=substeps)
        self._substep, self._sticky = 0, 0
        if self._num_peds:
            reacts = self.pedestrians.reacts_to_robot
            robot = [row[4:6] for row in self.robot.plan(physics)] if reacts else None
            self._crowd_track = self._advance_crowd(substeps, robot)

    def before_substep(self, physics: mjcf.Physics) -> None:
        """Places the pedestrians for the coming physics step, then writes the tracking force."""
        data = physics.data.ptr
        k = self._substep
        if k:
            self._note_contacts(data)
        if self._num_peds:
            if k >= len(self._crowd_track):  # more substeps than a period: one more crowd step
                self._crowd_track = self._advance_crowd(1, [data.qpos[self._qpos].copy()])
                self._substep = k = 0
            if self._ped_xy_data is data:
                self._ped_xy[...] = self._crowd_track[k]
            else:
                data.mocap_pos[self._ped_index, :2] = self._crowd_track[k]
        self.robot.apply_tracking_force(physics)
        self._substep += 1

    def _advance_crowd(self, steps: int, robot_positions: list[np.ndarray] | None) -> np.ndarray:
        """The crowd's next ``steps`` physics steps, ``(steps, P, 2)`` positions; they become current.

        A model that ignores the robot is advanced :data:`CROWD_LOOKAHEAD` periods at a time and
        its rows are handed out in order (its own state then runs ahead of the simulation).
        ``robot_positions`` (the robot centre at the start of each step) may be None for it.
        """
        peds = self.pedestrians
        if peds.reacts_to_robot:
            track = peds.advance(self._dt, steps, robot_positions=robot_positions,
                                 robot_radius=self.config.robot.radius)
        else:
            ahead, i = self._ahead, self._ahead_at
            if i + steps > len(ahead):
                block = peds.advance(self._dt, max(steps, CROWD_LOOKAHEAD * self.config.timing.substeps))
                ahead = self._ahead = block if i == len(ahead) else np.concatenate([ahead[i:], block])
                i = 0
            self._ahead_at = i + steps
            track = ahead[i : i + steps]
        self._crowd_before = track[-2] if len(track) > 1 else self._crowd_now
        self._crowd_now = track[-1]
        return track

    def run_period(self, physics: mjcf.Physics) -> None:
        """The period's physics steps after :meth:`apply_command`: each :meth:`before_substep`, then ``mj_step``.

        With ``fused`` (and :func:`mjnav.fused.fused_support`) all of them run in one compiled
        call with bit-identical results; otherwise, when some substeps already ran, when no
        :meth:`apply_command` started the period, or while a MuJoCo callback is installed
        (:func:`mjnav.fused.callbacks_installed`), in Python.
        """
        substeps = self.config.timing.substeps
        stepper = None if self._substep or callbacks_installed() else self._stepper(physics)
        robot = self.robot
        plan = robot.plan_rows(physics) if stepper is not None else None
        track = self._crowd_track if self._num_peds else np.zeros((substeps, 0, 2))
        rows = self._ped_rows
        if stepper is None or len(plan) != substeps or len(track) < substeps or track.shape[1] != len(rows):
            model, data = physics.model.ptr, physics.data.ptr
            for _ in range(substeps - self._substep):
                self.before_substep(physics)
                mujoco.mj_step(model, data)
            return
        index, gains = robot.tracking_arrays(physics)
        k = resumed = 0
        while k < substeps:
            k = stepper.run(k, not (resumed or self._sticky), plan, track, rows, index, gains)
            if k < substeps:  # the previous step found contacts: note them as before_substep does
                self._note_contacts(stepper.data)
                resumed = not self._sticky
        robot.advance_substeps(substeps)
        self._substep = substeps

    def _stepper(self, physics: mjcf.Physics) -> FusedStepper | None:
        """The fused stepper of this physics, if it can run the whole period."""
        if not self.fused or self.robot.substeps_tracked:
            return None
        data = physics.data.ptr
        stepper = self._fused
        if stepper is None or stepper.data is not data:
            try:
                stepper = self._fused = FusedStepper(physics.model.ptr, data)
            except RuntimeError as exc:
                self.fused, self.fused_unavailable = False, str(exc)
                return None
        return stepper

    def control_step(self, physics: mjcf.Physics, jerk: np.ndarray) -> None:
        """One control period without composer: :meth:`apply_command`, :meth:`run_period`, :meth:`sync`.

        The sync (``mj_step1``, as composer's legacy stepping) makes contacts and kinematics
        describe the final state for :meth:`scan` and :meth:`robot_in_collision`.

        Args:
            physics: The physics.
            jerk: (2,) jerk for the period, m/s³.
        """
        self.apply_command(physics, jerk)
        self.run_period(physics)
        self.sync(physics)

    def sync(self, physics: mjcf.Physics) -> None:
        """Recomputes position/velocity quantities (kinematics, contacts) for the current state.

        Composer's default ``legacy_step=True`` already does this after every substep; with
        ``legacy_step=False`` (cheaper) call it once per control period, before :meth:`scan` and
        :meth:`robot_in_collision`. It never changes the state.

        ``mj_step`` finds contacts before it integrates, so the contacts on hand here belong to
        the last substep's start; they are noted for :meth:`robot_in_collision` first (a contact
        the constraint solver resolved within that substep still counts).
        """
        data = physics.data.ptr
        self._note_contacts(data)
        mujoco.mj_step1(physics.model.ptr, data)

    def _note_contacts(self, data: mujoco.MjData) -> None:
        """Keeps the kind of a robot contact among the current contacts, unless one is kept already."""
        if data.ncon and not self._sticky:
            self._sticky = self._contact_kind(data)

    # ------------------------------------------------------------------ reading
    def robot_state(self, physics: mjcf.Physics) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """(p, v, a), each (2,): MuJoCo position and velocity, reference acceleration (MPC state)."""
        data = physics.data.ptr
        views = self._state_views
        if views[0] is not data:  # a slice of an MjData array is a view that never moves
            if not (isinstance(self._qpos, slice) and isinstance(self._qvel, slice)):
                return data.qpos[self._qpos].copy(), data.qvel[self._qvel].copy(), self.robot.acceleration
            views = self._state_views = (data, data.qpos[self._qpos], data.qvel[self._qvel])
        return views[1].copy(), views[2].copy(), self.robot.acceleration

    def pedestrian_circles(self) -> np.ndarray:
        """(P, 3) ``[x, y, r]`` of the active pedestrians, metres."""
        return self._current_circles().copy()

    def pedestrian_velocities(self) -> np.ndarray:
        """(P, 2) velocities of the active pedestrians over the last physics substep, m/s (the crowd
        model's own before the first step)."""
        if self._crowd_before is None:
            return self.pedestrians.velocities if self._num_peds else np.zeros((0, 2))
        return (self._crowd_now - self._crowd_before) / self._dt

    def pedestrian_goals(self) -> np.ndarray:
        """(P, 2) the active pedestrians' goals as the crowd model holds them, metres (NaN rows for a
        model without goals; a model that ignores the robot runs up to CROWD_LOOKAHEAD periods ahead)."""
        goals = getattr(self.pedestrians, "goals", None) if self._num_peds else np.zeros((0, 2))
        return np.full((self._num_peds, 2), np.nan) if goals is None else np.array(goals, dtype=np.float64)

    def _current_circles(self) -> np.ndarray:
        """The reused ``(P, 3)`` circles buffer, refreshed with the current positions."""
        if self._num_peds:
            self._circles[:, :2] = self._crowd_now
        return self._circles

    @property
    def segments(self) -> np.ndarray:
        """(S, 4) wall faces and placed obstacle edges (as compiled) at LiDAR height, metres."""
        return self._segments

    def scan(self, physics: mjcf.Physics, rng: np.random.Generator | None = None, noise: bool = True,
             backend: str | None = None) -> np.ndarray:
        """The LiDAR scan from the robot centre (spec §2).

        Args:
            physics: The physics (synchronised after stepping, as composer and :meth:`control_step` do).
            rng: Noise generator (required when ``noise``).
            noise: Add N(0, noise_std²) per beam, clipped to [0, max_range].
            backend: ``analytic`` or ``mujoco``; default ``config.lidar.backend``.

        Returns:
            (B,) float64 ranges, metres.
        """
        lidar = self.lidar if backend is None else self.lidars[backend]
        origin = physics.data.ptr.qpos[self._qpos]
        circles = self._current_circles() if lidar.name == "analytic" else None
        ranges = lidar.scan(physics, origin, self._segments, circles)
        if not noise:
            return ranges
        if rng is None:
            raise ValueError("scan(noise=True) needs a generator")
        cfg = self.config.lidar
        return add_noise(ranges, cfg.noise_std, cfg.max_range, rng)

    def robot_in_collision(self, physics: mjcf.Physics) -> tuple[bool, str | None]:
        """Whether the robot touched a wall, obstacle or pedestrian during the last period.

        Uses MuJoCo contacts (only robot pairs can collide): those found by each physics step
        of the period (at the step's start state) and in the final state.

        Returns:
            ``(collided, kind)`` with kind ``wall``, ``obstacle``, ``pedestrian`` or None.
        """
        data = physics.data.ptr
        code = self._sticky or (self._contact_kind(data) if data.ncon else 0)
        return bool(code), COLLISION_KINDS[code]

    def _contact_kind(self, data: mujoco.MjData) -> int:
        """Kind code of the deepest current robot contact (0 if none)."""
        n = data.ncon
        if not n:
            return 0
        contacts = data.contact
        pairs = contacts.geom[:n]
        kinds = self._geom_kind[pairs].max(axis=1)
        hits = (pairs == self._robot_geom).any(axis=1) & (kinds > 0)
        if not hits.any():
            return 0
        dist = np.where(hits, contacts.dist[:n], np.inf)
        return int(kinds[int(np.argmin(dist))])


def _as_index(ids: np.ndarray) -> slice | np.ndarray:
    """A slice when the ids are consecutive (faster numpy access), else an int array."""
    ids = np.asarray(ids, dtype=np.int64).reshape(-1)
    if ids.size and np.array_equal(ids, np.arange(ids[0], ids[0] + ids.size)):
        return slice(int(ids[0]), int(ids[0]) + ids.size)
    return ids


def _check_heights(config: TaskConfig) -> None:
    """LiDAR rays must hit walls, obstacles and pedestrians; the robot must clear the floor."""
    h = config.lidar.height
    limits = {"arena.wall_height": config.arena.wall_height}
    if config.obstacles.num_slots:
        limits["obstacles.height"] = config.obstacles.height
    if config.crowd.num_slots:
        limits["crowd.height"] = config.crowd.height
    for name, top in limits.items():
        if not 0.0 < h < top:
            raise ValueError(f"lidar.height {h} m must lie strictly between the floor and {name} ({top} m)")
    if config.robot.height / 2 >= h:
        raise ValueError(f"robot.height/2 ({config.robot.height / 2} m) must be below lidar.height ({h} m)")
