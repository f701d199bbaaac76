"""Tests for the ORCA pedestrians (mjnav.world.orca)."""

from __future__ import annotations

import dataclasses
import math

import numpy as np
import pytest

from mjnav.world.orca import (
    OrcaConfig,
    OrcaModel,
    OrcaObstacles,
    orca_obstacles,
    orca_velocities,
)
from tests.world import _orca_reference as ref

DT = 0.02
HALF = 5.0
BOUNDS = (-HALF, -HALF, HALF, HALF)
SQUARE = np.array([[1.0, -1.0], [3.0, -1.0], [3.0, 1.0], [1.0, 1.0]])
CELL_CENTRES = [(-1.76, -1.76), (1.76, 1.76), (1.76, -1.76), (-1.76, 1.76)]


# ---------------------------------------------------------------------------- helpers


def _walk(
    pos: np.ndarray, goals: np.ndarray, radii: np.ndarray, speeds: np.ndarray, obstacles: OrcaObstacles,
    steps: int, config: OrcaConfig = OrcaConfig(), perturb: float = 0.0,
) -> np.ndarray:  # fmt: skip
    """Drives discs to fixed goals with the ORCA core (no guard); returns positions (steps, N, 2).

    ``perturb`` (m/s) adds a seeded random vector of that length to every preferred velocity each
    step, as RVO2's examples do to break symmetric deadlocks.
    """
    rng = np.random.default_rng(0)
    pos, vel = pos.astype(float).copy(), np.zeros_like(pos, dtype=float)
    track = np.empty((steps, *pos.shape))
    for k in range(steps):
        delta = goals - pos
        dist = np.linalg.norm(delta, axis=1, keepdims=True)
        pref = delta * np.minimum(1.0, speeds[:, None] / np.maximum(dist, 1e-12))
        if perturb:
            angle = rng.uniform(0.0, 2.0 * np.pi, len(pos))
            pref += perturb * np.stack([np.cos(angle), np.sin(angle)], axis=1)
        vel = orca_velocities(pos, vel, radii, pref, speeds, obstacles, config, DT)
        pos = pos + vel * DT
        track[k] = pos
    return track


def _pair_gaps(track: np.ndarray, radii: np.ndarray) -> np.ndarray:
    """Surface gaps of all distinct pairs at every step, metres."""
    i, j = np.triu_indices(len(radii), k=1)
    return np.linalg.norm(track[:, i] - track[:, j], axis=-1) - radii[i] - radii[j]


def _signed_distance(points: np.ndarray, poly: np.ndarray) -> np.ndarray:
    """Signed distance (negative inside) from points (..., 2) to a CCW convex polygon, metres."""
    a, b = poly, np.roll(poly, -1, axis=0)
    rel, edge = points[..., None, :] - a, b - a
    t = np.clip(np.sum(rel * edge, axis=-1) / np.sum(edge * edge, axis=-1), 0.0, 1.0)
    dist = np.linalg.norm(rel - t[..., None] * edge, axis=-1).min(axis=-1)
    inside = np.all(edge[:, 0] * rel[..., 1] - edge[:, 1] * rel[..., 0] >= 0.0, axis=-1)
    return np.where(inside, -dist, dist)


def _polygon(centre: tuple[float, float], sides: int, rng: np.random.Generator) -> np.ndarray:
    angles = np.sort(rng.uniform(0.0, 2.0 * np.pi, sides))
    return np.asarray(centre) + 0.6 * np.stack([np.cos(angles), np.sin(angles)], axis=1)


def _scene(seed: int, count: int = 30, obstacles: bool = True) -> dict:
    """Stage-7-like scene (as tests/world/test_crowd.py): 30 discs on a grid, 4 polygons."""
    rng = np.random.default_rng(seed)
    grid = np.linspace(-HALF + 0.6, HALF - 0.6, 6)
    positions = np.array([(x, y) for x in grid for y in grid])[:count]
    polys = [_polygon(c, 3 + k % 2, rng) for k, c in enumerate(CELL_CENTRES)] if obstacles else []
    return {
        "positions": positions,
        "radii": rng.uniform(0.1, 0.4, count),
        "speeds": rng.uniform(0.3, 0.6, count),
        "headings": rng.uniform(-np.pi, np.pi, count),
        "bounds": BOUNDS,
        "obstacles": polys,
    }


