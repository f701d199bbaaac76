"""Fuzz the convex region and the MPC with random inputs and count invariant violations.

    python scripts/fuzz.py [scans=100000] [problems=100000] [seed=0] [solver=daqp] [figure=docs/media/fuzz.png]

Region (``compute_region`` on random scans: uniform noise, smooth random rooms, ray-cast random
circles and segments, near-touching and empty scans): where it returns a polygon (found or
recovered) the polygon must be convex and clockwise, hold the origin strictly inside, and hold
no scan point shrunk by the inflation it used strictly inside (tolerance: the 1 µm ``push`` the
algorithm adds to every half-plane, plus 1e-9 m). A failure
without a polygon is counted by status, not as a violation.

MPC (``Mpc.solve`` on random problems: a random region as above, random velocity and
acceleration within the limits, random references inside and outside it): a solved plan must
satisfy every constraint (jerk, velocity, acceleration, polygon) and the triple-integrator
dynamics to 1e-6; otherwise the result must be a counted fallback, whose jerks still respect
``j_max``. Any exception is an error. Prints a JSON report, saves a histogram of the worst
violation margins, exits 1 on any violation or exception.
"""

from __future__ import annotations

import dataclasses
import json
import math
import sys
import time
from collections import Counter
from pathlib import Path
from typing import Any

import numpy as np

from mjnav.control.mpc import Mpc, MpcConfig, simulate_triple_integrator
from mjnav.geometry.polygon import halfplanes, is_convex, signed_area
from mjnav.geometry.raycast import beam_angles, cast_rays
from mjnav.geometry.region import Region, RegionConfig, compute_region
from mjnav.args import Parsed
from mjnav.cli import run_script

TOL_REGION = RegionConfig().push + 1e-9  # m: GALAXY pushes each half-plane out by ``push`` (1 µm) on purpose
TOL_MPC = 1e-6  # SI
ANGLES = beam_angles(360)
CFG = RegionConfig()


def random_scan(rng: np.random.Generator) -> np.ndarray:
    """One random 360-beam scan, metres, from one of five families."""
    kind = rng.integers(5)
    if kind == 0:  # uniform noise, anywhere in [0, max_range]
        return rng.uniform(0.0, CFG.max_range, 360)
    if kind == 1:  # smooth random room: a few harmonics around a mean radius
        k = np.arange(1, 6)[:, None]
        r = rng.uniform(0.5, 6.0) + (rng.normal(0, 0.4, (5, 1)) * np.cos(k * ANGLES + rng.uniform(0, 6.3, (5, 1)))).sum(0)
        return np.clip(r, 0.0, CFG.max_range)
    if kind == 2:  # ray-cast random circles and segments around the origin
        circles = np.column_stack([rng.uniform(-5, 5, (12, 2)), rng.uniform(0.1, 0.8, 12)])
        circles = circles[np.hypot(circles[:, 0], circles[:, 1]) > circles[:, 2] + 0.05]
        segs = rng.uniform(-6, 6, (6, 4))
        return cast_rays(np.zeros(2), ANGLES, segs, circles, CFG.max_range) + rng.normal(0, 0.02, 360)
    if kind == 3:  # something within or near the inflation: touching, recovering, escaping
        r = rng.uniform(1.0, CFG.max_range, 360)
        centre, width = rng.integers(360), rng.integers(1, 40)
        r[(np.arange(centre, centre + width)) % 360] = rng.uniform(0.0, 0.45)
        return r
    return np.full(360, rng.choice([CFG.max_range, 0.0, rng.uniform(0.0, 0.5)]))  # empty, blind or boxed in


def region_violations(ranges: np.ndarray, region: Region) -> dict[str, float]:
    """Margins by which a polygon breaks an invariant (> 0 is a violation); {} without a polygon."""
    if not region.has_polygon:
        return {}
    v = region.vertices
    shrunk = np.maximum(np.minimum(ranges, CFG.max_range) - region.inflation, 0.0)
    points = np.column_stack([shrunk * np.cos(ANGLES), shrunk * np.sin(ANGLES)])
    inside_depth = np.min(region.offsets[None, :] - points @ region.normals.T, axis=1)  # > 0: strictly inside
    return {
        "convex_clockwise": -1.0 if is_convex(v, 1e-12) and signed_area(v) < 0 else 1.0,
        "origin_inside": -float(np.min(region.offsets)),
        "shrunk_point_inside": float(np.max(inside_depth)) - TOL_REGION,
    }


def mpc_problem(rng: np.random.Generator, mpc_cfg: MpcConfig) -> tuple[np.ndarray, ...] | None:
    """(state, q_s, q_l, polygon) of a random problem, or None when the scan gave no polygon."""
    region = compute_region(random_scan(rng), ANGLES, CFG)
    if not region.has_polygon:
        return None
    state = np.zeros((3, 2))
    state[1] = rng.uniform(-mpc_cfg.v_max, mpc_cfg.v_max, 2) * rng.choice([0.0, 0.3, 1.0])
    state[2] = rng.uniform(-mpc_cfg.a_max, mpc_cfg.a_max, 2) * rng.choice([0.0, 0.3, 1.0])
    q_s, q_l = rng.uniform(-3, 3, 2), rng.uniform(-8, 8, 2)
    return state, q_s, q_l, region.vertices


