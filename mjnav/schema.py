"""Typed, frozen config dataclasses for the world, robot and task terms, and the
generic validated merge used by the stage loader (:mod:`mjnav.config`).

Every dataclass validates its values in ``__post_init__``; :func:`merge` rejects
unknown keys and wrong types with the key's dotted path. Units are SI.
"""

from __future__ import annotations

import dataclasses
import difflib
import math
import numbers
import re
import types
import typing
from typing import Any, Literal

import yaml

__all__ = [
    "ArenaConfig",
    "ConfigError",
    "CrowdConfig",
    "LayoutConfig",
    "LidarConfig",
    "ObservationConfig",
    "ObstacleConfig",
    "RewardConfig",
    "RobotConfig",
    "TimingConfig",
    "apply_overrides",
    "check",
    "coerce",
    "from_dict",
    "merge",
    "parse_override",
    "to_dict",
]


class ConfigError(ValueError):
    """A config key or value is invalid; the message names the key and source."""


def check(cond: bool, name: str, msg: str) -> None:
    """Raise ``ValueError("name: msg")`` unless ``cond`` (config validation in ``__post_init__``)."""
    if not cond:
        raise ValueError(f"{name}: {msg}")





def _check_range(pair: tuple[float, float], name: str, low: float = 0.0) -> None:
    check(len(pair) == 2, name, "expects [min, max]")
    check(low <= pair[0] <= pair[1], name, f"needs {low} <= min <= max, got {list(pair)}")


@dataclasses.dataclass(frozen=True)
class ArenaConfig:
    """Walled rectangle around the stage interior.

    Attributes:
        size: Interior extent (x, y) in metres; the interior is centred on the origin.
        wall_thickness: Wall thickness in metres.
        wall_height: Wall height in metres.
    """

    size: tuple[float, float] = (20.0, 30.0)
    wall_thickness: float = 0.1
    wall_height: float = 0.6

    def __post_init__(self) -> None:
        check(len(self.size) == 2 and min(self.size) >= 2.0, "size", "needs two extents >= 2 m")
        check(self.wall_thickness > 0, "wall_thickness", "must be > 0")
        check(self.wall_height > 0, "wall_height", "must be > 0")


@dataclasses.dataclass(frozen=True)
class ObstacleConfig:
    """Static polygon prisms (triangles and quadrilaterals on a circle).

    Attributes:
        count: Obstacles per episode.
        slots: Compiled obstacle slots: 0 means ``count``; otherwise >= count, unused slots parked.
        circumradius: Radius of the circle the vertices lie on, metres.
        min_area: Smallest accepted polygon area (rejects slivers), m².
        max_area: Largest accepted polygon area, m².
        bank_size: Number of shapes in the per-task shape bank.
        bank_seed: Seed of the shape bank (shared by every environment of a task).
        height: Prism height, metres.
    """

    count: int = 0
    slots: int = 0
    circumradius: float = 1.0
    min_area: float = 0.3
    max_area: float = 2.0
    bank_size: int = 64
    bank_seed: int = 0
    height: float = 0.6

    def __post_init__(self) -> None:
        check(self.count >= 0, "count", "must be >= 0")
        check(self.slots == 0 or self.slots >= self.count, "slots", "must be 0 (= count) or >= count")
        check(self.circumradius > 0, "circumradius", "must be > 0")
        check(0 <= self.min_area < self.max_area, "min_area", "needs 0 <= min_area < max_area")
        check(self.bank_size >= 1, "bank_size", "must be >= 1")
        check(self.height > 0, "height", "must be > 0")

    @property
    def num_slots(self) -> int:
        """Compiled obstacle slots (``slots`` or ``count`` when 0)."""
        return max(self.slots, self.count)


#: Responsibility an ORCA pedestrian takes for avoiding the robot: as another agent (half) or as a
#: non-avoiding obstacle (all).
ROBOT_RESPONSIBILITY = {"agent": 0.5, "obstacle": 1.0}


