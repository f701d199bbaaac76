"""Tests for the pedestrian motion models (mjnav.world.crowd, mjnav.world.social_force)."""

from __future__ import annotations

import math

import numpy as np
import pytest

from mjnav.schema import CrowdConfig
from mjnav.world import make_pedestrian_model
from mjnav.world.crowd import PedestrianModel, RandomWalkModel
from mjnav.world.social_force import MAX_SPEED_FACTOR, SocialForceModel

DT = 0.02
HALF = 5.0  # 10 x 10 m arena, as stages 5-7
BOUNDS = (-HALF, -HALF, HALF, HALF)
MODELS = ["random_walk", "social_force"]
SPEED_RANGE = (0.3, 0.6)
CELL_CENTRES = [(-1.76, -1.76), (1.76, 1.76), (1.76, -1.76), (-1.76, 1.76)]


def _polygon(centre: tuple[float, float], sides: int, rng: np.random.Generator) -> np.ndarray:
    angles = np.sort(rng.uniform(0.0, 2.0 * np.pi, sides))
    return np.asarray(centre) + 0.6 * np.stack([np.cos(angles), np.sin(angles)], axis=1)


def _scene(seed: int, count: int = 30, obstacles: bool = True) -> dict:
    """Stage-7-like scene: discs on a 6 x 6 grid (1.76 m apart), polygons between grid points."""
    rng = np.random.default_rng(seed)
    grid = np.linspace(-HALF + 0.6, HALF - 0.6, 6)
    positions = np.array([(x, y) for x in grid for y in grid])[:count]
    polys = [_polygon(c, 3 + k % 2, rng) for k, c in enumerate(CELL_CENTRES)] if obstacles else []
    return {
        "positions": positions,
        "radii": rng.uniform(0.1, 0.4, count),
        "speeds": rng.uniform(*SPEED_RANGE, count),
        "headings": rng.uniform(-np.pi, np.pi, count),
        "bounds": BOUNDS,
        "obstacles": polys,
    }


def _model(name: str, **overrides: object) -> PedestrianModel:
    return make_pedestrian_model(CrowdConfig(count=30, speed=SPEED_RANGE, model=name, **overrides))


def _run(
    model: PedestrianModel, scene: dict, seed: int, steps: int, robot: np.ndarray | None = None
) -> tuple[np.ndarray, np.ndarray]:
    """Resets and steps ``model``; returns positions and velocities, each (steps, P, 2)."""
    model.reset(**scene, rng=np.random.default_rng(seed))
    pos, vel = [], []
    for _ in range(steps):
        model.step(DT, robot)
        pos.append(model.positions)
        vel.append(model.velocities)
    return np.array(pos), np.array(vel)


def _signed_distance(points: np.ndarray, poly: np.ndarray) -> np.ndarray:
    """Signed distance (negative inside) from points (..., 2) to a CCW convex polygon, metres."""
    a, b = poly, np.roll(poly, -1, axis=0)
    rel, edge = points[..., None, :] - a, b - a
    t = np.clip(np.sum(rel * edge, axis=-1) / np.sum(edge * edge, axis=-1), 0.0, 1.0)
    dist = np.linalg.norm(rel - t[..., None] * edge, axis=-1).min(axis=-1)
    inside = np.all(edge[:, 0] * rel[..., 1] - edge[:, 1] * rel[..., 0] >= 0.0, axis=-1)
    return np.where(inside, -dist, dist)


def _pair_gaps(pos: np.ndarray, radii: np.ndarray) -> np.ndarray:
    """Surface gaps of all distinct pairs, (steps, P * (P - 1) / 2), metres."""
    i, j = np.triu_indices(len(radii), k=1)
    return np.linalg.norm(pos[:, i] - pos[:, j], axis=-1) - radii[i] - radii[j]


@pytest.fixture(scope="module", params=MODELS)
def long_run(request: pytest.FixtureRequest) -> tuple[str, dict, np.ndarray, np.ndarray]:
    """30 pedestrians, 10 x 10 m, 4 obstacles, 3000 steps (60 s), robot parked at the origin."""
    scene = _scene(seed=0)
    pos, vel = _run(_model(request.param), scene, seed=0, steps=3000, robot=np.zeros(2))
    return request.param, scene, pos, vel


def test_long_run_never_produces_nan(long_run: tuple) -> None:
    """Positions and velocities stay finite over a long crowded run."""
    _, _, pos, vel = long_run
    assert np.all(np.isfinite(pos)) and np.all(np.isfinite(vel))


def test_discs_never_cross_walls(long_run: tuple) -> None:
    """Every disc stays fully inside the wall interior at every step."""
    _, scene, pos, _ = long_run
    r = scene["radii"][None, :, None]
    assert np.all(pos - r >= -HALF - 1e-12) and np.all(pos + r <= HALF + 1e-12)