def mpc_violations(mpc: Mpc, state: np.ndarray, polygon: np.ndarray, result: Any) -> dict[str, float]:
    """Margins by which a solved plan breaks a constraint or the dynamics (> 0 is a violation)."""
    c = mpc.config
    out = {"jerk": float(np.max(np.abs(result.jerks))) - c.j_max - TOL_MPC}
    if result.fallback is not None:
        return out  # fallbacks are counted; only the actuator bound must hold
    x = state.copy()
    err = 0.0
    for k in range(c.horizon):
        x = simulate_triple_integrator(x, result.jerks[k], c.t_c)
        err = max(err, float(np.max(np.abs(x - np.vstack([result.positions[k], result.velocities[k],
                                                          result.accelerations[k]])))))
    normals, offsets = halfplanes(polygon)
    out.update({
        "velocity": float(np.max(np.abs(result.velocities))) - c.v_max - TOL_MPC,
        "acceleration": float(np.max(np.abs(result.accelerations))) - c.a_max - TOL_MPC,
        "polygon": float(np.max(result.positions @ normals.T - offsets)) - TOL_MPC,
        "dynamics": err - TOL_MPC,
    })
    return out


def run(scans: int, problems: int, seed: int = 0, solver: str = "daqp") -> dict[str, Any]:
    """Fuzz both parts; returns the report (counts, worst margins, timings)."""
    rng = np.random.default_rng(seed)
    report: dict[str, Any] = {"seed": seed, "region": {}, "mpc": {}}
    worst: dict[str, list[float]] = {"region": [], "mpc": []}
    status, violations, errors, t0 = Counter(), Counter(), [], time.perf_counter()
    for i in range(scans):
        ranges = random_scan(rng)
        try:
            region = compute_region(ranges, ANGLES, CFG)
        except Exception as err:  # counted and reported, never hidden
            errors.append(f"scan {i}: {type(err).__name__}: {err}")
            continue
        status["recovered" if region.recovered else region.status] += 1
        margins = region_violations(ranges, region)
        violations.update(k for k, m in margins.items() if m > 0)
        if margins:
            worst["region"].append(max(margins.values()))
    report["region"] = {"scans": scans, "status": dict(status), "violations": dict(violations),
                        "exceptions": errors[:20], "exception_count": len(errors),
                        "seconds": round(time.perf_counter() - t0, 1)}
    mpc_cfg = MpcConfig(solver=solver)
    mpc, fallbacks, violations, errors, solved, t0 = Mpc(mpc_cfg), Counter(), Counter(), [], 0, time.perf_counter()
    while solved < problems:
        problem = mpc_problem(rng, mpc_cfg)
        if problem is None:
            continue
        state, q_s, q_l, polygon = problem
        solved += 1
        try:
            result = mpc.solve(state, q_s, q_l, polygon)
        except Exception as err:
            errors.append(f"problem {solved}: {type(err).__name__}: {err}")
            continue
        fallbacks[result.fallback or "solved"] += 1
        margins = mpc_violations(mpc, state, polygon, result)
        violations.update(k for k, m in margins.items() if m > 0)
        worst["mpc"].append(max(margins.values()))
    report["mpc"] = {"problems": problems, "solver": solver, "outcomes": dict(fallbacks),
                     "violations": dict(violations), "exceptions": errors[:20], "exception_count": len(errors),
                     "seconds": round(time.perf_counter() - t0, 1)}
    report["worst"] = {k: (max(v) if v else None) for k, v in worst.items()}
    report["_margins"] = worst
    return report


def figure(report: dict[str, Any], path: Path) -> None:
    """Histograms of each case's worst margin (< 0: the invariant holds with that much room)."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, axes = plt.subplots(1, 2, figsize=(10, 3.6))
    for ax, key, title in zip(axes, ("region", "mpc"), ("region: worst invariant margin", "MPC: worst constraint margin")):
        values = np.asarray(report["_margins"][key])
        if values.size:
            ax.hist(np.clip(values, -5, 1), bins=80, color="tab:blue")
        ax.axvline(0.0, color="tab:red", lw=1)
        ax.set_yscale("log")
        ax.set_title(f"{title}\n(n={values.size}, > 0 would be a violation)", fontsize=9)
        ax.set_xlabel("margin (m or SI units)")
    fig.tight_layout()
    path.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(path, dpi=110)
    plt.close(fig)


@dataclasses.dataclass(frozen=True)
class FuzzOptions:
    """The keys of ``scripts/fuzz.py``.

    Attributes:
        scans: Random scans given to the convex region.
        problems: Random problems given to the MPC.
        seed: Seed of the random inputs.
        solver: MPC QP solver (``daqp``, ``osqp`` or ``quadprog``).
        figure: Histogram of the worst violation margins (empty: none).
    """

    scans: int = 100_000
    problems: int = 100_000
    seed: int = 0
    solver: str = "daqp"
    figure: str = "docs/media/fuzz.png"


def main(argv: list[str]) -> int:
    """Parse ``key=value`` arguments (``--help``: the keys), fuzz, print the report; 1 on any violation."""
    return run_script(argv, "scripts/fuzz.py", "Fuzz the convex region and the MPC; count invariant violations.",
                      FuzzOptions, _main)


def _main(parsed: Parsed) -> int:
    opts: FuzzOptions = parsed.options
    report = run(opts.scans, opts.problems, opts.seed, opts.solver)
    if opts.figure:
        figure(report, Path(opts.figure))
    report.pop("_margins")
    print(json.dumps(report, indent=1))
    bad = sum(report[k]["exception_count"] + sum(report[k]["violations"].values()) for k in ("region", "mpc"))
    return 1 if bad or math.isnan(bad) else 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