@dataclasses.dataclass(frozen=True)
class OrcaConfig:
    """ORCA parameters. Defaults are CrowdNav's (``crowd_sim/envs/policy/orca.py``).

    Attributes:
        neighbor_dist: Largest centre distance of another disc that is considered, metres, > 0
            (CrowdNav 10; RVO2's examples 15).
        max_neighbors: Most other discs considered per agent, nearest first, >= 0 (CrowdNav 10).
        time_horizon: Other discs must not be hit within this time under constant velocities, s,
            > 0 (CrowdNav 5; longer: earlier, more cautious avoidance).
        time_horizon_obst: Same for walls and obstacles, s, > 0 (CrowdNav 5).
        safety_margin: Added to every disc radius (pedestrians and robot) inside ORCA, metres,
            >= 0 (CrowdNav adds 0.01 + ``safety_space`` = 0.01). Contacts use the true radii.
        max_speed_factor: Max speed as a multiple of each pedestrian's preferred speed, >= 1
            (CrowdNav 1: ``max_speed = v_pref``).
        goal_tolerance: Distance to the goal at which a new goal is drawn, metres, > 0 (as social
            force).
        reactive: Pedestrians avoid the robot disc when True; ignore it when False (the paper's
            non-reactive crowd, the default).
        robot_as: With ``reactive``, ``"agent"``: pedestrians take half of the avoidance, as if
            the robot were another ORCA agent (CrowdNav's visible robot); ``"obstacle"``: they
            take all of it, as for a moving obstacle that does not avoid them.
    """

    neighbor_dist: float = 10.0
    max_neighbors: int = 10
    time_horizon: float = 5.0
    time_horizon_obst: float = 5.0
    safety_margin: float = 0.01
    max_speed_factor: float = 1.0
    goal_tolerance: float = 0.5
    reactive: bool = False
    robot_as: Literal["agent", "obstacle"] = "agent"

    def __post_init__(self) -> None:
        for name in ("neighbor_dist", "time_horizon", "time_horizon_obst", "goal_tolerance"):
            _require_number(name, getattr(self, name), 0.0, strict=True)
        _require_number("safety_margin", self.safety_margin, 0.0, strict=False)
        _require_number("max_speed_factor", self.max_speed_factor, 1.0, strict=False)
        count = self.max_neighbors
        integer = isinstance(count, numbers.Integral) and not isinstance(count, bool)
        _require(integer and count >= 0, "max_neighbors", f"must be an integer >= 0, got {count!r}")
        _require(isinstance(self.reactive, bool), "reactive", f"must be true or false, got {self.reactive!r}")
        _require(self.robot_as in ROBOT_RESPONSIBILITY, "robot_as",
                 f"must be one of {sorted(ROBOT_RESPONSIBILITY)}, got {self.robot_as!r}")  # fmt: skip

    @property
    def robot_responsibility(self) -> float:
        """Share of the avoidance of the robot that a pedestrian takes (see :attr:`robot_as`)."""
        return ROBOT_RESPONSIBILITY[self.robot_as]


def _require(cond: bool, name: str, msg: str) -> None:
    """Raises ``ValueError("orca.<name>: <msg>")`` unless ``cond``."""
    if not cond:
        raise ValueError(f"orca.{name}: {msg}")


def _require_number(name: str, value: object, low: float, strict: bool) -> None:
    """Raises unless ``value`` is a finite real number above ``low`` (or equal, unless ``strict``)."""
    real = isinstance(value, numbers.Real) and not isinstance(value, bool)
    ok = real and math.isfinite(value) and (value > low if strict else value >= low)
    _require(ok, name, f"must be a finite number {'>' if strict else '>='} {low}, got {value!r}")