def _run(model: OrcaModel, scene: dict, seed: int, steps: int, robot: np.ndarray | None = None) -> np.ndarray:
    """Resets and steps ``model``; returns positions (steps, P, 2)."""
    model.reset(**scene, rng=np.random.default_rng(seed))
    track = np.empty((steps, len(scene["radii"]), 2))
    for k in range(steps):
        model.step(DT, robot)
        track[k] = model.positions
    return track


# ---------------------------------------------------------------------------- the core


def test_head_on_swap_without_contact() -> None:
    """Two discs walking at each other pass without touching and reach their goals.

    Their paths are 2 cm apart: with exactly collinear paths and zero initial velocities ORCA only
    slows both down (a symmetric deadlock, as in RVO2, whose examples perturb preferred velocities).
    """
    pos, radii, speeds = np.array([[-2.0, 0.0], [2.0, 0.02]]), np.array([0.3, 0.25]), np.array([0.5, 0.5])
    goals = pos[::-1].copy()
    track = _walk(pos, goals, radii, speeds, orca_obstacles(), steps=1000)
    assert _pair_gaps(track, radii).min() > 0.0
    np.testing.assert_allclose(track[-1], goals, atol=1e-3)


def _circle(count: int) -> np.ndarray:
    """(count, 2) points evenly on a circle of radius 4 m."""
    angles = 2 * np.pi * np.arange(count) / count
    return 4.0 * np.stack([np.cos(angles), np.sin(angles)], axis=1)


@pytest.mark.parametrize(("count", "perturb"), [(12, 0.0), (12, 0.05), (16, 0.05), (20, 0.05)])
def test_circle_swap_never_touches(count: int, perturb: float) -> None:
    """Discs on a circle swap to their antipodes; no pair is ever closer than its radii sum.

    Exactly symmetric (no perturbation) they jam around the centre and wait, touching only
    through the safety margins; with RVO2-style perturbations of 5 cm/s, 12 and 16 discs arrive,
    20 still jam at a 5 s time horizon (as RVO2 itself does: measured with pyrvo 0.4.3).
    """
    pos, radii, speeds = _circle(count), np.full(count, 0.3), np.full(count, 0.5)
    track = _walk(pos, -pos, radii, speeds, orca_obstacles(bounds=BOUNDS), steps=3000, perturb=perturb)
    assert _pair_gaps(track, radii).min() > 0.0
    arrived = np.linalg.norm(track[-1] + pos, axis=1).max() < 0.05
    assert arrived == (perturb > 0.0 and count <= 16)


def test_matches_rvo2_over_a_circle_swap() -> None:
    """Where the RVO2 binding pyrvo is installed, 500 steps of a 12-disc circle swap agree with it
    to float32 precision (RVO2 computes in float32)."""
    pyrvo = pytest.importorskip("pyrvo")
    pos, count = _circle(12), 12
    ours = _walk(pos, -pos, np.full(count, 0.3), np.full(count, 0.5), orca_obstacles(), steps=500)
    sim = pyrvo.RVOSimulator()
    sim.set_time_step(DT)
    for p in pos:
        sim.add_agent(tuple(p), 10.0, 10, 5.0, 5.0, 0.31, 0.5, (0.0, 0.0))
    for _ in range(500):
        now = np.array([sim.get_agent_position(a).to_tuple() for a in range(count)])
        delta = -pos - now
        pref = delta * np.minimum(1.0, 0.5 / np.maximum(np.linalg.norm(delta, axis=1, keepdims=True), 1e-12))
        for a in range(count):
            sim.set_agent_pref_velocity(a, tuple(pref[a]))
        sim.do_step()
    theirs = np.array([sim.get_agent_position(a).to_tuple() for a in range(count)])
    np.testing.assert_allclose(ours[-1], theirs, atol=1e-3)


