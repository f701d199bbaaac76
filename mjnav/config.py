"""Stage configs: :class:`TaskConfig` and the YAML loader.

A stage file (``tasks/stageN.yaml``, :mod:`mjnav.stages`) holds *deltas* over the defaults of
:class:`TaskConfig`; it may name one parent with ``extends: stageM`` (one
level). Unknown keys and bad values fail at load time with the key's dotted
path and the file's name. Dotted overrides (``crowd.count=25``) use the same
validation, so scripts can expose them on the command line.
"""

from __future__ import annotations

import dataclasses
from pathlib import Path
from typing import Any, Literal

import yaml

from mjnav.args import task_overrides
from mjnav.control.action import ActionConfig
from mjnav.control.crowd import ShieldConfig
from mjnav.control.mpc import MpcConfig
from mjnav.geometry.region import RegionConfig
from mjnav.perception.tracker import TracksConfig
from mjnav.resources import tasks_dir
from mjnav.schema import (
    ArenaConfig,
    ConfigError,
    CrowdConfig,
    LayoutConfig,
    LidarConfig,
    ObservationConfig,
    ObstacleConfig,
    RewardConfig,
    RobotConfig,
    TimingConfig,
    apply_overrides,
    merge,
)
from mjnav.tasks.design import DESIGNS, get_design
from mjnav.world import PEDESTRIAN_MODELS

__all__ = ["ConfigError", "TaskConfig", "TASK_SECTIONS", "load_task", "override_task", "task_dir"]


@dataclasses.dataclass(frozen=True)
class TaskConfig:
    """A whole navigation stage.

    Attributes:
        name: Stage name (``stage6``).
        version: Behaviour version; bumped when results would change.
        collision: ``contact`` (MuJoCo contacts) or ``scan`` (authors: shrunk scan <= 0).
        design: State and action design of the paper's first ablation (``ours``, ``design1`` …
            ``design4``): a name of :data:`mjnav.tasks.design.DESIGNS`.
    """

    name: str = "custom"
    version: int = 2  # 2: pedestrians keep layout.pedestrian_clearance from start and goal
    collision: Literal["contact", "scan"] = "contact"
    design: str = "ours"
    arena: ArenaConfig = ArenaConfig()
    obstacles: ObstacleConfig = ObstacleConfig()
    crowd: CrowdConfig = CrowdConfig()
    robot: RobotConfig = RobotConfig()
    lidar: LidarConfig = LidarConfig()
    timing: TimingConfig = TimingConfig()
    layout: LayoutConfig = LayoutConfig()
    region: RegionConfig = RegionConfig()
    action: ActionConfig = ActionConfig()
    mpc: MpcConfig = MpcConfig()
    reward: RewardConfig = RewardConfig()
    observation: ObservationConfig = ObservationConfig()
    tracks: TracksConfig = TracksConfig()
    shield: ShieldConfig = ShieldConfig()

    def _derived(self) -> dict[str, dict[str, tuple[str, Any]]]:
        """Copies the action layer keeps of other sections: ``{section: {field: (source key, value)}}``."""
        t_c, robot = self.timing.control_period, self.robot
        return {
            "mpc": {"t_c": ("timing.control_period", t_c), "v_max": ("robot.v_max", robot.v_max),
                    "a_max": ("robot.a_max", robot.a_max), "j_max": ("robot.j_max", robot.j_max),
                    "track_short": ("design (design3 tracks Q_l only)", self.design != "design3")},
            "action": {"t_c": ("timing.control_period", t_c), "jerk_max": ("robot.j_max", robot.j_max),
                       "long_time": ("mpc.horizon x timing.control_period", self.mpc.horizon * t_c)},
            "region": {"max_range": ("lidar.max_range", self.lidar.max_range)},
            "tracks": {"noise_std": ("lidar.noise_std", self.lidar.noise_std)},
        }

    def __post_init__(self) -> None:
        """Fill the derived copies from their sources and check cross-section constraints.

        ``robot``, ``timing``, ``lidar`` and ``mpc.horizon`` are the sources of truth: the copies
        (``mpc.v_max``, ``action.t_c``, ...) always follow them; setting a copy explicitly to another
        value is rejected by :meth:`check_explicit`.
        """
        for section, fields in self._derived().items():
            values = {name: value for name, (_, value) in fields.items()}
            object.__setattr__(self, section, dataclasses.replace(getattr(self, section), **values))
        if self.region.inflation < self.robot.radius:
            raise ValueError(f"region.inflation: {self.region.inflation} m is below robot.radius "
                             f"({self.robot.radius} m): the free region would not keep the robot's disc clear")
        self._check_registered()
        if self.shield.enabled and (action := get_design(self.design).action) != "points":
            raise ValueError(f"shield.enabled: the crowd shield checks the action's two reference points; design "
                             f"{self.design!r} acts with {action!r} (use a design with action 'points', such as ours)")
        if self.lidar.beams < self.region.num_points:
            raise ValueError(f"lidar.beams: {self.lidar.beams} beams cannot give region.num_points "
                             f"({self.region.num_points}) boundary points")

    def _check_registered(self) -> None:
        """Raise ValueError, naming the key, for a design or pedestrian model no registry knows."""
        for key, registry, name in (("design", DESIGNS, self.design), ("crowd.model", PEDESTRIAN_MODELS, self.crowd.model)):
            if name not in registry:
                raise ValueError(f"{key}: {registry.unknown_message(name)}")

    def check_explicit(self, data: dict[str, Any]) -> None:
        """Reject keys in ``data`` that set a derived copy to a value other than its source's.

        Raises:
            ValueError: Naming the copy and the key to set instead.
        """
        for section, fields in self._derived().items():
            given = data.get(section)
            if not isinstance(given, dict):
                continue
            for name, (key, value) in fields.items():
                if name in given and given[name] != value:
                    raise ValueError(f"{section}.{name}: {given[name]} disagrees with {key} ({value}); "
                                     f"it is derived: set {key}")