@dataclasses.dataclass(frozen=True)
class CrowdConfig:
    """Pedestrians: mocap-driven cylinders.

    Attributes:
        count: Pedestrians per episode.
        slots: Compiled pedestrian slots (>= count); unused slots are parked.
        radius: Radius range [min, max], metres.
        speed: Speed range [min, max], m/s.
        model: Motion model: a name of :data:`mjnav.world.PEDESTRIAN_MODELS` (``random_walk``, the
            paper's, ``social_force`` or ``orca``; checked when the task config is built).
        reactive: Whether pedestrians react to the robot: None keeps the model's own behaviour (the
            random walk and ORCA ignore the robot, as in the paper; social force is repelled by it);
            true makes social force and ORCA avoid it (ORCA: as :attr:`OrcaConfig.robot_as`), false
            makes them ignore it. The random walk cannot react (true is refused).
        yaw_rate: Random-walk heading rate bound, rad/s (uniform in ±yaw_rate).
        yaw_interval: Random walk: the yaw rate is re-drawn every this many seconds (proposal).
        height: Cylinder height, metres.
        relaxation_time: Social force: time to reach the desired velocity, s.
        repulsion_strength: Social force: pedestrian repulsion magnitude, m/s².
        repulsion_range: Social force: repulsion decay length, metres.
        wall_strength: Social force: wall/obstacle repulsion magnitude, m/s².
        wall_range: Social force: wall/obstacle repulsion decay length, metres.
        robot_strength: Social force: robot repulsion magnitude, m/s².
        goal_tolerance: Social force: distance at which a new goal is drawn, metres.
        max_speed_factor: Social force: speed cap as a multiple of the desired speed.
        orca: ORCA's parameters (``crowd.model=orca``); its ``reactive`` is set by ``crowd.reactive``.
    """

    count: int = 0
    slots: int = 0
    radius: tuple[float, float] = (0.2, 0.3)
    speed: tuple[float, float] = (0.3, 0.3)
    model: str = "random_walk"
    yaw_rate: float = math.pi / 6
    yaw_interval: float = 0.1
    height: float = 1.7
    relaxation_time: float = 0.5
    repulsion_strength: float = 10.0
    repulsion_range: float = 0.3
    wall_strength: float = 10.0
    wall_range: float = 0.2
    robot_strength: float = 10.0
    goal_tolerance: float = 0.5
    max_speed_factor: float = 1.3
    reactive: bool | None = None
    orca: OrcaConfig = OrcaConfig()

    def __post_init__(self) -> None:
        check(self.count >= 0, "count", "must be >= 0")
        check(self.slots == 0 or self.slots >= self.count, "slots", "must be 0 (= count) or >= count")
        _check_range(self.radius, "radius", low=0.01)
        _check_range(self.speed, "speed")
        check(self.yaw_rate >= 0, "yaw_rate", "must be >= 0")
        check(self.yaw_interval >= 0, "yaw_interval", "must be >= 0")
        check(self.max_speed_factor >= 1, "max_speed_factor", "must be >= 1")
        check(self.height > 0, "height", "must be > 0")
        check(self.relaxation_time > 0, "relaxation_time", "must be > 0")

    @property
    def num_slots(self) -> int:
        """Compiled pedestrian slots (``slots`` or ``count`` when 0)."""
        return max(self.slots, self.count)


@dataclasses.dataclass(frozen=True)
class RobotConfig:
    """Omni-directional point-mass robot (disc) and its tracking controller.

    Attributes:
        radius: Disc radius, metres.
        mass: Mass, kg.
        height: Disc height, metres.
        v_max: Per-axis velocity limit, m/s.
        a_max: Per-axis acceleration limit, m/s².
        j_max: Per-axis jerk limit, m/s³.
        force_max: Actuator force limit per axis, N (feed-forward plus feedback).
        kv: Velocity feedback gain of the tracking controller, 1/s.
        kp: Position feedback gain of the tracking controller, 1/s².
        model: The robot entity: a name of :data:`mjnav.entities.ROBOTS` (``omni``, the disc robot of
            the paper; checked when the simulation is built).
    """

    radius: float = 0.225
    mass: float = 10.0
    height: float = 0.3
    v_max: float = 2.5
    a_max: float = 4.0
    j_max: float = 8.0
    force_max: float = 200.0
    kv: float = 10.0
    kp: float = 0.0
    model: str = "omni"

    def __post_init__(self) -> None:
        for name in ("radius", "mass", "height", "v_max", "a_max", "j_max", "force_max"):
            check(getattr(self, name) > 0, name, "must be > 0")
        check(self.kv >= 0 and self.kp >= 0, "kv", "gains must be >= 0")


