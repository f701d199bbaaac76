"""Random baselines: the lower bounds of the comparison.

* :class:`RandomActionPolicy` (policy name ``random``): a raw action drawn from N(0, σ²) per
  value (σ = 1) every step and sent through the **learned** action path (sigmoid → reference
  points in the convex region → MPC with the polygon constraint). This is what an untrained
  policy does: it shows how much the safe action layer alone achieves.
* :class:`RandomPlanner` (policy name ``random_jerk``): a uniform random jerk in ±j_max per axis
  every step, as a :class:`mjnav.planners.base.Planner` (no region, no MPC), with the velocity kept
  inside ±v_max by braking the axes that would leave it.

Both draw from the generator handed to them at reset (the task gives planners their own stream
``default_rng([episode_seed, 1])``; the runner seeds the action policy the same way), so a
scenario stays paired across policies and runs are reproducible.
"""

from __future__ import annotations

from typing import TYPE_CHECKING

import numpy as np

from mjnav.control.dynamics import Limits, brake, integrate

__all__ = ["RandomActionPolicy", "RandomPlanner"]

if TYPE_CHECKING:
    from mjnav.config import TaskConfig
    from mjnav.planners.base import PlannerInput


class RandomActionPolicy:
    """Raw actions ~ N(0, std²), for the learned action path (``size`` values: the design's)."""

    def __init__(self, std: float = 1.0, size: int = 4) -> None:
        """``std``: standard deviation of each raw (pre-sigmoid) value; ``size``: action length."""
        self.std, self.size = std, size
        self._rng = np.random.default_rng(0)

    def reset(self, rng: np.random.Generator) -> None:
        """Start an episode with its own generator."""
        self._rng = rng

    def __call__(self, observation: np.ndarray) -> np.ndarray:
        """A (size,) float32 raw action (the observation is ignored)."""
        del observation
        return (self.std * self._rng.standard_normal(self.size)).astype(np.float32)


class RandomPlanner:
    """Uniform random jerk within the limits, as a :class:`mjnav.planners.base.Planner`."""

    def __init__(self) -> None:
        """No parameters: the limits come with :meth:`reset`."""
        self.limits = Limits()
        self.stats = {"failures": 0}
        self._rng = np.random.default_rng(0)

    def reset(self, config: TaskConfig, rng: np.random.Generator) -> None:
        """Start an episode (``config``: the task's TaskConfig)."""
        self.limits = Limits.from_task(config)
        self._rng = rng

    def act(self, inp: PlannerInput) -> np.ndarray:
        """Random jerk (2,), m/s³; axes heading past ±v_max brake instead."""
        lim = self.limits
        v = np.nan_to_num(np.asarray(inp.velocity, dtype=np.float64))
        a = np.nan_to_num(np.asarray(inp.acceleration, dtype=np.float64))
        jerk = self._rng.uniform(-lim.j_max, lim.j_max, 2)
        t = lim.control_period
        _, v_end, a_next = integrate(0.0, v, a, jerk, t)
        v_next = v_end + a * np.abs(a) / (2.0 * lim.j_max)
        stop = brake(v, a, lim)
        unsafe = (np.abs(v_next) > 0.9 * lim.v_max) | (np.abs(a_next) > lim.a_max)
        return np.where(unsafe, stop, jerk)
