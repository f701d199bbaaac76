"""The MPC as the region layer's failure mode asks for it (:class:`GuardedMpc`).

With ``region.on_failure='recover'`` (:mod:`mjnav.geometry.region`) the MPC never plans without
a polygon (``keep_clear``: a failed QP brakes instead of dropping the polygon) and, while the
polygon is a recovered one (the robot is within R_inf of a return), plans with the per-axis
velocity limit ``region.recover_speed``. With ``on_failure='paper'`` it is the plain spec §5 MPC.
When there is no polygon at all the caller backs away instead
(:func:`mjnav.control.dynamics.escape`; :attr:`GuardedMpc.must_escape`).
"""

from __future__ import annotations

import dataclasses

import numpy as np

from mjnav.control.mpc import Mpc, MpcConfig, MpcResult
from mjnav.geometry.region import Region, RegionConfig

__all__ = ["GuardedMpc"]


class GuardedMpc:
    """One environment's MPC, plus a slower one for recovered regions."""

    def __init__(self, mpc: MpcConfig, region: RegionConfig, constrained: bool = True) -> None:
        """Args: mpc: MPC parameters; region: region parameters (``on_failure``, ``recover_speed``);
        constrained: plan inside the polygon at all (False for Design 4)."""
        self.constrained = constrained
        self.keep_clear = region.on_failure == "recover" and constrained
        self.mpc = Mpc(mpc)
        slow = dataclasses.replace(mpc, v_max=min(mpc.v_max, region.recover_speed))
        self._slow = Mpc(slow) if self.keep_clear else None

    def reset(self) -> None:
        """Forget previous plans (every episode start)."""
        self.mpc.reset()
        if self._slow is not None:
            self._slow.reset()

    def must_escape(self, region: Region) -> bool:
        """Whether there is no polygon to plan in although one is required."""
        return self.keep_clear and not region.has_polygon

    def solve(self, state: np.ndarray, q_s: np.ndarray, q_l: np.ndarray, region: Region,
              goal_inside: bool = False) -> MpcResult:
        """Plan one step inside ``region`` (robot frame; see :meth:`Mpc.solve_unchecked`)."""
        planes = (region.normals, region.offsets) if self.constrained and region.has_polygon else None
        mpc = self._slow if self._slow is not None and region.recovered else self.mpc
        return mpc.solve_unchecked(state, q_s, q_l, planes, goal_inside, self.keep_clear)