#: Field names of :class:`TaskConfig`: the first part of a short config key (``crowd.count=25``).
TASK_SECTIONS = tuple(f.name for f in dataclasses.fields(TaskConfig))


def override_task(config: TaskConfig, overrides: dict[str, Any] | list[str] | None) -> TaskConfig:
    """``config`` with dotted overrides applied; ``task.crowd.count`` and ``crowd.count`` mean the same
    (the command line's key forms, :func:`mjnav.args.task_overrides`).

    Raises:
        ConfigError: An unknown key (with the closest known one) or a bad value.
    """
    return apply_overrides(config, task_overrides(overrides or {}, TASK_SECTIONS))


def task_dir() -> Path:
    """Folder of the stage YAML files (:func:`mjnav.resources.tasks_dir`)."""
    return tasks_dir()


def _read_yaml(path: Path) -> dict[str, Any]:
    """The mapping in a task YAML file; an empty, unparsable or non-mapping file is a ConfigError
    (an empty file would otherwise silently mean "all defaults"; write ``{}`` for that)."""
    try:
        with open(path, encoding="utf-8") as f:
            data = yaml.safe_load(f)
    except (yaml.YAMLError, UnicodeDecodeError) as err:
        raise ConfigError(f"{path}: not valid YAML ({str(err).splitlines()[0]})") from None
    if data is None:
        raise ConfigError(f"{path}: empty task file (write {{}} for the defaults)")
    if not isinstance(data, dict):
        raise ConfigError(f"{path.name}: top level must be a mapping")
    return data


def _resolve_path(name_or_path: str | Path) -> Path:
    path = Path(name_or_path)
    if path.suffix in (".yaml", ".yml"):
        if not path.is_file():
            raise ConfigError(f"task file {str(path)!r} does not exist")
        return path
    candidate = task_dir() / f"{name_or_path}.yaml"
    if not candidate.exists():
        known = sorted(p.stem for p in task_dir().glob("*.yaml"))
        raise ConfigError(f"unknown task {str(name_or_path)!r} (known: {', '.join(known)})")
    return candidate


def load_task(name_or_path: str | Path, overrides: dict[str, Any] | list[str] | None = None) -> TaskConfig:
    """Load a stage config (``stage6`` or a YAML path) and apply dotted overrides.

    Args:
        name_or_path: A bundled stage name or the path of a YAML file.
        overrides: Dotted overrides applied after the file.

    Returns:
        The validated :class:`TaskConfig`.

    Raises:
        ConfigError: The message names the offending key and file.
    """
    path = _resolve_path(name_or_path)
    data = _read_yaml(path)
    parent = data.pop("extends", None)
    config = TaskConfig(name=path.stem)
    if parent is not None:
        parent_path = _resolve_path(parent)
        parent_data = _read_yaml(parent_path)
        if "extends" in parent_data:
            raise ConfigError(f"{path.name}: 'extends' allows one level ({parent_path.name} extends again)")
        config = _merge_file(config, parent_data, parent_path)
    config = _merge_file(config, {"name": path.stem, **data}, path)
    return override_task(config, overrides)


def _merge_file(config: TaskConfig, data: dict[str, Any], path: Path) -> TaskConfig:
    try:
        return merge(config, data)
    except ConfigError as err:
        raise ConfigError(f"{path.name}: {err}") from None
