"""Non-learned navigation baselines, each a :class:`mjnav.tasks.core.Planner`.

``mpc_goal`` (convex region + MPC towards the goal), ``teb`` (timed elastic band), ``dwa``
(dynamic window) and ``random_jerk`` (:class:`RandomPlanner`). Set ``env.task.planner`` to one
and the task uses it instead of the learned action layer; the episode and its scoring stay the
same. Pure numpy/scipy; every planner brakes (and counts it in ``stats``) instead of raising.
"""

from __future__ import annotations

from collections.abc import Callable
from typing import TYPE_CHECKING

from mjnav.baselines.dwa import DwaConfig, DwaPlanner
from mjnav.baselines.mpc_goal import MpcGoalPlanner
from mjnav.baselines.random import RandomActionPolicy, RandomPlanner
from mjnav.baselines.teb import TebConfig, TebPlanner

__all__ = [
    "PLANNERS",
    "DwaConfig",
    "DwaPlanner",
    "MpcGoalPlanner",
    "RandomActionPolicy",
    "RandomPlanner",
    "TebConfig",
    "TebPlanner",
    "make_planner",
]

if TYPE_CHECKING:
    from mjnav.tasks.core import Planner

#: Planner factories by policy name.
PLANNERS: dict[str, Callable[[], Planner]] = {
    "mpc_goal": MpcGoalPlanner,
    "teb": TebPlanner,
    "dwa": DwaPlanner,
    "random_jerk": RandomPlanner,
}


def make_planner(name: str) -> Planner:
    """A fresh planner by name (one of :data:`PLANNERS`).

    Raises:
        KeyError: For an unknown name (the message lists the known ones).
    """
    if name not in PLANNERS:
        raise KeyError(f"unknown baseline {name!r} (known: {', '.join(sorted(PLANNERS))})")
    return PLANNERS[name]()