def test_discs_driven_at_walls_and_obstacles_never_enter() -> None:
    """Discs whose goals lie inside a wall or an obstacle stop at its surface, never inside."""
    pos = np.array([[-1.0, 0.0], [-1.0, 3.0], [0.0, -3.0], [-3.0, -3.0]])
    goals = np.array([[2.0, 0.0], [-9.0, 3.0], [0.0, -9.0], [-9.0, -9.0]])  # square centre, walls, corner
    radii, speeds = np.array([0.3, 0.2, 0.4, 0.25]), np.array([0.6, 0.6, 0.6, 0.6])
    obstacles = orca_obstacles([SQUARE], bounds=BOUNDS)
    track = _walk(pos, goals, radii, speeds, obstacles, steps=1500)
    assert np.all(_signed_distance(track, SQUARE) >= radii - 1e-9)
    assert np.all(np.abs(track) <= HALF - radii[:, None] + 1e-9)
    final_gap = np.array([_signed_distance(track[-1, 0], SQUARE) - 0.3, track[-1, 1, 0] + HALF - 0.2])
    assert np.all(final_gap < 0.05)  # they did get close: ORCA slowed them, it did not stop them early


def test_segment_blocks_both_sides() -> None:
    """A two-vertex obstacle (segment) is not crossed from either side."""
    obstacles = orca_obstacles(segments=np.array([[0.0, -2.0, 0.0, 2.0]]))
    pos, goals = np.array([[-1.0, 0.0], [1.0, 0.5]]), np.array([[1.0, 0.0], [-1.0, 0.5]])
    track = _walk(pos, goals, np.array([0.2, 0.2]), np.array([0.5, 0.5]), obstacles, steps=1000)
    assert np.all(track[:, 0, 0] <= -0.2 + 1e-9) and np.all(track[:, 1, 0] >= 0.2 - 1e-9)


def _random_case(rng: np.random.Generator, dense: bool) -> dict:
    """Random agents around the square, a triangle and a segment inside walls; a robot 2 in 3 times."""
    n = int(rng.integers(2, 12))
    span = 1.5 if dense else 4.0
    triangle = np.array([[1.0, 1.0], [2.5, 1.2], [1.8, 2.4]]) + rng.normal(0.0, 0.1, (3, 2))
    return {
        "positions": rng.uniform(-span, span, (n, 2)),
        "velocities": rng.normal(0.0, 0.6, (n, 2)),
        "radii": rng.uniform(0.1, 0.4, n),
        "preferred": rng.normal(0.0, 0.6, (n, 2)),
        "max_speeds": rng.uniform(0.3, 1.0, n),
        "obstacles": orca_obstacles([triangle, SQUARE - 5.0], bounds=BOUNDS,
                                    segments=np.array([[0.0, -4.0, 3.0, -3.5]])),  # fmt: skip
        "config": OrcaConfig(
            neighbor_dist=float(rng.uniform(1.0, 10.0)), max_neighbors=int(rng.integers(1, 8)),
            time_horizon=float(rng.uniform(0.5, 5.0)), time_horizon_obst=float(rng.uniform(0.5, 5.0)),
            robot_as=("agent", "obstacle")[int(rng.integers(2))],
        ),  # fmt: skip
        "dt": DT,
        "robot": (rng.uniform(-2.0, 2.0, 2), rng.normal(0.0, 1.0, 2), 0.225) if rng.uniform() < 2 / 3 else None,
    }


def _reference(case: dict) -> np.ndarray:
    c, m = case["config"], case["config"].safety_margin
    robot = None if case["robot"] is None else (case["robot"][0], case["robot"][1], case["robot"][2] + m)
    return ref.orca(case["positions"], case["velocities"], case["radii"] + m, case["preferred"],
                    case["max_speeds"], case["obstacles"], c.neighbor_dist, c.max_neighbors, c.time_horizon,
                    c.time_horizon_obst, case["dt"], robot, c.robot_responsibility)  # fmt: skip