def test_discs_stay_out_of_obstacles(long_run: tuple) -> None:
    """No disc overlaps a static obstacle at the end of any step."""
    _, scene, pos, _ = long_run
    for poly in scene["obstacles"]:
        assert np.all(_signed_distance(pos, poly) >= scene["radii"] - 1e-9)


def test_speeds(long_run: tuple) -> None:
    """Random walk keeps each speed exactly; social force stays below 1.3 x the desired speed."""
    name, scene, _, vel = long_run
    speed = np.linalg.norm(vel, axis=-1)
    if name == "random_walk":
        np.testing.assert_allclose(speed, np.broadcast_to(scene["speeds"], speed.shape), rtol=1e-12)
        assert SPEED_RANGE[0] - 1e-12 <= speed.min() and speed.max() <= SPEED_RANGE[1] + 1e-12
    else:
        assert np.all(speed <= MAX_SPEED_FACTOR * scene["speeds"] + 1e-12)
        assert np.median(speed) > 0.5 * SPEED_RANGE[0]  # they do walk


def test_pedestrian_overlap_is_slight(long_run: tuple) -> None:
    """Discs overlap by at most 1 cm after any step.

    Both models separate every overlapping pair each step; only the obstacle and wall
    projections that follow can push one disc back into another, by at most its motion in one
    step (1.3 x 0.6 m/s x 0.02 s ~ 1.6 cm; measured: 0 for random walk, 1.6 mm for social force).
    """
    _, scene, pos, _ = long_run
    assert _pair_gaps(pos, scene["radii"]).min() >= -0.01


def test_social_repulsion_keeps_pedestrians_apart() -> None:
    """With 10 m/s² repulsion, pedestrians are within 1 cm of another in under 1 % of steps.

    The repulsion, not the contact guard, does the work (measured 0.1-0.2 %; 4.5 % with the
    default 2.1 m/s², where the goal drive of a jam outweighs the contact repulsion).
    """
    scene = _scene(seed=0)
    pos, _ = _run(_model("social_force", repulsion_strength=10.0), scene, seed=0, steps=3000)
    gaps = np.linalg.norm(pos[:, :, None] - pos[:, None], axis=-1) - scene["radii"][:, None] - scene["radii"]
    gaps[:, np.arange(30), np.arange(30)] = np.inf
    assert np.mean(gaps.min(axis=-1) < 0.01) < 0.01


def test_random_walk_ignores_robot() -> None:
    """The random walk gives bit-identical trajectories with and without a robot."""
    scene = _scene(seed=1)
    with_robot, _ = _run(_model("random_walk"), scene, seed=1, steps=300, robot=np.array([0.0, 0.0]))
    without, _ = _run(_model("random_walk"), scene, seed=1, steps=300)
    np.testing.assert_array_equal(with_robot, without)


def test_social_force_avoids_robot() -> None:
    """Social-force pedestrians keep farther from a parked robot than when it is ignored."""
    scene, robot = _scene(seed=2, obstacles=False), np.array([0.3, -0.2])
    avoided, _ = _run(_model("social_force", robot_strength=10.0), scene, seed=2, steps=1500, robot=robot)
    ignored, _ = _run(_model("social_force"), scene, seed=2, steps=1500)
    gap = lambda pos: (np.linalg.norm(pos - robot, axis=-1) - scene["radii"] - 0.225).min()  # noqa: E731
    assert gap(ignored) < 0.0 < gap(avoided)


def test_social_force_reaches_goals_in_free_space() -> None:
    """Every pedestrian reaches at least one goal in 60 s; each goal lies in free space."""
    scene, tol = _scene(seed=3, count=10), CrowdConfig().goal_tolerance
    model = _model("social_force")
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


def test_heading_turns_at_most_yaw_rate_times_dt() -> None:
    """Away from contacts the heading changes by at most yaw_rate * dt per step, at held rates."""
    rng = np.random.default_rng(4)
    model = RandomWalkModel(yaw_rate=math.pi / 6, yaw_interval=0.1)
    positions = np.stack([np.linspace(-40.0, 40.0, 5), np.zeros(5)], axis=1)
    model.reset(positions, np.full(5, 0.1), np.full(5, 0.3), rng.uniform(-np.pi, np.pi, 5),
                (-50.0, -50.0, 50.0, 50.0), [], rng)  # fmt: skip
    headings = [model.headings]
    for _ in range(500):  # 10 s at 0.3 m/s: at most 3 m, far from walls and each other
        model.step(DT)
        headings.append(model.headings)
    turn = np.angle(np.exp(1j * np.diff(np.array(headings), axis=0)))
    assert np.abs(turn).max() <= math.pi / 6 * DT + 1e-12
    assert np.abs(turn).max() > 0.5 * math.pi / 6 * DT  # it does turn
    held = turn.reshape(100, 5, 5)  # yaw rate redrawn every 0.1 s = 5 steps
    np.testing.assert_allclose(held, np.broadcast_to(held[:, :1], held.shape), atol=1e-12)