@dataclasses.dataclass(frozen=True)
class LidarConfig:
    """Planar 360° rangefinder.

    Attributes:
        beams: Number of beams (beam 0 along +x, counter-clockwise).
        max_range: Range, metres; no hit reads max_range.
        noise_std: Gaussian noise per beam, metres (clipped to [0, max_range]).
        backend: A name of :data:`mjnav.sensors.LIDAR_BACKENDS`: ``analytic`` (exact 2-D ray
            casting) or ``mujoco`` (MuJoCo ray casts in the world); checked when the simulation is built.
        height: Beam height above the floor, metres.
        rangefinders: Compile the 360 rangefinder sites and sensors into the task's robot (spec §2).
            Off by default: neither backend reads them (``mujoco`` casts with ``mj_multiRay``; the
            task disables sensors), and their site kinematics cost every physics evaluation (one
            per Euler step, four per RK4 step; ~10 % of a whole stage-7 control step). Exported
            worlds always have them.
    """

    beams: int = 360
    max_range: float = 10.0
    noise_std: float = 0.05
    backend: str = "analytic"
    height: float = 0.3
    rangefinders: bool = False

    def __post_init__(self) -> None:
        check(self.beams >= 8, "beams", "must be >= 8")
        check(self.max_range > 0, "max_range", "must be > 0")
        check(self.noise_std >= 0, "noise_std", "must be >= 0")
        check(self.height > 0, "height", "must be > 0")



@dataclasses.dataclass(frozen=True)
class TimingConfig:
    """Control and physics timing.

    Attributes:
        control_period: One RL/MPC step, seconds.
        substeps: Physics steps per control period.
        episode_steps: Control steps before a timeout (truncation).
        integrator: MuJoCo integrator (``Euler``, ``RK4``, ``implicit``, ``implicitfast``). The
            robot's tracking plan is exact for each, so the default is the cheapest.
    """

    control_period: float = 0.1
    substeps: int = 5
    episode_steps: int = 300
    integrator: Literal["Euler", "RK4", "implicit", "implicitfast"] = "Euler"

    def __post_init__(self) -> None:
        check(self.control_period > 0, "control_period", "must be > 0")
        check(self.substeps >= 1, "substeps", "must be >= 1")
        check(self.episode_steps >= 1, "episode_steps", "must be >= 1")

    @property
    def physics_timestep(self) -> float:
        """Physics step, seconds."""
        return self.control_period / self.substeps


@dataclasses.dataclass(frozen=True)
class LayoutConfig:
    """Episode layout sampling rules (spec §9).

    Attributes:
        start_goal_min_distance: Minimum start-goal distance, metres.
        start_goal_max_distance: Maximum start-goal distance, metres (0 = no limit).
        free_clearance: Clearance of start/goal from walls and obstacles, metres.
        obstacle_clearance: Minimum distance of obstacle centres from start and goal, metres.
        min_start_scan: Re-sample until the nearest shrunk scan reading at the start exceeds this, metres.
        pedestrian_gap: Minimum gap between pedestrians at spawn, metres.
        pedestrian_clearance: Minimum distance of pedestrian centres from start and goal at spawn,
            metres (spec §9's 1.95 m for obstacle centres, which the authors' task generator applies
            to pedestrians too; 0 gives task version 1's layouts).
        max_attempts: Attempts before sampling fails with an error.
    """

    start_goal_min_distance: float = 1.0
    start_goal_max_distance: float = 0.0
    free_clearance: float = 0.5
    obstacle_clearance: float = 1.95
    min_start_scan: float = 1.0
    pedestrian_gap: float = 0.1
    pedestrian_clearance: float = 1.95
    max_attempts: int = 1000

    def __post_init__(self) -> None:
        for name in ("start_goal_min_distance", "free_clearance", "obstacle_clearance", "min_start_scan",
                     "pedestrian_gap", "pedestrian_clearance"):
            check(getattr(self, name) >= 0, name, "must be >= 0")
        check(self.start_goal_max_distance == 0 or self.start_goal_max_distance >= self.start_goal_min_distance,
              "start_goal_max_distance", "must be 0 (no limit) or >= start_goal_min_distance")
        check(self.max_attempts >= 1, "max_attempts", "must be >= 1")