def test_kernel_matches_plain_python_half_planes_and_linear_programs(monkeypatch: pytest.MonkeyPatch) -> None:
    """On random cases the numba kernel equals a plain-Python ORCA (same half-planes, LP 1-3).

    Dense cases overlap and make the agent half-planes infeasible, so linear program 3 runs too.
    """
    calls = {"lp3": 0}
    original = ref.lp3

    def counted(*args: object) -> np.ndarray:
        calls["lp3"] += 1
        return original(*args)

    monkeypatch.setattr(ref, "lp3", counted)
    rng = np.random.default_rng(1)
    for k in range(40):
        case = _random_case(rng, dense=bool(k % 2))
        np.testing.assert_allclose(orca_velocities(**case), _reference(case), rtol=0.0, atol=1e-10)
    assert calls["lp3"] > 10


def test_feasible_result_is_the_closest_admissible_velocity() -> None:
    """Where linear program 2 succeeds, its velocity meets every half-plane and the speed limit, and
    no admissible velocity is closer to the preferred one (checked with scipy's SLSQP)."""
    optimize = pytest.importorskip("scipy.optimize")
    rng = np.random.default_rng(3)
    checked = 0
    for _ in range(15):
        case = _random_case(rng, dense=False)
        got = orca_velocities(**case)
        c, m = case["config"], case["config"].safety_margin
        robot = None if case["robot"] is None else (case["robot"][0], case["robot"][1], case["robot"][2] + m)
        for i in range(len(got)):
            lines, _ = ref.agent_lines(
                i, case["positions"], case["velocities"], case["radii"] + m, case["max_speeds"], case["obstacles"],
                c.neighbor_dist, c.max_neighbors, c.time_horizon, c.time_horizon_obst, DT, robot,
                c.robot_responsibility,
            )  # fmt: skip
            pref, vmax = case["preferred"][i], case["max_speeds"][i]
            if ref.lp2(lines, vmax, pref, False)[0] < len(lines):
                continue  # infeasible: linear program 3's compromise, compared above
            slack = [ref.det(d, p - got[i]) for p, d in lines]
            assert max(slack, default=-1.0) <= 1e-9 and np.linalg.norm(got[i]) <= vmax + 1e-9
            cons = [{"type": "ineq", "fun": lambda v, p=p, d=d: -ref.det(d, p - v)} for p, d in lines]
            cons.append({"type": "ineq", "fun": lambda v: vmax * vmax - v @ v})
            best = optimize.minimize(lambda v: np.sum((v - pref) ** 2), got[i] * 0.5, constraints=cons,
                                     method="SLSQP", options={"ftol": 1e-12, "maxiter": 500})  # fmt: skip
            if best.success and all(con["fun"](best.x) >= -1e-9 for con in cons):
                assert np.sum((got[i] - pref) ** 2) <= best.fun + 1e-7
                checked += 1
    assert checked > 30


def test_core_rejects_bad_inputs() -> None:
    """Wrong shapes, NaN, non-positive radii or dt raise ValueError."""
    good = {"positions": np.zeros((2, 2)) + [[0.0, 0.0], [1.0, 0.0]], "velocities": np.zeros((2, 2)),
            "radii": np.array([0.2, 0.2]), "preferred": np.zeros((2, 2)), "max_speeds": np.array([0.5, 0.5]),
            "obstacles": orca_obstacles(), "config": OrcaConfig(), "dt": DT}  # fmt: skip
    orca_velocities(**good)
    bad = [{"positions": np.zeros((2, 3))}, {"velocities": np.full((2, 2), np.nan)}, {"radii": np.array([0.0, 0.2])},
           {"max_speeds": np.array([-1.0, 0.5])}, {"dt": 0.0}, {"robot": (np.zeros(2), np.zeros(2), -0.1)},
           {"robot": (np.array([np.nan, 0.0]), np.zeros(2), 0.2)}]  # fmt: skip
    for change in bad:
        with pytest.raises(ValueError):
            orca_velocities(**{**good, **change})


