"""``OmniRobot``: the omni-directional disc robot, its LiDAR sites and tracking controller (spec §1-2).

The robot is one body at LiDAR height with two slide joints (world x and y: no rotation, no
vertical motion, never touching the floor, so no friction), a cylinder geom, two force motors
and one rangefinder per beam (``ray_000`` ... on sites whose +z axis is the beam direction;
MuJoCo excludes the robot's own body from the rays). ``qpos`` is the world (x, y) position.

Tracking. At the start of each control period the caller sets the reference (p, v, a, jerk);
before every physics substep :meth:`OmniRobot.apply_tracking_force` applies, per axis,

    F = m·ā + m·kv·(v_ref − v) + m·kp·(p_ref − p),

where ā is the mean reference acceleration over the coming substep, ``a + j·(t + dt/2)``. With
a force held constant over a step, MuJoCo's RK4 integrates the resulting constant
acceleration exactly, so in free space the state after one period matches the triple
integrator to ~j·dt³/12 per substep (≈ 0.03 mm over 0.1 s at the jerk limit); semi-implicit
Euler is off by ~ā·dt²/2 per substep (mm), see ``tests/entities/test_robot.py``.

The controller method is deliberately not named ``before_substep``: that is a composer
``Entity`` hook (``physics, random_state``) which composer calls by itself; NavSim calls
:meth:`OmniRobot.apply_tracking_force` from the task's ``before_substep`` instead.

MuJoCo has no acceleration state: :attr:`OmniRobot.acceleration` (the reference acceleration
``a + j·t``) is the robot's acceleration for the MPC.
"""

from __future__ import annotations

import mujoco
import numpy as np
from dm_control import composer, mjcf

from mjnav.geometry.raycast import beam_angles
from mjnav.schema import LidarConfig, RobotConfig

__all__ = ["ROBOT_CONTYPE", "OmniRobot", "integrator_value"]

#: The robot is the only geom with a contype bit; scene geoms have conaffinity 1.
ROBOT_CONTYPE = 1