@dataclasses.dataclass(frozen=True)
class RewardConfig:
    """Reward terms and weights (spec §7).

    Attributes:
        variant: ``r_t1`` (all), ``r_t2`` (no change term), ``r_t3`` (no feasibility), ``r_t4`` (neither).
        goal_tolerance: Success distance d_th, metres.
        success: Success bonus.
        collision: Collision penalty (negative).
        proximity_scale: Proximity penalty scale (negative).
        proximity_decay: Proximity exponential decay, 1/m.
        proximity_range: Proximity applies when the min shrunk scan is below this, metres.
        approach_gain: Gain when approaching the goal.
        recede_gain: Gain when receding.
        approach_clip: Clip of the approach term's magnitude.
        feasibility: Feasibility weight (negative).
        feasibility_clip: Clip of the feasibility term's magnitude.
        change: Change weight (negative).
        slow: Slow-speed step penalty (negative).
        speed_scale: Speed normaliser of the slow term, m/s.
        velocity_change: Velocity-change penalty weight (negative).
        constant: Constant step reward.
    """

    variant: Literal["r_t1", "r_t2", "r_t3", "r_t4"] = "r_t1"
    goal_tolerance: float = 0.7
    success: float = 140.0
    collision: float = -30.0
    proximity_scale: float = -1.8
    proximity_decay: float = 2.0
    proximity_range: float = 2.0
    approach_gain: float = 3.0
    recede_gain: float = 2.0
    approach_clip: float = 1.5
    feasibility: float = -0.15
    feasibility_clip: float = 1.2
    change: float = -0.15
    slow: float = -0.01
    speed_scale: float = 2.5 * math.sqrt(2.0)
    velocity_change: float = -0.008
    constant: float = 0.0

    def __post_init__(self) -> None:
        check(self.goal_tolerance > 0, "goal_tolerance", "must be > 0")
        check(self.speed_scale > 0, "speed_scale", "must be > 0")
        for name in ("success", "approach_gain", "recede_gain", "approach_clip", "feasibility_clip",
                     "proximity_decay", "proximity_range"):
            check(getattr(self, name) >= 0, name, "must be >= 0")
        for name in ("collision", "proximity_scale", "feasibility", "change", "slow", "velocity_change"):
            check(getattr(self, name) <= 0, name, "is a penalty weight and must be <= 0")