def test_obstacle_packing() -> None:
    """Walls are one clockwise loop of concave corners; polygons are CCW and convex; segments link both ways."""
    obs = orca_obstacles([SQUARE[::-1], np.vstack([SQUARE[:1], SQUARE])], bounds=BOUNDS,
                         segments=np.array([[0.0, 0.0, 1.0, 0.0]]))  # fmt: skip
    assert len(obs.point) == 4 + 4 + 4 + 2  # the repeated vertex of the second square is dropped
    assert not obs.convex[:4].any() and obs.convex[4:].all()
    np.testing.assert_array_equal(obs.next[obs.prev], np.arange(len(obs.point)))
    np.testing.assert_array_equal(obs.next[12:], [13, 12])
    np.testing.assert_allclose(np.linalg.norm(obs.direction, axis=1), 1.0)
    edge = obs.point[obs.next[4:8]] - obs.point[4:8]
    assert np.all(edge[:, 0] * np.roll(edge[:, 1], -1) - edge[:, 1] * np.roll(edge[:, 0], -1) > 0)  # CCW
    for bad in ({"bounds": (0.0, 0.0, -1.0, 1.0)}, {"segments": np.zeros((1, 4))}, {"segments": np.zeros(4)},
                {"polygons": [np.zeros((2, 2))]}):  # fmt: skip
        with pytest.raises(ValueError):
            orca_obstacles(**bad)


# ---------------------------------------------------------------------------- the model


@pytest.fixture(scope="module")
def long_run() -> tuple[dict, np.ndarray, OrcaModel]:
    """30 pedestrians, 10 x 10 m, 4 obstacles, 3000 steps (60 s), non-reactive."""
    scene, model = _scene(seed=0), OrcaModel()
    return scene, _run(model, scene, seed=0, steps=3000, robot=np.zeros(2)), model


def test_long_run_no_contact_no_penetration(long_run: tuple) -> None:
    """No two pedestrians ever overlap, none crosses a wall or enters an obstacle, and the last
    guard never had to correct anyone: ORCA alone kept them apart and out."""
    scene, track, model = long_run
    r = scene["radii"]
    assert np.all(np.isfinite(track))
    assert _pair_gaps(track, r).min() >= 0.0 and model.overlaps == 0
    assert np.all(np.abs(track) <= HALF - r[:, None] + 1e-12)
    for poly in scene["obstacles"]:
        assert np.all(_signed_distance(track, poly) >= r - 1e-9)
    assert model.guard_corrections == 0


def test_pedestrians_walk_within_their_speed(long_run: tuple) -> None:
    """Steps never exceed the preferred speed (max_speed_factor 1) and the crowd keeps moving."""
    scene, track, _ = long_run
    speed = np.linalg.norm(np.diff(track, axis=0), axis=-1) / DT
    assert np.all(speed <= scene["speeds"] + 1e-9)
    assert np.median(speed) > 0.5 * 0.3


def test_guard_counts_and_repairs_a_disc_started_in_an_obstacle() -> None:
    """A disc that starts overlapping an obstacle is pushed out by the guard, which counts it."""
    model = OrcaModel()
    model.reset(np.array([[0.85, 0.0]]), np.array([0.3]), np.array([0.5]), np.array([0.0]), BOUNDS, [SQUARE],
                np.random.default_rng(0))  # fmt: skip
    model.step(DT)
    assert model.guard_corrections >= 1
    assert _signed_distance(model.positions, SQUARE)[0] >= 0.3 - 1e-12


