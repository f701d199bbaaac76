"""Reward terms on hand-built states (spec §7)."""

import math

import numpy as np
import pytest

from mjnav.schema import RewardConfig
from mjnav.tasks import reward as R


def _inputs(**kw) -> R.RewardInputs:
    base = dict(
        success=False, collision=False, min_scan=5.0, distance=10.0, prev_distance=10.5,
        plan_ok=True, prev_plan_ok=True,
        q_s=np.array([1.0, 0.0]), q_l=np.array([4.0, 0.0]),
        q1=np.array([1.0, 0.0]), qn=np.array([4.0, 0.0]),
        prev_q_s=np.array([1.0, 0.0]), prev_q_l=np.array([4.0, 0.0]),
        velocity=np.array([2.0, 0.0]), prev_velocity=np.array([2.0, 0.0]), control_period=0.1,
    )
    base.update(kw)
    return R.RewardInputs(**base)


def test_total_is_weighted_sum_of_terms() -> None:
    """The step reward equals Σ weight·term over the enabled terms."""
    cfg = RewardConfig()
    inp = _inputs(min_scan=0.5, q_s=np.array([1.5, 0.2]), prev_q_l=np.array([3.0, 1.0]),
                  velocity=np.array([1.0, 0.5]))
    total, weighted = R.total(inp, cfg)
    raw, w = R.compute_terms(inp, cfg), R.weights(cfg)
    assert total == pytest.approx(sum(w[k] * raw[k] for k in R.TERMS))
    assert total == pytest.approx(sum(weighted.values()))


def test_success_and_collision_values() -> None:
    """Success gives +140 and collision −30 (plus proximity on the same step)."""
    cfg = RewardConfig()
    assert R.total(_inputs(success=True), cfg)[1]["success"] == 140.0
    _, terms = R.total(_inputs(collision=True, min_scan=0.0), cfg)
    assert terms["collision"] == -30.0
    assert terms["proximity"] == pytest.approx(-1.8)


def test_proximity_only_below_range() -> None:
    """Proximity is −1.8·exp(−2m) below 2 m and 0 from 2 m on."""
    cfg = RewardConfig()
    assert R.total(_inputs(min_scan=1.0), cfg)[1]["proximity"] == pytest.approx(-1.8 * math.exp(-2.0))
    assert R.total(_inputs(min_scan=2.0), cfg)[1]["proximity"] == 0.0


def test_approach_gains_and_clip() -> None:
    """Approaching pays 3×progress, receding 2×, clipped to ±1.5, nothing on the first step."""
    cfg = RewardConfig()
    assert R.approach(10.5, 10.0, cfg) == pytest.approx(1.5)
    assert R.approach(10.0, 9.8, cfg) == pytest.approx(0.6)
    assert R.approach(10.0, 10.2, cfg) == pytest.approx(-0.4)
    assert R.approach(10.0, 12.0, cfg) == pytest.approx(-1.5)
    assert R.approach(None, 9.0, cfg) == 0.0


def test_feasibility_plain_norms_clipped_and_gated() -> None:
    """Feasibility is −0.15·(‖Q_s−p₁‖+‖Q_l−p_N‖), at most 1.2 in magnitude, 0 after a failed plan."""
    cfg = RewardConfig()
    inp = _inputs(q1=np.array([1.0, 0.3]), qn=np.array([4.0, -0.4]))
    assert R.total(inp, cfg)[1]["feasibility"] == pytest.approx(-0.15 * 0.7)
    far = _inputs(qn=np.array([40.0, 0.0]))
    assert R.total(far, cfg)[1]["feasibility"] == pytest.approx(-1.2)
    assert R.total(_inputs(plan_ok=False, qn=np.array([9.0, 0.0])), cfg)[1]["feasibility"] == 0.0


def test_change_term_gated_by_previous_plan() -> None:
    """Change is −0.15·(‖ΔQ_s‖+‖ΔQ_l‖) only when the previous plan succeeded."""
    cfg = RewardConfig()
    inp = _inputs(prev_q_s=np.array([1.0, 1.0]), prev_q_l=np.array([4.0, 2.0]))
    assert R.total(inp, cfg)[1]["change"] == pytest.approx(-0.15 * 3.0)
    assert R.total(_inputs(prev_plan_ok=False, prev_q_s=np.zeros(2)), cfg)[1]["change"] == 0.0
    assert R.total(_inputs(prev_q_s=None, prev_q_l=None), cfg)[1]["change"] == 0.0


def test_step_terms() -> None:
    """Slow penalty scales with 1−‖v‖/3.5355 and velocity change with Σ|Δv|/t_c/2."""
    cfg = RewardConfig()
    inp = _inputs(velocity=np.array([0.0, 0.0]), prev_velocity=np.array([0.2, -0.1]))
    terms = R.total(inp, cfg)[1]
    assert terms["slow"] == pytest.approx(-0.01)
    assert terms["velocity_change"] == pytest.approx(-0.008 * 0.3 / 0.1 / 2)
    assert terms["constant"] == 0.0


@pytest.mark.parametrize(("variant", "absent"), [("r_t1", set()), ("r_t2", {"change"}),
                                                  ("r_t3", {"feasibility"}), ("r_t4", {"change", "feasibility"})])
def test_variants_drop_terms(variant: str, absent: set) -> None:
    """Reward variants drop exactly the ablated terms."""
    _, terms = R.total(_inputs(), RewardConfig(variant=variant))
    assert set(R.TERMS) - set(terms) == absent