@dataclasses.dataclass(frozen=True)
class ObservationConfig:
    """Observation layout options (spec §6).

    Attributes:
        frames: Stacked frames.
        angle: ``mpc`` (code: previous MPC direction vs goal) or ``velocity`` (paper).
        frame_stride: Control steps between stacked frames (1: consecutive, the paper's). Not in
            the paper: at 1 a pedestrian moves 3-6 cm between frames, the size of the scan noise.
        frame: Axes of every angle and velocity: ``world`` (the paper's) or ``goal`` (turned so
            that the goal lies at angle 0; not in the paper). Each frame is turned by the goal
            direction at its own step. With ``goal`` the same scene seen from another direction
            gives the same observation, so the network need not compose the goal direction from
            the world-frame polar angles, velocity and dθ; pair it with ``action.heading='goal'``.
        history: How the older frames' polygon blocks read: ``paper`` (each past region's own
            boundary points, seen from where the robot was then) or ``aligned`` (not in the paper:
            each past region read from the robot's current position along the current frame's
            bearings, so that an approaching pedestrian shows as a falling r̂ at a fixed θ̂; the same
            information, with the robot's own motion taken out; :func:`mjnav.tasks.observation.aligned_block`).
        critic_pedestrians: Privileged inputs of an asymmetric critic (training only; not in the
            paper): the K nearest pedestrians' true positions, velocities and radii
            (:mod:`mjnav.tasks.privileged`), reported as ``info["critic"]`` and given to the critic,
            never to the actor. 0: off (the paper's critic sees the actor's observation).
        tracks: K > 0 appends, after the stacked frames, the K nearest pedestrian tracks of the
            robot's own LiDAR tracker (:mod:`mjnav.perception`; not privileged) as
            ``[dx, dy, vx, vy, valid]`` in the observation's axes (not in the paper; "Ours +
            tracks", :func:`mjnav.tasks.observation.tracks_block`); turning it on runs the tracker.
            0: off (the paper's observation, bit for bit).
    """

    frames: int = 3
    angle: Literal["mpc", "velocity"] = "mpc"
    frame_stride: int = 1
    frame: Literal["world", "goal"] = "world"
    history: Literal["paper", "aligned"] = "paper"
    critic_pedestrians: int = 0
    tracks: int = 0

    def __post_init__(self) -> None:
        check(self.frames >= 1, "frames", "must be >= 1")
        check(self.tracks >= 0, "tracks", "must be >= 0 (0: off)")
        check(self.critic_pedestrians >= 0, "critic_pedestrians", "must be >= 0")
        check(self.frame_stride >= 1, "frame_stride", "must be >= 1")
        check(self.frame in ("world", "goal"), "frame", "must be 'world' or 'goal'")
        check(self.history in ("paper", "aligned"), "history", "must be 'paper' or 'aligned'")


def _is_dataclass_type(tp: Any) -> bool:
    return isinstance(tp, type) and dataclasses.is_dataclass(tp)


def coerce(value: Any, tp: Any, path: str) -> Any:
    """Convert a parsed (YAML) value to the annotated type ``tp``.

    Raises:
        ConfigError: Naming ``path``, on a value of the wrong type (``seed: expected an integer, got 'x'``).
    """
    return _coerce(value, tp, path)


def _coerce(value: Any, tp: Any, path: str) -> Any:
    """Convert a YAML value to the annotated type or raise ConfigError naming ``path``."""
    origin = typing.get_origin(tp)
    if _is_dataclass_type(tp):
        if not isinstance(value, dict):
            raise ConfigError(f"{path}: expected a mapping, got {value!r}")
        return from_dict(tp, value, path)
    if origin is Literal:
        if value not in typing.get_args(tp):
            raise ConfigError(f"{path}: {value!r} is not one of {list(typing.get_args(tp))}")
        return value
    if origin is tuple:
        args = typing.get_args(tp)
        if len(args) == 2 and args[1] is Ellipsis:  # tuple[T, ...]: any length
            if not isinstance(value, (list, tuple)):
                raise ConfigError(f"{path}: expected a list, got {value!r}")
            args = (args[0],) * len(value)
        if not isinstance(value, (list, tuple)) or len(value) != len(args):
            raise ConfigError(f"{path}: expected a list of {len(args)} values, got {value!r}")
        return tuple(_coerce(v, a, f"{path}[{i}]") for i, (v, a) in enumerate(zip(value, args)))
    if origin in (typing.Union, types.UnionType):
        for arg in typing.get_args(tp):
            if arg is type(None) and value is None:
                return None
        args = [a for a in typing.get_args(tp) if a is not type(None)]
        return _coerce(value, args[0], path)
    return _coerce_scalar(value, tp, path)


_EXPONENT = re.compile(r"[-+]?(\d+\.?\d*|\.\d+)[eE][-+]?\d+")