def test_same_seed_same_trajectory() -> None:
    """The same inputs and seed give bit-identical trajectories; another seed differs."""
    scene = _scene(seed=5)
    first = _run(OrcaModel(), scene, seed=7, steps=300)
    again = _run(OrcaModel(), scene, seed=7, steps=300)
    other = _run(OrcaModel(), scene, seed=8, steps=300)
    np.testing.assert_array_equal(first, again)
    assert not np.array_equal(first, other)


@pytest.mark.parametrize("reactive", [False, True])
def test_advance_equals_single_steps(reactive: bool) -> None:
    """advance(dt, n) equals n single steps, with the robot moving along a line."""
    scene = _scene(seed=5)
    robot = np.stack([np.linspace(-3.0, 3.0, 100), np.zeros(100)], axis=1)
    config = OrcaConfig(reactive=reactive)
    single = OrcaModel(config)
    single.reset(**scene, rng=np.random.default_rng(7))
    expected = []
    for k in range(100):
        single.step(DT, robot[k])
        expected.append(single.positions)
    model = OrcaModel(config)
    model.reset(**scene, rng=np.random.default_rng(7))
    tracks = [model.advance(DT, 5, robot_positions=robot[5 * p : 5 * p + 5]) for p in range(20)]
    np.testing.assert_array_equal(np.concatenate(tracks), np.array(expected))


def test_non_reactive_ignores_robot_and_reactive_avoids_it() -> None:
    """The default crowd walks through a parked robot as if absent; a reactive one keeps clear of it."""
    scene, robot = _scene(seed=2, obstacles=False), np.array([0.3, -0.2])
    without = _run(OrcaModel(), scene, seed=2, steps=1500)
    ignored = _run(OrcaModel(), scene, seed=2, steps=1500, robot=robot)
    np.testing.assert_array_equal(ignored, without)
    assert not OrcaModel().reacts_to_robot and OrcaModel(OrcaConfig(reactive=True)).reacts_to_robot
    gap = lambda track: (np.linalg.norm(track - robot, axis=-1) - scene["radii"] - 0.225).min()  # noqa: E731
    for robot_as in ("agent", "obstacle"):
        avoided = _run(OrcaModel(OrcaConfig(reactive=True, robot_as=robot_as)), scene, seed=2, steps=1500, robot=robot)
        assert gap(avoided) > 0.0
    assert gap(ignored) < 0.0


def test_reactive_crowd_keeps_clear_of_a_robot_driving_through_it() -> None:
    """A robot crossing the stage-7-like scene at 0.5 m/s runs into non-reactive pedestrians, while
    reactive ones (robot as agent or as obstacle) never touch it nor each other."""
    robot = np.stack([np.linspace(-4.0, 4.0, 800), np.full(800, 0.1)], axis=1)  # 8 m in 16 s
    scene = _scene(seed=0)
    for config in (OrcaConfig(), OrcaConfig(reactive=True), OrcaConfig(reactive=True, robot_as="obstacle")):
        model = OrcaModel(config)
        model.reset(**scene, rng=np.random.default_rng(0))
        track = model.advance(DT, 800, robot_positions=robot)
        gap = (np.linalg.norm(track - robot[:, None], axis=-1) - scene["radii"] - 0.225).min()
        assert (gap > 0.0) == config.reactive
        assert model.overlaps == 0 and model.guard_corrections == 0


def test_goals_lie_in_free_space_and_are_reached() -> None:
    """Every pedestrian reaches at least one goal in 60 s; goals keep clear of walls and obstacles."""
    scene, tol = _scene(seed=3, count=10), OrcaConfig().goal_tolerance
    model = OrcaModel()
    model.reset(**scene, rng=np.random.default_rng(3))
    reached, goals = np.zeros(10, dtype=bool), [model.goals]
    for _ in range(3000):
        previous = model.goals
        model.step(DT)
        changed = np.any(model.goals != previous, axis=1)
        reached |= changed & (np.linalg.norm(model.positions - previous, axis=1) < tol)
        goals.append(model.goals[changed])
    assert reached.all()
    goals = np.concatenate(goals)
    assert np.all(np.abs(goals) <= HALF - 0.1)
    assert all(np.all(_signed_distance(goals, poly) >= 0.1) for poly in scene["obstacles"])


