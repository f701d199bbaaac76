"""State and action designs of the paper's first ablation (section "Ablation Study on State and
Action Space"; spec §11), selected by ``TaskConfig.design``.

========  =====================================  ================================  ==================
design    observation per frame                  action (raw → command)             MPC constraint
========  =====================================  ================================  ==================
ours      convex region (120) + 13 state values  (α_s, β_s, α_l, β_l) → Q_s, Q_l   convex region
design1   scan' (120) + dθ, ρ, v_x, v_y          (v_x, v_y) = v_max·tanh(a)         – (velocity tracking)
design2   convex region (120) + dθ, ρ, v_x, v_y  (v_x, v_y) = v_max·tanh(a)         – (velocity tracking)
design3   convex region (120) + 9 state values   (α_l, β_l) → Q_l (long-term space) convex region, p_N only
design4   scan' (120) + 12 state values          (α_s, β_s, α_l, β_l) → Q_s, Q_l   none
========  =====================================  ================================  ==================

``scan'`` is the raw scan at the polygon's resolution: every ``n/60``-th beam's (shrunk) range with
the same ``(r̂, θ̂)`` encoding as the polygon block (spec §11). The state columns index the 13
values of :func:`mjnav.tasks.observation.state_block` (``dθ, ρ, v_x, v_y, region_ok, θ(Q_s),
θ(Q_l), |Q_s|, |Q_l|, θ(Q*_1), θ(Q*_N), |Q*_1|, |Q*_N|``): Design 3 drops the Q_s and Q*_1 terms,
Design 4 the region flag (it has no region), Designs 1–2 keep ``ρ, v, dθ`` (paper eq. Design 1).
Design 4 samples both points in the scan's coverage (rays against the closed polyline of the
``scan'`` points) and plans without a polygon. Velocity actions are followed by the jerk-limited
velocity tracker the DWA and TEB baselines use (:func:`mjnav.control.dynamics.track_velocity`).

The velocity designs read their two axes as ``action.heading`` says, like Ours' and Design 3's
angles: ``velocity`` (default) along and across the current velocity (world axes at rest), the
frame their only goal term dθ is measured in; ``absolute`` as world axes, the paper's equation
taken literally. In world axes the goal direction is heading(v) + π·dθ, which the network has to
compose from v and dθ, and at rest dθ says nothing (the first Design 1 run learned nothing in
0.87M steps with it).

Designs are looked up by name in :data:`DESIGNS` (entry-point group ``mjnav.designs``); a new one
combines the observation, state columns and action kinds above: ``DESIGNS.register("mine",
lambda: Design("mine", "region", (0, 1, 2, 3), "points", 4, True))``.
"""

from __future__ import annotations

import dataclasses
from typing import Literal

from mjnav.registry import Registry

__all__ = ["DESIGNS", "Design", "get_design"]


@dataclasses.dataclass(frozen=True)
class Design:
    """One row of the table in the module docstring.

    Attributes:
        name: ``ours`` or ``design1`` … ``design4``.
        observe: ``region`` (the convex polygon's boundary) or ``scan`` (every n/60-th beam).
        state_columns: Indices into the 13-value state block kept in each frame.
        action: ``points`` (Q_s and Q_l), ``long_point`` (Q_l only) or ``velocity``.
        action_size: Raw action length.
        polygon_constraint: The MPC keeps its plan inside the convex region.
    """

    name: str
    observe: Literal["region", "scan"]
    state_columns: tuple[int, ...]
    action: Literal["points", "long_point", "velocity"]
    action_size: int
    polygon_constraint: bool

    @property
    def state_size(self) -> int:
        """Values per frame in the state block."""
        return len(self.state_columns)


#: Designs by ``design`` name; a factory takes no arguments and returns the :class:`Design`.
DESIGNS: Registry[Design] = Registry("design", "mjnav.designs")
_ALL = tuple(range(13))
for _design in (
    Design("ours", "region", _ALL, "points", 4, True),
    Design("design1", "scan", (0, 1, 2, 3), "velocity", 2, False),
    Design("design2", "region", (0, 1, 2, 3), "velocity", 2, False),
    Design("design3", "region", (0, 1, 2, 3, 4, 6, 8, 10, 12), "long_point", 2, True),
    Design("design4", "scan", (0, 1, 2, 3, *range(5, 13)), "points", 4, False),
):
    DESIGNS.register(_design.name, (lambda d=_design: d), source="builtin")


def get_design(name: str) -> Design:
    """The :class:`Design` called ``name``.

    Raises:
        ValueError: For an unknown name (the message lists the known ones and the closest).
    """
    if name not in DESIGNS:
        raise ValueError(f"design: {DESIGNS.unknown_message(name)}")
    return DESIGNS.make(name)