def test_wall_reflection_is_specular() -> None:
    """A disc hitting the +x wall at 45 degrees leaves at 135 degrees with its speed kept."""
    model = RandomWalkModel(yaw_rate=0.0)
    model.reset(np.array([[4.0, 0.0]]), np.array([0.2]), np.array([0.5]), np.array([math.pi / 4]), BOUNDS, [],
                np.random.default_rng(0))  # fmt: skip
    for _ in range(200):
        model.step(DT)
    np.testing.assert_allclose(model.headings, [3 * math.pi / 4], atol=1e-12)
    assert model.positions[0, 0] <= HALF - 0.2


def test_obstacle_reflection_uses_edge_normal() -> None:
    """A disc running head-on into a square's face bounces straight back and never enters it."""
    square = np.array([[1.0, -1.0], [3.0, -1.0], [3.0, 1.0], [1.0, 1.0]])
    model = RandomWalkModel(yaw_rate=0.0)
    model.reset(np.array([[-2.0, 0.0]]), np.array([0.3]), np.array([0.5]), np.array([0.0]), BOUNDS, [square],
                np.random.default_rng(0))  # fmt: skip
    xs = []
    for _ in range(400):
        model.step(DT)
        xs.append(model.positions[0, 0])
    assert max(xs) <= 1.0 - 0.3 + 1e-12
    np.testing.assert_allclose(np.abs(model.headings), [math.pi], atol=1e-12)


def test_head_on_pedestrians_bounce_apart() -> None:
    """Two discs walking head-on reverse along the line of centres after touching."""
    model = RandomWalkModel(yaw_rate=0.0)
    model.reset(np.array([[-1.0, 0.0], [1.0, 0.0]]), np.array([0.2, 0.3]), np.array([0.4, 0.4]),
                np.array([0.0, math.pi]), BOUNDS, [], np.random.default_rng(0))  # fmt: skip
    for _ in range(200):
        model.step(DT)
    np.testing.assert_allclose(model.velocities, [[-0.4, 0.0], [0.4, 0.0]], atol=1e-12)
    assert np.diff(model.positions[:, 0])[0] > 0.5


@pytest.mark.parametrize("name", MODELS)
def test_same_seed_same_trajectory(name: str) -> None:
    """The same inputs and seed give bit-identical trajectories; another seed differs."""
    scene = _scene(seed=5)
    first, _ = _run(_model(name), scene, seed=7, steps=500, robot=np.array([0.5, 0.5]))
    again, _ = _run(_model(name), scene, seed=7, steps=500, robot=np.array([0.5, 0.5]))
    other, _ = _run(_model(name), scene, seed=8, steps=500, robot=np.array([0.5, 0.5]))
    np.testing.assert_array_equal(first, again)
    assert not np.array_equal(first, other)


@pytest.mark.parametrize("name", MODELS)
def test_advance_equals_single_steps(name: str) -> None:
    """advance(dt, n) (one kernel call per period) is bit-identical to n single steps."""
    scene, robot = _scene(seed=5), np.array([0.5, 0.5])
    single, _ = _run(_model(name), scene, seed=7, steps=100, robot=robot)
    model = _model(name)
    model.reset(**scene, rng=np.random.default_rng(7))
    tracks = [model.advance(DT, 5, robot_positions=np.tile(robot, (5, 1))) for _ in range(20)]
    np.testing.assert_array_equal(np.concatenate(tracks), single)
    for bad in (0, -1, 2.5):
        with pytest.raises(ValueError, match="steps"):
            model.advance(DT, bad)


@pytest.mark.parametrize("name", MODELS)
def test_robot_on_top_of_pedestrian_stays_finite(name: str) -> None:
    """A robot sitting on a pedestrian's centre produces no NaN and no wall crossing."""
    scene = _scene(seed=6, count=5)
    pos, vel = _run(_model(name), scene, seed=6, steps=200, robot=scene["positions"][0].copy())
    assert np.all(np.isfinite(pos)) and np.all(np.isfinite(vel))
    assert np.all(np.abs(pos) <= HALF - scene["radii"][:, None] + 1e-12)


