"""Non-learned navigation planners, each a :class:`mjnav.planners.base.Planner`.

``mpc_goal`` (convex region + MPC towards the goal), ``mpc_gap`` (the same towards open space near
the goal direction), ``mpc_crowd`` (the same steered by the pedestrians' true motion: privileged, an
oracle), ``mpc_tracked`` (the same steered by the robot's own LiDAR tracks), ``teb`` (timed
elastic band), ``dwa`` (dynamic window) and ``random_jerk`` (:class:`RandomPlanner`). Set
``env.task.planner`` to one and the task uses it instead of the learned action layer; the episode
and its scoring stay the same. numpy/scipy with numba kernels (TEB's band solver
:mod:`mjnav.planners.trf`, DWA's clearance); every planner brakes (and counts it in ``stats``)
instead of raising.

Planners are looked up by name in :data:`PLANNERS` (``policy=<name>``; ``planner.<field>=value``
sets the fields of its config class), or given as ``policy=package.module:Class`` or
``policy=path/to/file.py:Class`` (:func:`mjnav.planners.resolve.resolve`; the protocol and
an example are in the planners guide of the documentation). Outside packages add planners through the entry-point group
``mjnav.planners``; in one module::

    from mjnav.planners import PLANNERS

    @PLANNERS.register("straight")
    class Straight:  # a Planner: reset(config, rng) and act(PlannerInput) -> jerk
        ...
"""

from __future__ import annotations

from collections.abc import Sequence
from pathlib import Path

from mjnav.planners.base import Planner, PlannerInput
from mjnav.planners.dwa import DwaConfig, DwaPlanner
from mjnav.planners.mpc_crowd import MpcCrowdConfig, MpcCrowdPlanner
from mjnav.planners.mpc_tracked import MpcTrackedConfig, MpcTrackedPlanner
from mjnav.planners.mpc_goal import MpcGapConfig, MpcGapPlanner, MpcGoalConfig, MpcGoalPlanner
from mjnav.planners.random import RandomActionPolicy, RandomPlanner
from mjnav.planners.resolve import PlannerError, PlannerSource, is_spec, resolve
from mjnav.planners.teb import TebConfig, TebPlanner
from mjnav.registry import Registry

__all__ = [
    "PLANNERS",
    "DwaConfig",
    "DwaPlanner",
    "MpcCrowdConfig",
    "MpcCrowdPlanner",
    "MpcGapConfig",
    "MpcGapPlanner",
    "MpcGoalConfig",
    "MpcGoalPlanner",
    "MpcTrackedConfig",
    "MpcTrackedPlanner",
    "Planner",
    "PlannerError",
    "PlannerInput",
    "PlannerSource",
    "RandomActionPolicy",
    "RandomPlanner",
    "TebConfig",
    "TebPlanner",
    "is_planner_spec",
    "make_planner",
    "planner_config",
    "resolve_planner",
]

#: Planners by policy name; a factory takes its config class's instance (or nothing, without one).
PLANNERS: Registry[Planner] = Registry("planner", "mjnav.planners")
PLANNERS.register("mpc_goal", MpcGoalPlanner, config=MpcGoalConfig, source="builtin")
PLANNERS.register("mpc_gap", MpcGapPlanner, config=MpcGapConfig, source="builtin")
PLANNERS.register("mpc_crowd", MpcCrowdPlanner, config=MpcCrowdConfig, source="builtin")
PLANNERS.register("mpc_tracked", MpcTrackedPlanner, config=MpcTrackedConfig, source="builtin")
PLANNERS.register("teb", TebPlanner, config=TebConfig, source="builtin")
PLANNERS.register("dwa", DwaPlanner, config=DwaConfig, source="builtin")
PLANNERS.register("random_jerk", RandomPlanner, source="builtin")


def resolve_planner(spec: str | Path) -> PlannerSource:
    """The planner a spec names: a name of :data:`PLANNERS`, ``package.module:Class`` or
    ``path/to/file.py:Class`` (:func:`mjnav.planners.resolve.resolve`).

    Raises:
        mjnav.registry.RegistryError: An unknown name (a KeyError listing the known ones and the closest).
        PlannerError: A missing file, a failed import, no such class, not a Planner, a bad ``privileged``.
    """
    return resolve(spec, PLANNERS)


def is_planner_spec(spec: str | Path) -> bool:
    """Whether ``spec`` names a planner by its form (a name of :data:`PLANNERS`, ``module:Class`` or
    ``file.py:Class``); nothing is imported."""
    return is_spec(spec, PLANNERS)


def planner_config(name: str, overrides: Sequence[str] = ()) -> object | None:
    """The parameters a planner runs with: its config class's defaults plus ``overrides``
    (None for a planner without parameters and no overrides).

    Args:
        name: A planner spec: registered name, ``package.module:Class`` or ``file.py:Class``
            (:func:`mjnav.planners.resolve.resolve`).
        overrides: ``["w_clearance=0.8", ...]``.

    Raises:
        mjnav.registry.RegistryError: An unknown planner name.
        PlannerError: A module or file that cannot be loaded, or not a Planner.
        ConfigError: Overrides for a planner without parameters, or a bad override (unknown field,
            bad value: :func:`mjnav.schema.apply_overrides`).
    """
    return resolve_planner(name).config(overrides)


def make_planner(name: str, overrides: Sequence[str] = ()) -> Planner:
    """A fresh planner by spec (a name of :data:`PLANNERS`, ``package.module:Class`` or ``file.py:Class``).

    Args:
        name: Planner spec.
        overrides: ``["w_clearance=0.8", ...]`` applied to its parameters (:func:`planner_config`).

    Raises:
        mjnav.registry.RegistryError: For an unknown name (a KeyError; the message lists the known
            ones and the closest).
        PlannerError: A module or file that cannot be loaded, or not a Planner.
        ConfigError: Overrides for a planner without parameters, or a bad override.
    """
    return resolve_planner(name).make(overrides)