class OmniRobot(composer.Entity):
    """Disc robot with x/y slide joints, force motors, rangefinders and a tracking controller."""

    def _build(self, config: RobotConfig, lidar: LidarConfig, rangefinders: bool = True,
               name: str = "robot") -> None:
        """Builds the MJCF.

        Args:
            config: Radius, mass, height, limits and tracking gains (SI units).
            lidar: Beam count and height of the rangefinders.
            rangefinders: Add the per-beam sites and rangefinder sensors (spec §2). Their site
                poses cost MuJoCo ~3 us per kinematics pass (4 per RK4 step); without them the
                ``mujoco`` LiDAR backend still works through ``mj_multiRay``.
            name: MJCF model name (the namespace of its elements).
        """
        self._config = config
        self._lidar = lidar
        self._mjcf_root = mjcf.RootElement(model=name)
        self._body = self._mjcf_root.worldbody.add("body", name="base", pos=(0, 0, lidar.height))
        self._body.add("inertial", pos=(0, 0, 0), mass=config.mass,
                       diaginertia=np.full(3, 0.5 * config.mass * config.radius**2))
        self._joints = [self._body.add("joint", name=axis, type="slide", axis=vec, damping=0, armature=0)
                        for axis, vec in (("x", (1, 0, 0)), ("y", (0, 1, 0)))]
        self._geom = self._body.add("geom", name="disc", type="cylinder", rgba=(0.15, 0.45, 0.85, 1),
                                    size=(config.radius, config.height / 2), contype=ROBOT_CONTYPE,
                                    conaffinity=0)
        self._actuators = [
            self._mjcf_root.actuator.add("motor", name=f"force_{j.name}", joint=j, gear=(1,),
                                         ctrllimited=True, ctrlrange=(-config.force_max, config.force_max))
            for j in self._joints
        ]
        self._sites, self._sensors = self._add_rangefinders(lidar) if rangefinders else ([], [])
        self._camera = self._body.add("camera", name="follow", pos=(0, -4.0, 6.0),
                                      xyaxes=(1, 0, 0, 0, 0.83, 0.55))
        self._cache_model = None
        self.reset_reference(np.zeros(2))

    def _add_rangefinders(self, lidar: LidarConfig) -> tuple[list, list]:
        sites, sensors = [], []
        for i, angle in enumerate(beam_angles(lidar.beams)):
            site = self._body.add("site", name=f"ray_{i:03d}", size=(0.005,), group=4,
                                  zaxis=(np.cos(angle), np.sin(angle), 0.0))
            sites.append(site)
            sensors.append(self._mjcf_root.sensor.add("rangefinder", name=f"ray_{i:03d}", site=site))
        return sites, sensors

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
        return self._a + self._j * self._t

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
        self._qpos_list = [int(i) for i in self._qpos_adr]
        self._dof_list = [int(i) for i in self._dof_adr]
        self._ctrl_list = [int(i) for i in self._ctrl_adr]
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
        self.set_reference(position, np.zeros(2), np.zeros(2), np.zeros(2))

    def set_reference(self, p: np.ndarray, v: np.ndarray, a: np.ndarray, jerk: np.ndarray) -> None:
        """Starts a control period: the triple-integrator reference from (p, v, a) under ``jerk``.

        Args:
            p: (2,) position at the period start, metres.
            v: (2,) velocity, m/s.
            a: (2,) acceleration, m/s².
            jerk: (2,) jerk held over the period, m/s³.
        """
        self._p = np.array(p, dtype=np.float64)
        self._v = np.array(v, dtype=np.float64)
        self._a = np.array(a, dtype=np.float64)
        self._j = np.array(jerk, dtype=np.float64)
        self._pf, self._vf = [float(x) for x in self._p], [float(x) for x in self._v]
        self._af, self._jf = [float(x) for x in self._a], [float(x) for x in self._j]
        self._t = 0.0

    def reference(self, t: float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Reference (p, v, a) at time ``t`` into the period (exact triple integrator)."""
        p, v, a, j = self._p, self._v, self._a, self._j
        return (p + v * t + a * (t * t / 2) + j * (t**3 / 6), v + a * t + j * (t * t / 2), a + j * t)

    def apply_tracking_force(self, physics: mjcf.Physics, t_in_period: float | None = None) -> None:
        """Writes the tracking force for the coming physics step and advances the period clock.

        Args:
            physics: The physics.
            t_in_period: Time since the period start, s; None continues the internal clock.
        """
        self._bind(physics)
        if t_in_period is not None:
            self._t = float(t_in_period)
        t, dt, cfg = self._t, self._dt, self._config
        data = physics.data.ptr
        qpos, qvel, ctrl = data.qpos, data.qvel, data.ctrl
        m, kv, kp, fmax = cfg.mass, cfg.kv, cfg.kp, cfg.force_max
        tm, t2, t3 = t + dt / 2, t * t / 2, t**3 / 6
        for axis in range(2):  # plain floats: ~3x faster than 2-element numpy arithmetic
            p, v, a, j = self._pf[axis], self._vf[axis], self._af[axis], self._jf[axis]
            force = a + j * tm + kv * (v + a * t + j * t2 - qvel[self._dof_list[axis]])
            if kp:
                force += kp * (p + v * t + a * t2 + j * t3 - qpos[self._qpos_list[axis]])
            ctrl[self._ctrl_list[axis]] = min(max(m * force, -fmax), fmax)
        self._t = t + dt


def integrator_value(name: str) -> int:
    """MuJoCo integrator enum value for ``RK4``, ``Euler``, ``implicit`` or ``implicitfast``."""
    table = {"RK4": mujoco.mjtIntegrator.mjINT_RK4, "Euler": mujoco.mjtIntegrator.mjINT_EULER,
             "implicit": mujoco.mjtIntegrator.mjINT_IMPLICIT,
             "implicitfast": mujoco.mjtIntegrator.mjINT_IMPLICITFAST}
    if name not in table:
        raise ValueError(f"integrator {name!r}: use one of {sorted(table)}")
    return int(table[name])
