"""Stage configs: :class:`TaskConfig` and the YAML loader.

A stage file (``tasks/stageN.yaml``) holds *deltas* over the defaults of
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

from mjnav.control.action import ActionConfig
from mjnav.control.mpc import MpcConfig
from mjnav.geometry.region import RegionConfig
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

__all__ = ["ConfigError", "TaskConfig", "load_task", "task_dir"]


@dataclasses.dataclass(frozen=True)
class TaskConfig:
    """A whole navigation stage.

    Attributes:
        name: Stage name (``stage6``).
        version: Behaviour version; bumped when results would change.
        collision: ``contact`` (MuJoCo contacts) or ``scan`` (authors: shrunk scan <= 0).
    """

    name: str = "custom"
    version: int = 1
    collision: Literal["contact", "scan"] = "contact"
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

    def __post_init__(self) -> None:
        """Derive the action layer's copies of robot limits and timing from ``robot``/``timing``/``lidar``.

        ``robot``, ``timing`` and ``lidar`` are the sources of truth; a copy set explicitly to a
        different value (not its default) is an error naming both keys.
        """
        sources = {"t_c": ("timing.control_period", self.timing.control_period),
                   "v_max": ("robot.v_max", self.robot.v_max), "a_max": ("robot.a_max", self.robot.a_max),
                   "j_max": ("robot.j_max", self.robot.j_max), "jerk_max": ("robot.j_max", self.robot.j_max),
                   "max_range": ("lidar.max_range", self.lidar.max_range)}
        derived = {"mpc": ("t_c", "v_max", "a_max", "j_max"), "action": ("t_c", "jerk_max"),
                   "region": ("max_range",)}
        for section, fields in derived.items():
            sub = getattr(self, section)
            default = type(sub)()
            changes = {}
            for name in fields:
                key, value = sources[name]
                current = getattr(sub, name)
                if current not in (value, getattr(default, name)):
                    raise ValueError(f"{section}.{name}: {current} disagrees with {key} ({value}); set {key}")
                changes[name] = value
            object.__setattr__(self, section, dataclasses.replace(sub, **changes))



def task_dir() -> Path:
    """Folder of the bundled stage YAML files."""
    here = Path(__file__).resolve().parent
    for candidate in (here / "stages", here.parent / "tasks"):
        if candidate.is_dir():
            return candidate
    raise FileNotFoundError("stage folder not found next to the mjnav package")


def _read_yaml(path: Path) -> dict[str, Any]:
    with open(path, encoding="utf-8") as f:
        data = yaml.safe_load(f) or {}
    if not isinstance(data, dict):
        raise ConfigError(f"{path.name}: top level must be a mapping")
    return data


def _resolve_path(name_or_path: str | Path) -> Path:
    path = Path(name_or_path)
    if path.suffix in (".yaml", ".yml") and path.exists():
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
    return apply_overrides(config, overrides or {})


def _merge_file(config: TaskConfig, data: dict[str, Any], path: Path) -> TaskConfig:
    try:
        return merge(config, data)
    except ConfigError as err:
        raise ConfigError(f"{path.name}: {err}") from None
