"""Reward terms of spec §7 as small pure functions, weighted by :class:`RewardConfig`.

Each term is an unweighted quantity; the step reward is ``Σ weight[name] · term[name]``
over the terms enabled by the variant (``r_t1`` all, ``r_t2`` without ``change``,
``r_t3`` without ``feasibility``, ``r_t4`` without both). Terms are reported
weighted, one entry per name, so logs show ``reward/<name>``.
"""

from __future__ import annotations

import dataclasses
import math

import numpy as np

from mjnav.schema import RewardConfig

__all__ = ["TERMS", "RewardInputs", "compute_terms", "enabled_terms", "total", "weighted_terms", "weights"]

TERMS = (
    "success", "collision", "proximity", "approach", "feasibility", "change", "slow", "velocity_change", "constant",
)
_DISABLED = {"r_t1": (), "r_t2": ("change",), "r_t3": ("feasibility",), "r_t4": ("change", "feasibility")}


@dataclasses.dataclass(slots=True)
class RewardInputs:
    """What one control step hands to the reward (made every step, so not frozen: treat as read-only).

    Attributes:
        success: Goal reached this step (distance < goal tolerance).
        collision: Robot collided this step.
        min_scan: Smallest shrunk scan reading after the step, metres.
        distance: Robot-goal distance after the step, metres.
        prev_distance: Robot-goal distance before the step, metres (None on the first step).
        plan_ok: The MPC solved this step's QP (no fallback).
        prev_plan_ok: The previous step's plan succeeded (False on the first step).
        q_s, q_l: This step's action points (network's own Q_l), world frame, metres; ``q_s`` is
            None for a design without a short-term point (Design 3), whose Q_s terms drop out.
        q1, qn: This step's planned p₁ and p_N, world frame, metres.
        prev_q_s, prev_q_l: Previous step's action points, world frame (None on the first step).
        velocity: Robot velocity after the step, m/s.
        prev_velocity: Robot velocity before the step, m/s.
        control_period: Control period t_c, seconds.
    """

    success: bool
    collision: bool
    min_scan: float
    distance: float
    prev_distance: float | None
    plan_ok: bool
    prev_plan_ok: bool
    q_s: np.ndarray | None
    q_l: np.ndarray
    q1: np.ndarray
    qn: np.ndarray
    prev_q_s: np.ndarray | None
    prev_q_l: np.ndarray | None
    velocity: np.ndarray
    prev_velocity: np.ndarray
    control_period: float


def _dist(a: np.ndarray, b: np.ndarray) -> float:
    """Euclidean distance of two 2-vectors (Python floats: cheaper than numpy on 2 elements)."""
    return math.dist(a.tolist(), b.tolist())


def proximity(min_scan: float, cfg: RewardConfig) -> float:
    """exp(−decay·m) when the min shrunk scan m is below the range, else 0."""
    return math.exp(-cfg.proximity_decay * min_scan) if min_scan < cfg.proximity_range else 0.0


def approach(prev_distance: float | None, distance: float, cfg: RewardConfig) -> float:
    """Gain·(ρ_{t−1} − ρ_t), gain by direction, clipped to ±approach_clip; 0 on the first step."""
    if prev_distance is None:
        return 0.0
    progress = prev_distance - distance
    gain = cfg.approach_gain if progress > 0 else cfg.recede_gain
    return min(max(float(gain * progress), -cfg.approach_clip), cfg.approach_clip)


def feasibility(inp: RewardInputs, cfg: RewardConfig) -> float:
    """‖Q_s − p₁‖ + ‖Q_l − p_N‖ when the plan succeeded, capped so |weight·term| ≤ clip."""
    if not inp.plan_ok:
        return 0.0
    gap = (0.0 if inp.q_s is None else _dist(inp.q_s, inp.q1)) + _dist(inp.q_l, inp.qn)
    cap = cfg.feasibility_clip / abs(cfg.feasibility) if cfg.feasibility else math.inf
    return min(gap, cap)


def change(inp: RewardInputs) -> float:
    """‖ΔQ_s‖ + ‖ΔQ_l‖ (world frame) when the previous plan succeeded, else 0 (no Q_s: ‖ΔQ_l‖)."""
    if not inp.prev_plan_ok or inp.prev_q_l is None:
        return 0.0
    short = 0.0 if inp.q_s is None or inp.prev_q_s is None else _dist(inp.q_s, inp.prev_q_s)
    return short + _dist(inp.q_l, inp.prev_q_l)


def compute_terms(inp: RewardInputs, cfg: RewardConfig) -> dict[str, float]:
    """Unweighted value of every term in :data:`TERMS`."""
    (vx, vy), (px, py) = inp.velocity.tolist(), inp.prev_velocity.tolist()
    return {
        "success": float(inp.success),
        "collision": float(inp.collision),
        "proximity": proximity(inp.min_scan, cfg),
        "approach": approach(inp.prev_distance, inp.distance, cfg),
        "feasibility": feasibility(inp, cfg),
        "change": change(inp),
        "slow": 1.0 - math.hypot(vx, vy) / cfg.speed_scale,
        "velocity_change": (abs(vx - px) + abs(vy - py)) / inp.control_period / 2.0,
        "constant": 1.0,
    }


def weights(cfg: RewardConfig) -> dict[str, float]:
    """Weight of every term (approach carries its gains inside the term, weight 1)."""
    return {
        "success": cfg.success,
        "collision": cfg.collision,
        "proximity": cfg.proximity_scale,
        "approach": 1.0,
        "feasibility": cfg.feasibility,
        "change": cfg.change,
        "slow": cfg.slow,
        "velocity_change": cfg.velocity_change,
        "constant": cfg.constant,
    }


def enabled_terms(cfg: RewardConfig) -> tuple[str, ...]:
    """Terms the variant keeps."""
    return tuple(t for t in TERMS if t not in _DISABLED[cfg.variant])


def weighted_terms(cfg: RewardConfig) -> tuple[tuple[str, float], ...]:
    """(name, weight) of the enabled terms, in :data:`TERMS` order."""
    w = weights(cfg)
    return tuple((name, w[name]) for name in enabled_terms(cfg))


def total(
    inp: RewardInputs, cfg: RewardConfig, terms_weights: tuple[tuple[str, float], ...] | None = None
) -> tuple[float, dict[str, float]]:
    """Step reward and its weighted terms (disabled terms are absent).

    Args:
        inp: The step's inputs.
        cfg: Reward weights and variant.
        terms_weights: :func:`weighted_terms` of ``cfg``, if the caller keeps it (it is the same
            every step); computed here otherwise.

    Returns:
        (reward, {name: weight·term}) with reward equal to the sum of the dict's values.
    """
    terms = compute_terms(inp, cfg)
    pairs = weighted_terms(cfg) if terms_weights is None else terms_weights
    weighted = {name: weight * terms[name] for name, weight in pairs}
    return float(sum(weighted.values())), weighted
