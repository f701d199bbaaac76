"""``OmniRobot``: the omni-directional disc robot, its LiDAR sites and tracking controller (spec §1-2).

The robot is one body at LiDAR height with two slide joints (world x and y: no rotation, no
vertical motion, never touching the floor, so no friction), a cylinder geom, two force motors
and one rangefinder per beam (``ray_000`` ... on sites whose +z axis is the beam direction;
MuJoCo excludes the robot's own body from the rays). ``qpos`` is the world (x, y) position.

Tracking. At the start of each control period the caller sets the reference (p, v, a, jerk) and
the number of physics substeps n in the period. The robot then plans one constant acceleration
u_k per substep: the reference's mean acceleration over the substep, ``a + j·(t_k + dt/2)``, plus
the smallest correction that makes the *discrete* trajectory of the model's integrator end
exactly on the triple integrator's (p, v) after n substeps (one constant-force step is
``v⁺ = v + dt·u`` and ``p⁺ = p + dt·v + c·dt²·u`` with c = 1/2 for RK4, 1 for semi-implicit
Euler and the implicit integrators). Before every substep :meth:`OmniRobot.apply_tracking_force`
applies, per axis,

    F = m·u_k + m·kv·(v_k − v) + m·kp·(p_k − p),

with (p_k, v_k) the planned state at the substep start. In free space the feedback terms are zero
and the state after one period equals the triple integrator to rounding (1e-12 m) with any of
these integrators, so the default is the cheapest, Euler (a quarter of RK4's cost per step).
Within the period an Euler plan back-loads the acceleration (a ramp of up to
±5.5·(|a|·T + |j|·T²/2) m/s² around the reference, T the period), so mid-period states differ from the
continuous reference by < 1 mm and < 7 cm/s; RK4's plan is the reference to ~j·dt³. In contact
the feedback pushes back physically and the next period re-plans from the measured state. See
``tests/entities/test_robot.py``.

The controller method is deliberately not named ``before_substep``: that is a composer
``Entity`` hook (``physics, random_state``) which composer calls by itself; NavSim calls
:meth:`OmniRobot.apply_tracking_force` from the task's ``before_substep`` instead.

MuJoCo has no acceleration state: :attr:`OmniRobot.acceleration` (the reference acceleration
``a + j·t``) is the robot's acceleration for the MPC.
"""

from __future__ import annotations

import functools
import re

import mujoco
import numpy as np
from dm_control import composer, mjcf

from mjnav.control.dynamics import clamp, integrate, tracking_force, transition_matrices
from mjnav.geometry.raycast import beam_angles
from mjnav.resources import asset
from mjnav.schema import LidarConfig, RobotConfig

__all__ = ["ROBOT_CONTYPE", "OmniRobot", "integrator_value", "plan_substeps"]

#: The robot is the only geom with a contype bit; scene geoms have conaffinity 1.
ROBOT_CONTYPE = 1
#: Beams of the rangefinders in ``assets/robot.xml`` (other counts are built here).
_ASSET_BEAMS = 360
_RAY_LINE = re.compile(r'^ *<(?:site|rangefinder) name="ray_\d+"[^>]*/>\n', re.MULTILINE)


