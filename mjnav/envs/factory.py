"""Build a stage's composer environment."""

from __future__ import annotations

from pathlib import Path

from dm_control import composer

from mjnav.config import TaskConfig, load_task, override_task
from mjnav.envs.environment import NavEnvironment
from mjnav.schema import apply_overrides
from mjnav.tasks.nav import CrowdNavTask

__all__ = ["make_env", "resolve_config"]


def resolve_config(task: str | Path | TaskConfig, overrides: dict | list[str] | None = None) -> TaskConfig:
    """A :class:`TaskConfig` from a stage name, a YAML path or a config, with dotted overrides."""
    if isinstance(task, TaskConfig):
        return override_task(task, overrides)
    return load_task(task, overrides)


def make_env(
    task: str | Path | TaskConfig = "stage6",
    seed: int | None = None,
    overrides: dict | list[str] | None = None,
) -> composer.Environment:
    """A ``composer.Environment`` for a stage.

    Args:
        task: Stage name (``"stage6"``), YAML path or :class:`TaskConfig`.
        seed: Seed of the environment's random state; episode seeds are drawn from it.
        overrides: Dotted config overrides (``["crowd.count=25"]``).

    Returns:
        The environment (a :class:`NavEnvironment`, composer's with one physics-state check per
        control step); ``env.task`` is the :class:`CrowdNavTask`. It compiles once here
        (first reset) and never again.
    """
    config = resolve_config(task, overrides)
    return NavEnvironment(
        CrowdNavTask(config),
        random_state=seed,
        strip_singleton_obs_buffer_dim=True,
        raise_exception_on_physics_error=True,
        recompile_mjcf_every_episode=False,  # fixed slots: episodes move things by binding
        legacy_step=False,  # the task syncs derived quantities once per control step
    )
