"""Non-learned navigation baselines, each a :class:`mjnav.planners.base.Planner`.

``mpc_goal`` (convex region + MPC towards the goal), ``mpc_gap`` (the same towards open space near
the goal direction), ``mpc_crowd`` (the same steered by the pedestrians' true motion: privileged, an
oracle), ``teb`` (timed elastic band), ``dwa``
(dynamic window) and ``random_jerk`` (:class:`RandomPlanner`). Set ``env.task.planner`` to one
and the task uses it instead of the learned action layer; the episode and its scoring stay the
same. Pure numpy/scipy; every planner brakes (and counts it in ``stats``) instead of raising.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from typing import TYPE_CHECKING

from mjnav.planners.dwa import DwaConfig, DwaPlanner
from mjnav.planners.mpc_crowd import MpcCrowdConfig, MpcCrowdPlanner
from mjnav.planners.mpc_goal import MpcGapConfig, MpcGapPlanner, MpcGoalPlanner
from mjnav.planners.random import RandomActionPolicy, RandomPlanner
from mjnav.planners.teb import TebConfig, TebPlanner
from mjnav.schema import ConfigError, apply_overrides

__all__ = [
    "PLANNERS",
    "PLANNER_CONFIGS",
    "DwaConfig",
    "DwaPlanner",
    "MpcCrowdConfig",
    "MpcCrowdPlanner",
    "MpcGapConfig",
    "MpcGapPlanner",
    "MpcGoalPlanner",
    "RandomActionPolicy",
    "RandomPlanner",
    "TebConfig",
    "TebPlanner",
    "make_planner",
    "planner_config",
]

if TYPE_CHECKING:
    from mjnav.planners.base import Planner

#: Planner factories by policy name.
PLANNERS: dict[str, Callable[[], Planner]] = {
    "mpc_goal": MpcGoalPlanner,
    "mpc_gap": MpcGapPlanner,
    "mpc_crowd": MpcCrowdPlanner,
    "teb": TebPlanner,
    "dwa": DwaPlanner,
    "random_jerk": RandomPlanner,
}


#: Parameter dataclass of each planner that takes ``planner.<field>=value`` overrides.
PLANNER_CONFIGS: dict[str, type] = {"dwa": DwaConfig, "teb": TebConfig, "mpc_gap": MpcGapConfig,
                                    "mpc_crowd": MpcCrowdConfig}


def planner_config(name: str, overrides: Sequence[str] = ()) -> object | None:
    """The parameters a planner runs with: its :data:`PLANNER_CONFIGS` defaults plus ``overrides``
    (None for a planner without parameters and no overrides).

    Raises:
        ConfigError: Overrides for a planner without parameters, or a bad override (unknown field,
            bad value: :func:`mjnav.schema.apply_overrides`).
    """
    if name not in PLANNER_CONFIGS:
        if overrides:
            raise ConfigError(f"planner overrides {list(overrides)}: {name} has no parameters "
                              f"(configurable: {', '.join(sorted(PLANNER_CONFIGS))})")
        return None
    return apply_overrides(PLANNER_CONFIGS[name](), list(overrides))


def make_planner(name: str, overrides: Sequence[str] = ()) -> Planner:
    """A fresh planner by name (one of :data:`PLANNERS`).

    Args:
        name: Planner name.
        overrides: ``["w_clearance=0.8", ...]`` applied to its parameters (:func:`planner_config`).

    Raises:
        KeyError: For an unknown name (the message lists the known ones).
        ConfigError: Overrides for a planner without parameters, or a bad override.
    """
    if name not in PLANNERS:
        raise KeyError(f"unknown baseline {name!r} (known: {', '.join(sorted(PLANNERS))})")
    if not overrides:
        return PLANNERS[name]()
    return PLANNERS[name](planner_config(name, overrides))