class OmniRobot(composer.Entity):
    """Disc robot with x/y slide joints, force motors, rangefinders and a tracking controller."""

    def _build(self, config: RobotConfig, lidar: LidarConfig, rangefinders: bool = True,
               name: str = "robot") -> None:
        """Builds the MJCF.

        Args:
            config: Radius, mass, height, limits and tracking gains (SI units).
            lidar: Beam count and height of the rangefinders.
            rangefinders: Add the per-beam sites and rangefinder sensors (spec §2). Their site
                poses cost MuJoCo ~4 us per kinematics pass (1 per Euler step, 4 per RK4 step); without them the
                ``mujoco`` LiDAR backend still works through ``mj_multiRay``.
            name: MJCF model name (the namespace of its elements).
        """
        self._config = config
        self._gains = (config.mass, config.kv, config.kp, config.force_max)  # read every substep
        self._lidar = lidar
        asset_rays = rangefinders and lidar.beams == _ASSET_BEAMS
        self._mjcf_root = _load_mjcf(config, lidar, name, asset_rays)
        self._body = self._mjcf_root.find("body", "base")
        self._joints = [self._mjcf_root.find("joint", axis) for axis in ("x", "y")]
        self._geom = self._mjcf_root.find("geom", "disc")
        self._actuators = [self._mjcf_root.find("actuator", f"force_{axis}") for axis in ("x", "y")]
        self._sites, self._sensors = (
            (self._body.find_all("site"), list(self._mjcf_root.sensor.rangefinder)) if asset_rays
            else _add_rangefinders(self._mjcf_root, self._body, lidar) if rangefinders else ([], []))
        self._camera = self._mjcf_root.find("camera", "follow")
        self._cache_model = None
        self._views: tuple = (None,)  # (MjData, qpos, qvel, ctrl) of the data last tracked
        self._x = np.zeros((4, 2))  # reference rows p, v, a, jerk; _p, _v, _a, _j are views of them
        self._p, self._v, self._a, self._j = self._x
        self._plan_out: np.ndarray | None = None  # (3n, 2) plan rows, reused every period
        self.reset_reference(np.zeros(2))

    # ------------------------------------------------------------------ properties
    @property
    def mjcf_model(self) -> mjcf.RootElement:
        """The robot's MJCF root."""
        return self._mjcf_root

    @property
    def config(self) -> RobotConfig:
        """The robot config."""
        return self._config

    @property
    def body(self) -> mjcf.Element:
        """The robot body."""
        return self._body

    @property
    def geom(self) -> mjcf.Element:
        """The collision disc."""
        return self._geom

    @property
    def joints(self) -> list[mjcf.Element]:
        """The x and y slide joints."""
        return list(self._joints)

    @property
    def actuators(self) -> list[mjcf.Element]:
        """The x and y force motors."""
        return list(self._actuators)

    @property
    def ray_sites(self) -> list[mjcf.Element]:
        """One site per beam; its +z axis is the beam direction."""
        return list(self._sites)

    @property
    def rangefinders(self) -> list[mjcf.Element]:
        """One rangefinder sensor per beam (``ray_000`` ...)."""
        return list(self._sensors)

    @property
    def camera(self) -> mjcf.Element:
        """A camera following the robot from behind and above."""
        return self._camera

    @property
    def acceleration(self) -> np.ndarray:
        """(2,) reference acceleration at the current time within the period, m/s² (the MPC's a)."""
        ax, ay, jx, jy = self._aj
        t = self._t
        return np.array((ax + jx * t, ay + jy * t))  # floats: the same IEEE operations as a + j·t, cheaper

    # ------------------------------------------------------------------ runtime
    def _bind(self, physics: mjcf.Physics) -> None:
        """Caches qpos/qvel/ctrl addresses for this physics (cheap per-substep access)."""
        model = physics.model.ptr
        if self._cache_model is model:
            return
        self._qpos_adr = np.asarray(physics.bind(self._joints).qposadr, dtype=np.int64)
        self._dof_adr = np.asarray(physics.bind(self._joints).dofadr, dtype=np.int64)
        self._ctrl_adr = np.asarray(physics.bind(self._actuators).element_id, dtype=np.int64)
        self._body_id = int(physics.bind(self._body).element_id)
        self._geom_id = int(physics.bind(self._geom).element_id)
        self._dt = float(model.opt.timestep)
        self._opt = model.opt  # a live view of the model's options
        self._qpos_list = [int(i) for i in self._qpos_adr]
        self._dof_list = [int(i) for i in self._dof_adr]
        self._ctrl_list = [int(i) for i in self._ctrl_adr]
        self._tracking_index = np.array([*self._dof_list, *self._qpos_list, *self._ctrl_list], dtype=np.int64)
        self._tracking_gains = np.array(self._gains, dtype=np.float64)
        self._cache_model = model

    def body_id(self, physics: mjcf.Physics) -> int:
        """The robot body id in ``physics``."""
        self._bind(physics)
        return self._body_id

    def geom_id(self, physics: mjcf.Physics) -> int:
        """The collision disc's geom id in ``physics``."""
        self._bind(physics)
        return self._geom_id

    def set_state(
        self, physics: mjcf.Physics, position: np.ndarray, velocity: np.ndarray | None = None
    ) -> None:
        """Teleports the robot (world x, y in metres; velocity m/s, default 0)."""
        self._bind(physics)
        data = physics.data.ptr
        data.qpos[self._qpos_adr] = position
        data.qvel[self._dof_adr] = 0.0 if velocity is None else velocity

    def get_state(self, physics: mjcf.Physics) -> tuple[np.ndarray, np.ndarray]:
        """(position (2,), velocity (2,)) copies, metres and m/s."""
        self._bind(physics)
        data = physics.data.ptr
        return data.qpos[self._qpos_adr], data.qvel[self._dof_adr]

    def reset_reference(self, position: np.ndarray) -> None:
        """Holds still at ``position``: zero velocity, acceleration and jerk."""
        self.set_reference(position, np.zeros(2), np.zeros(2), np.zeros(2), substeps=1)

    def set_reference(self, p: np.ndarray, v: np.ndarray, a: np.ndarray, jerk: np.ndarray, *,
                      substeps: int) -> None:
        """Starts a control period: the triple-integrator reference from (p, v, a) under ``jerk``.

        Args:
            p: (2,) position at the period start, metres.
            v: (2,) velocity, m/s.
            a: (2,) acceleration, m/s².
            jerk: (2,) jerk held over the period, m/s³.
            substeps: Physics steps in the period (the plan ends exactly after this many).
        """
        if substeps < 1:
            raise ValueError(f"substeps must be >= 1, got {substeps}")
        x = self._x  # rows written in place: no new arrays per period
        x[0], x[1], x[2], x[3] = p, v, a, jerk
        (ax, ay), (jx, jy) = x[2:].tolist()
        self._aj = (ax, ay, jx, jy)
        self._substeps = int(substeps)
        self._plan: list[list[float]] | None = None  # made at the first substep (needs dt)
        self._k = 0
        self._t = 0.0

    def reference(self, t: float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Reference (p, v, a) at time ``t`` into the period (:func:`mjnav.control.dynamics.integrate`)."""
        return integrate(self._p, self._v, self._a, self._j, float(t))

    def plan(self, physics: mjcf.Physics) -> list[list[float]]:
        """The period's plan, made on first use: per substep ``[ux, uy, vx, vy, px, py]``.

        u is the planned acceleration (m/s²), (v, p) the planned state at the substep start.
        """
        if self._plan is None:
            self._plan = self.plan_rows(physics).tolist()
        return self._plan

    def plan_rows(self, physics: mjcf.Physics) -> np.ndarray:
        """:meth:`plan` as an (n, 6) array (reused: valid until the next :meth:`set_reference`)."""
        self._bind(physics)
        c = _STEP_POSITION_GAIN.get(int(self._opt.integrator), 1.0)  # read live: it may change
        n = self._substeps
        out = self._plan_out
        if out is None or out.shape[0] != 3 * n:
            out = self._plan_out = np.empty((3 * n, 2))
        np.matmul(_plan_matrix(n, self._dt, c), self._x, out=out)  # = plan_substeps(p, v, a, j, ...)
        return out.reshape(n, 6)

    @property
    def substeps_tracked(self) -> int:
        """Physics steps of the current period that :meth:`apply_tracking_force` has driven."""
        return self._k

    def tracking_arrays(self, physics: mjcf.Physics) -> tuple[np.ndarray, np.ndarray]:
        """What :meth:`apply_tracking_force` computes with, for a compiled loop over substeps.

        Returns:
            ``index``: (6,) int64 ``[dof x, dof y, qpos x, qpos y, ctrl x, ctrl y]``;
            ``gains``: (4,) ``[mass (kg), kv (1/s), kp (1/s²), force limit (N)]``.
        """
        self._bind(physics)
        return self._tracking_index, self._tracking_gains

    def advance_substeps(self, count: int) -> None:
        """Advances the period clock by ``count`` substeps that were tracked elsewhere (same plan)."""
        self._k = k = self._k + count
        self._t = k * self._dt

    def apply_tracking_force(self, physics: mjcf.Physics) -> None:
        """Writes the tracking force for the coming physics step and advances the period clock.

        Substeps beyond the planned ``substeps`` follow the continuous reference (mean
        acceleration of the step plus feedback), so an over-long period still tracks it.
        """
        plan = self._plan if self._plan is not None else self.plan(physics)
        k, dt = self._k, self._dt
        if k < len(plan):
            ux, uy, vx, vy, px, py = plan[k]
        else:
            t = k * dt
            p, v, _ = self.reference(t)
            ux, uy = (self._a + self._j * (t + dt / 2)).tolist()
            vx, vy, px, py = float(v[0]), float(v[1]), float(p[0]), float(p[1])
        data = physics.data.ptr
        views = self._views
        if views[0] is not data:  # the arrays of one MjData never move: look them up once
            views = self._views = (data, data.qpos, data.qvel, data.ctrl)
        _, qpos, qvel, ctrl = views
        m, kv, kp, fmax = self._gains
        d0, d1 = self._dof_list
        q0, q1 = self._qpos_list  # Python floats: cheaper than numpy scalars, same IEEE results
        fx = tracking_force(ux, vx, qvel.item(d0), px, qpos.item(q0), kv, kp)
        fy = tracking_force(uy, vy, qvel.item(d1), py, qpos.item(q1), kv, kp)
        c0, c1 = self._ctrl_list
        ctrl[c0] = clamp(m * fx, fmax)
        ctrl[c1] = clamp(m * fy, fmax)
        self._k = k = k + 1
        self._t = k * dt


#: c in p⁺ = p + dt·v + c·dt²·u for one step of constant acceleration u, per MuJoCo integrator
#: (no damping: the implicit integrators reduce to semi-implicit Euler).
_STEP_POSITION_GAIN = {int(mujoco.mjtIntegrator.mjINT_RK4): 0.5, int(mujoco.mjtIntegrator.mjINT_EULER): 1.0,
                       int(mujoco.mjtIntegrator.mjINT_IMPLICIT): 1.0,
                       int(mujoco.mjtIntegrator.mjINT_IMPLICITFAST): 1.0}


@functools.lru_cache(maxsize=32)
def _plan_matrix(n: int, dt: float, c: float) -> np.ndarray:
    """(3n, 4) map from one axis' ``[p, v, a, jerk]`` to its plan rows ``[u_k, v_k, p_k]``, k < n.

    The plan is linear in the reference: u = a + j·(t_k + dt/2) (mean reference accelerations)
    plus the min-norm correction that makes ``v_n - v_0 = dt·Σ u_i`` and
    ``p_n - p_0 - n·dt·v_0 = dt²·Σ (n-i-1+c)·u_i`` equal the triple integrator's over n·dt.
    """
    k = np.arange(n, dtype=np.float64)
    lag = k[:, None] - k[None, :]
    vel_from_u = (lag > 0) * dt  # v_k = v_0 + dt·Σ_{i<k} u_i
    pos_from_u = np.where(lag > 0, lag - 1 + c, 0.0) * dt * dt  # p_k = p_0 + k·dt·v_0 + dt²·Σ ...
    end = np.vstack([np.full(n, dt), dt * dt * (n - k - 1 + c)])
    period = n * dt
    f, g = transition_matrices(period)
    target_from_aj = np.array([[f[1, 2], g[1]], [f[0, 2], g[0]]])  # rows Δv, Δp from (a, jerk)
    u_from_aj = np.column_stack([np.ones(n), k * dt + dt / 2])
    u_from_aj = u_from_aj + np.linalg.pinv(end) @ (target_from_aj - end @ u_from_aj)
    blocks = np.zeros((n, 3, 4))
    blocks[:, 0, 2:] = u_from_aj
    blocks[:, 1, 1] = 1.0
    blocks[:, 1, 2:] = vel_from_u @ u_from_aj
    blocks[:, 2, 0] = 1.0
    blocks[:, 2, 1] = k * dt
    blocks[:, 2, 2:] = pos_from_u @ u_from_aj
    return blocks.reshape(3 * n, 4)


def plan_substeps(p: np.ndarray, v: np.ndarray, a: np.ndarray, jerk: np.ndarray, n: int, dt: float,
                  c: float) -> list[tuple[float, ...]]:
    """Per-substep accelerations whose discrete trajectory ends on the triple integrator.

    Args:
        p, v, a, jerk: (2,) reference state at the period start (m, m/s, m/s²) and jerk, m/s³.
        n: Substeps in the period (n >= 2 ends exactly; n = 1 in the least-squares sense).
        dt: Physics step, s.
        c: Position gain of one constant-acceleration step (1/2 RK4, 1 Euler).

    Returns:
        n tuples ``(ux, uy, vx, vy, px, py)``: the acceleration of substep k (m/s²) and the planned
        velocity and position at its start.
    """
    rows = _plan_matrix(int(n), float(dt), float(c)) @ np.array([p, v, a, jerk], dtype=np.float64)
    return [tuple(r) for r in rows.reshape(n, 6).tolist()]


def integrator_value(name: str) -> int:
    """MuJoCo integrator enum value for ``RK4``, ``Euler``, ``implicit`` or ``implicitfast``."""
    table = {"RK4": mujoco.mjtIntegrator.mjINT_RK4, "Euler": mujoco.mjtIntegrator.mjINT_EULER,
             "implicit": mujoco.mjtIntegrator.mjINT_IMPLICIT,
             "implicitfast": mujoco.mjtIntegrator.mjINT_IMPLICITFAST}
    if name not in table:
        raise ValueError(f"integrator {name!r}: use one of {sorted(table)}")
    return int(table[name])


@functools.cache
def _robot_xml(with_rays: bool) -> str:
    """The text of ``assets/robot.xml``, without its ray sites and rangefinders unless ``with_rays``
    (dropping the lines is 20x faster than removing 720 parsed elements)."""
    text = asset("robot.xml").read_text(encoding="utf-8")
    return text if with_rays else _RAY_LINE.sub("", text)


def _load_mjcf(config: RobotConfig, lidar: LidarConfig, name: str, with_rays: bool) -> mjcf.RootElement:
    """``assets/robot.xml`` with the config's model name, LiDAR height, mass, disc size and force limit (SI)."""
    root = mjcf.from_xml_string(_robot_xml(with_rays), model_dir=str(asset("robot.xml").parent))
    root.model = name
    root.find("body", "base").pos = (0, 0, lidar.height)
    inertial = root.find("body", "base").inertial
    inertial.mass = config.mass
    inertial.diaginertia = np.full(3, 0.5 * config.mass * config.radius**2)
    root.find("geom", "disc").size = (config.radius, config.height / 2)
    for axis in ("x", "y"):
        root.find("actuator", f"force_{axis}").ctrlrange = (-config.force_max, config.force_max)
    return root


def _add_rangefinders(root: mjcf.RootElement, body: mjcf.Element, lidar: LidarConfig) -> tuple[list, list]:
    """Ray sites (before the camera, as in the asset) and rangefinders for ``lidar.beams`` beams."""
    position = body.all_children().index(root.find("camera", "follow"))
    sites, sensors = [], []
    for i, angle in enumerate(beam_angles(lidar.beams)):
        sites.append(body.insert("site", position + i, name=f"ray_{i:03d}", size=(0.005,), group=4,
                                 zaxis=(np.cos(angle), np.sin(angle), 0.0)))
        sensors.append(root.sensor.add("rangefinder", name=f"ray_{i:03d}", site=sites[-1]))
    return sites, sensors
