"""Non-learned navigation planners, each a :class:`mjnav.planners.base.Planner`.

``mpc_goal`` (convex region + MPC towards the goal), ``mpc_gap`` (the same towards open space near
the goal direction), ``mpc_crowd`` (the same steered by the pedestrians' true motion: privileged, an
oracle), ``teb`` (timed elastic band), ``dwa`` (dynamic window) and ``random_jerk``
(:class:`RandomPlanner`). Set ``env.task.planner`` to one and the task uses it instead of the
learned action layer; the episode and its scoring stay the same. Pure numpy/scipy; every planner
brakes (and counts it in ``stats``) instead of raising.

Planners are looked up by name in :data:`PLANNERS` (``policy=<name>``; ``planner.<field>=value``
sets the fields of its config class). Outside packages add planners through the entry-point group
``mjnav.planners``; in one module::

    from mjnav.planners import PLANNERS

    @PLANNERS.register("straight")
    class Straight:  # a Planner: reset(config, rng) and act(PlannerInput) -> jerk
        ...
"""

from __future__ import annotations

from collections.abc import Sequence

from mjnav.planners.base import Planner, PlannerInput
from mjnav.planners.dwa import DwaConfig, DwaPlanner
from mjnav.planners.mpc_crowd import MpcCrowdConfig, MpcCrowdPlanner
from mjnav.planners.mpc_goal import MpcGapConfig, MpcGapPlanner, MpcGoalPlanner
from mjnav.planners.random import RandomActionPolicy, RandomPlanner
from mjnav.planners.teb import TebConfig, TebPlanner
from mjnav.registry import Registry
from mjnav.schema import ConfigError, apply_overrides

__all__ = [
    "PLANNERS",
    "DwaConfig",
    "DwaPlanner",
    "MpcCrowdConfig",
    "MpcCrowdPlanner",
    "MpcGapConfig",
    "MpcGapPlanner",
    "MpcGoalPlanner",
    "Planner",
    "PlannerInput",
    "RandomActionPolicy",
    "RandomPlanner",
    "TebConfig",
    "TebPlanner",
    "make_planner",
    "planner_config",
]

#: Planners by policy name; a factory takes its config class's instance (or nothing, without one).
PLANNERS: Registry[Planner] = Registry("planner", "mjnav.planners")
PLANNERS.register("mpc_goal", MpcGoalPlanner, source="builtin")
PLANNERS.register("mpc_gap", MpcGapPlanner, config=MpcGapConfig, source="builtin")
PLANNERS.register("mpc_crowd", MpcCrowdPlanner, config=MpcCrowdConfig, source="builtin")
PLANNERS.register("teb", TebPlanner, config=TebConfig, source="builtin")
PLANNERS.register("dwa", DwaPlanner, config=DwaConfig, source="builtin")
PLANNERS.register("random_jerk", RandomPlanner, source="builtin")


def planner_config(name: str, overrides: Sequence[str] = ()) -> object | None:
    """The parameters a planner runs with: its config class's defaults plus ``overrides``
    (None for a planner without parameters and no overrides).

    Raises:
        mjnav.registry.RegistryError: An unknown planner name.
        ConfigError: Overrides for a planner without parameters, or a bad override (unknown field,
            bad value: :func:`mjnav.schema.apply_overrides`).
    """
    config_class = PLANNERS.get(name).config_class
    if config_class is None:
        if overrides:
            configurable = [n for n in PLANNERS.names() if PLANNERS.get(n).config_class is not None]
            raise ConfigError(f"planner overrides {list(overrides)}: {name} has no parameters "
                              f"(configurable: {', '.join(configurable)})")
        return None
    return apply_overrides(config_class(), list(overrides))


def make_planner(name: str, overrides: Sequence[str] = ()) -> Planner:
    """A fresh planner by name (one of :data:`PLANNERS`).

    Args:
        name: Planner name.
        overrides: ``["w_clearance=0.8", ...]`` applied to its parameters (:func:`planner_config`).

    Raises:
        mjnav.registry.RegistryError: For an unknown name (a KeyError; the message lists the known
            ones and the closest).
        ConfigError: Overrides for a planner without parameters, or a bad override.
    """
    return PLANNERS.make(name, planner_config(name, overrides))