def _coerce_scalar(value: Any, tp: Any, path: str) -> Any:
    if tp is bool:
        if not isinstance(value, bool):
            raise ConfigError(f"{path}: expected true/false, got {value!r}")
        return value
    if tp is int:
        if isinstance(value, bool) or not isinstance(value, int):
            raise ConfigError(f"{path}: expected an integer, got {value!r}")
        return value
    if tp is float:
        if isinstance(value, str) and _EXPONENT.fullmatch(value.strip()):
            value = float(value)  # YAML 1.1 reads 1e-4 (no dot) as a string
        if isinstance(value, bool) or not isinstance(value, (int, float)) or not math.isfinite(value):
            raise ConfigError(f"{path}: expected a finite number, got {value!r}")
        return float(value)
    if tp is str:
        if not isinstance(value, str):
            raise ConfigError(f"{path}: expected a string, got {value!r}")
        return value
    raise ConfigError(f"{path}: unsupported field type {tp!r}")


def from_dict(cls: type, data: dict[str, Any], path: str = "") -> Any:
    """Build dataclass ``cls`` from a (partial) mapping over its defaults.

    Args:
        cls: A (frozen) config dataclass.
        data: Keys to set; missing keys keep their defaults, nested mappings recurse.
        path: Dotted prefix used in error messages.

    Returns:
        The validated instance.

    Raises:
        ConfigError: On an unknown key, a value of the wrong type or an invalid value.
    """
    return merge(cls(), data, path)


def merge(base: Any, data: dict[str, Any], path: str = "") -> Any:
    """Return ``base`` with the keys of ``data`` replaced (recursively, validated)."""
    hints = typing.get_type_hints(type(base))
    names = {f.name for f in dataclasses.fields(base)}
    changes: dict[str, Any] = {}
    for key, value in data.items():
        where = f"{path}{key}"
        if key not in names:
            near = difflib.get_close_matches(key, names, n=1)
            hint = f"; did you mean {near[0]!r}?" if near else ""
            raise ConfigError(f"{where}: unknown key (known: {', '.join(sorted(names))}){hint}")
        field_type = hints[key]
        if _is_dataclass_type(field_type) and isinstance(value, dict):
            changes[key] = merge(getattr(base, key), value, where + ".")
        else:
            changes[key] = _coerce(value, field_type, where)
    try:
        merged = dataclasses.replace(base, **changes)
        if hasattr(merged, "check_explicit"):  # sections whose fields derive from others
            merged.check_explicit(data)
        return merged
    except ValueError as err:
        raise ConfigError(f"{path}{err}") from None


def to_dict(config: Any) -> dict[str, Any]:
    """Plain nested dict of a config (tuples as lists), e.g. for YAML dumps."""

    def plain(value: Any) -> Any:
        if isinstance(value, tuple):
            return [plain(v) for v in value]
        if isinstance(value, dict):
            return {k: plain(v) for k, v in value.items()}
        return value

    return plain(dataclasses.asdict(config))


def parse_override(text: str) -> tuple[str, Any]:
    """Split ``a.b.c=value`` into the dotted key and a YAML-parsed value."""
    if "=" not in text:
        raise ConfigError(f"override {text!r}: expected key=value")
    key, raw = text.split("=", 1)
    if not key:
        raise ConfigError(f"override {text!r}: empty key")
    return key.strip(), yaml.safe_load(raw) if raw else ""


def _nest(key: str, value: Any) -> dict[str, Any]:
    out: Any = value
    for part in reversed(key.split(".")):
        out = {part: out}
    return out


def apply_overrides(config: Any, overrides: dict[str, Any] | list[str]) -> Any:
    """Apply dotted overrides (``{"crowd.count": 25}`` or ``["crowd.count=25"]``)."""
    items = dict(parse_override(o) for o in overrides) if isinstance(overrides, list) else overrides
    for key, value in items.items():
        try:
            config = merge(config, _nest(key, value))
        except ConfigError as err:
            raise ConfigError(f"override {key}={value!r}: {err}") from None
    return config