@pytest.mark.parametrize("name", MODELS)
def test_clockwise_polygons_are_reversed(name: str) -> None:
    """Clockwise obstacle vertices give the same trajectories as counter-clockwise ones."""
    scene = _scene(seed=9)
    ccw, _ = _run(_model(name), scene, seed=9, steps=300)
    clockwise = {**scene, "obstacles": [p[::-1] for p in scene["obstacles"]]}
    cw, _ = _run(_model(name), clockwise, seed=9, steps=300)
    np.testing.assert_array_equal(ccw, cw)


@pytest.mark.parametrize("name", MODELS)
def test_empty_crowd_steps(name: str) -> None:
    """A crowd of zero pedestrians resets and steps, returning empty arrays."""
    model = _model(name)
    model.reset(np.zeros((0, 2)), np.zeros(0), np.zeros(0), np.zeros(0), BOUNDS, [], np.random.default_rng(0))
    model.step(DT, np.zeros(2))
    assert model.positions.shape == (0, 2) and model.velocities.shape == (0, 2) and model.radii.shape == (0,)


def test_properties_are_copies() -> None:
    """Writing into a returned array does not change the model state."""
    model = _model("random_walk")
    model.reset(**_scene(seed=0, count=3), rng=np.random.default_rng(0))
    model.positions[:] = np.nan
    model.velocities[:] = np.nan
    model.radii[:] = np.nan
    assert np.all(np.isfinite(model.positions)) and np.all(np.isfinite(model.velocities))


BAD_INPUTS = {
    "nan position": {"positions": np.array([[np.nan, 0.0], [1.0, 1.0]])},
    "position outside": {"positions": np.array([[6.0, 0.0], [1.0, 1.0]])},
    "wrong position shape": {"positions": np.zeros((2, 3))},
    "zero radius": {"radii": np.array([0.0, 0.2])},
    "inf radius": {"radii": np.array([np.inf, 0.2])},
    "radii length": {"radii": np.array([0.2, 0.2, 0.2])},
    "negative speed": {"speeds": np.array([-0.1, 0.3])},
    "nan heading": {"headings": np.array([0.0, np.nan])},
    "bounds too small": {"bounds": (0.0, 0.0, 0.3, 5.0), "positions": np.array([[0.1, 1.0], [0.2, 2.0]])},
    "bounds shape": {"bounds": (0.0, 0.0, 5.0)},
    "non-convex obstacle": {"obstacles": [np.array([[0.0, 0.0], [2.0, 0.0], [0.5, 0.5], [0.0, 2.0]])]},
    "degenerate obstacle": {"obstacles": [np.array([[0.0, 0.0], [1.0, 1.0], [2.0, 2.0]])]},
    "obstacle shape": {"obstacles": [np.zeros((2, 2))]},
}


@pytest.mark.parametrize("name", MODELS)
@pytest.mark.parametrize("case", list(BAD_INPUTS))
def test_bad_reset_inputs_raise(name: str, case: str) -> None:
    """Malformed, non-finite or out-of-bounds reset inputs raise ValueError."""
    good = {"positions": np.array([[0.0, 0.0], [1.0, 1.0]]), "radii": np.array([0.2, 0.3]),
            "speeds": np.array([0.3, 0.3]), "headings": np.array([0.0, 1.0]),
            "bounds": BOUNDS, "obstacles": []}  # fmt: skip
    with pytest.raises(ValueError):
        _model(name).reset(**{**good, **BAD_INPUTS[case]}, rng=np.random.default_rng(0))


@pytest.mark.parametrize("name", MODELS)
def test_bad_step_inputs_raise(name: str) -> None:
    """Stepping before reset raises RuntimeError; a non-positive or NaN dt raises ValueError."""
    model = _model(name)
    with pytest.raises(RuntimeError):
        model.step(DT)
    model.reset(**_scene(seed=0, count=2), rng=np.random.default_rng(0))
    for dt in (0.0, -DT, math.nan):
        with pytest.raises(ValueError):
            model.step(dt)


def test_social_force_rejects_nan_robot() -> None:
    """A NaN robot position raises ValueError instead of poisoning the crowd."""
    model = _model("social_force")
    model.reset(**_scene(seed=0, count=2), rng=np.random.default_rng(0))
    with pytest.raises(ValueError, match="robot"):
        model.step(DT, np.array([np.nan, 0.0]))


def test_factory_builds_each_model_and_names_unknown_one() -> None:
    """The factory maps model names to classes and rejects unknown names by name."""
    assert isinstance(make_pedestrian_model(CrowdConfig(model="random_walk")), RandomWalkModel)
    assert isinstance(make_pedestrian_model(CrowdConfig(model="social_force")), SocialForceModel)
    with pytest.raises(ValueError, match="'teleport'"):
        make_pedestrian_model(CrowdConfig(model="teleport"))  # type: ignore[arg-type]