def test_empty_crowd_and_registry_shape() -> None:
    """Zero pedestrians step; the class is a registry factory taking its config dataclass."""
    model = OrcaModel.config_class and OrcaModel(OrcaModel.config_class())
    model.reset(np.zeros((0, 2)), np.zeros(0), np.zeros(0), np.zeros(0), BOUNDS, [], np.random.default_rng(0))
    model.step(DT, np.zeros(2))
    assert model.positions.shape == (0, 2) and model.velocities.shape == (0, 2)

    @dataclasses.dataclass(frozen=True)
    class Crowd:
        reactive: bool | None = True
        orca: OrcaConfig = OrcaConfig(time_horizon=2.0)

    assert OrcaModel.from_config(Crowd()).reacts_to_robot
    assert OrcaModel.from_config(Crowd()).config.time_horizon == 2.0
    assert not OrcaModel.from_config(Crowd(reactive=None)).reacts_to_robot
    assert not OrcaModel.from_config(object()).reacts_to_robot
    assert OrcaModel.from_config(object(), OrcaConfig(reactive=True)).reacts_to_robot


def test_bad_step_inputs_raise() -> None:
    """Stepping before reset, a bad dt, or a NaN robot for a reactive crowd raise."""
    model = OrcaModel(OrcaConfig(reactive=True))
    with pytest.raises(RuntimeError):
        model.step(DT)
    model.reset(**_scene(seed=0, count=2), rng=np.random.default_rng(0))
    for dt in (0.0, -DT, math.nan):
        with pytest.raises(ValueError):
            model.step(dt)
    with pytest.raises(ValueError, match="robot"):
        model.step(DT, np.array([np.nan, 0.0]))
    with pytest.raises(ValueError, match="robot"):
        model.advance(DT, 2, robot_positions=np.zeros((3, 2)))
    with pytest.raises(ValueError, match="robot"):
        model.step(DT, np.zeros(2), robot_radius=0.0)
    model.step(DT, np.array([0.0, 0.0, 0.7]))  # (x, y, yaw): extra columns are ignored
    with pytest.raises(TypeError):
        OrcaModel({"time_horizon": 5.0})  # type: ignore[arg-type]


def test_benchmark_runs_on_stage7_layouts() -> None:
    """The benchmark drives every model on real stage-7 layouts; ORCA crowds there have no contact."""
    from mjnav.bench import crowd as bench_crowd  # noqa: PLC0415  (loads the task configs)

    costs = bench_crowd.crowd_step_cost(episodes=1, periods=2)
    assert [c.model for c in costs] == list(bench_crowd.MODELS)
    assert all(c.us_per_control_step > 0 and c.cpu_us_per_control_step >= 0 for c in costs)
    contacts = bench_crowd.orca_contacts(episodes=2)
    assert contacts["steps"] == 2 * 300 * 5 and contacts["overlapping_pair_steps"] == 0


BAD_CONFIGS = {
    "neighbor_dist": 0.0,
    "max_neighbors": -1,
    "time_horizon": -1.0,
    "time_horizon_obst": math.inf,
    "safety_margin": -0.01,
    "max_speed_factor": 0.5,
    "goal_tolerance": math.nan,
    "reactive": "yes",
    "robot_as": "ghost",
}


@pytest.mark.parametrize("field", list(BAD_CONFIGS))
def test_bad_config_raises_naming_the_field(field: str) -> None:
    """Each out-of-range parameter raises ValueError naming it."""
    with pytest.raises(ValueError, match=f"orca.{field}"):
        OrcaConfig(**{field: BAD_CONFIGS[field]})
    with pytest.raises(ValueError, match="max_neighbors"):
        OrcaConfig(max_neighbors=2.5)  # type: ignore[arg-type]
