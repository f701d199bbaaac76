"""NavSim: every stage builds, resets and steps; determinism; no recompiling; parking; collisions."""

from __future__ import annotations

import dataclasses

import mujoco
import numpy as np
import pytest
from dm_control import composer

from mjnav.config import load_task
from mjnav.entities.arena import PARK_DEPTH
from mjnav.sim import NavSim

STAGES = [f"stage{i}" for i in range(1, 8)]
SPEC = {  # spec §9: interior, static, dynamic
    "stage1": ((20, 30), 0, 0), "stage2": ((20, 30), 10, 0), "stage3": ((20, 30), 10, 5),
    "stage4": ((20, 30), 10, 10), "stage5": ((10, 10), 0, 10), "stage6": ((10, 10), 0, 20),
    "stage7": ((10, 10), 0, 30),
}


def _build(config):
    sim = NavSim(config)
    return sim, sim.make_physics()


def _replace(config, **sections):
    """Config with some fields of its sections replaced: ``obstacles={"count": 3}``."""
    changes = {name: dataclasses.replace(getattr(config, name), **fields) for name, fields in sections.items()}
    return dataclasses.replace(config, **changes)


@pytest.mark.parametrize("stage", STAGES)
def test_every_stage_builds_resets_and_steps(stage):
    """Each stage compiles, matches its spec row, resets and runs 50 control steps with valid scans."""
    config = load_task(stage)
    sim, physics = _build(config)
    size, static, dynamic = SPEC[stage]
    assert tuple(config.arena.size) == size
    rng = np.random.default_rng(0)
    layout = sim.initialize_episode(physics, rng)
    assert len(layout.obstacle_shapes) == static and len(layout.ped_radii) == dynamic
    assert sim.crowd.active == dynamic
    for _ in range(50):
        _, v, a = sim.robot_state(physics)
        sim.control_step(physics, np.clip(-2.0 * a - 3.0 * v, -8.0, 8.0))  # gentle: damp to rest
        scan = sim.scan(physics, rng)
        assert scan.shape == (360,) and np.all((scan >= 0) & (scan <= 10.0))
    assert np.all(np.abs(sim.robot_state(physics)[0]) < np.asarray(size) / 2)


def test_same_seed_gives_bit_identical_episodes():
    """Two independently built sims with the same seed produce identical worlds, states and scans."""
    config = load_task("stage3")
    runs = []
    for _ in range(2):
        sim, physics = _build(config)
        rng = np.random.default_rng(11)
        layout = sim.initialize_episode(physics, rng)
        trace = []
        for k in range(30):
            sim.control_step(physics, np.array([np.sin(k), np.cos(k)]) * 6.0)
            trace.append(np.concatenate([physics.data.qpos, physics.data.qvel, physics.data.mocap_pos.ravel(),
                                         sim.scan(physics, rng), sim.scan(physics, noise=False, backend="mujoco")]))
        runs.append((layout, np.asarray(trace)))
    assert runs[0][0] == runs[1][0]
    assert np.array_equal(runs[0][1], runs[1][1])


def test_reset_does_not_recompile():
    """Resets reuse the compiled model (same pointer, sizes) and still give fresh layouts."""
    sim, physics = _build(load_task("stage4"))
    model, ngeom = physics.model.ptr, physics.model.ngeom
    rng = np.random.default_rng(2)
    starts = [sim.initialize_episode(physics, rng).start for _ in range(3)]
    assert physics.model.ptr is model and physics.model.ngeom == ngeom
    assert not np.array_equal(starts[0], starts[1])


def test_parked_slots_are_invisible():
    """With fewer obstacles/pedestrians than slots, the parked ones are below the floor and unseen."""
    config = _replace(load_task("stage4"), obstacles={"count": 3, "slots": 10}, crowd={"count": 4, "slots": 9})
    sim, physics = _build(config)
    for seed in range(3):
        sim.initialize_episode(physics, np.random.default_rng(seed))
        parked_obstacles = physics.bind(sim.arena.obstacle_slots[3:]).element_id
        parked_peds = sim.crowd.geom_ids(physics)[4:]
        assert np.all(physics.data.geom_xpos[np.r_[parked_obstacles, parked_peds], 2] < -PARK_DEPTH + 2)
        analytic = sim.scan(physics, noise=False, backend="analytic")  # knows only the active items
        np.testing.assert_allclose(sim.scan(physics, noise=False, backend="mujoco"), analytic, atol=1e-9)
        assert not sim.robot_in_collision(physics)[0]


def test_collisions_report_their_kind():
    """Teleporting the robot onto a pedestrian, an obstacle or a wall gives a contact of that kind."""
    sim, physics = _build(load_task("stage4"))
    layout = sim.initialize_episode(physics, np.random.default_rng(4))
    model, data = physics.model.ptr, physics.data.ptr
    targets = {
        "pedestrian": sim.pedestrian_circles()[0, :2],
        # straddling an edge: a disc wholly inside a mesh prism is a case MuJoCo's convex
        # collision may miss, and one a robot moving <= 7 cm per substep never reaches
        "obstacle": sim.arena.obstacle_polygons(physics, 0.3)[0][:2].mean(axis=0),
        "wall": np.array([10.0 - 0.1, layout.start[1]]),
    }
    assert sim.robot_in_collision(physics) == (False, None)
    for kind, xy in targets.items():
        sim.robot.set_state(physics, xy)
        mujoco.mj_forward(model, data)
        collided, found = sim.robot_in_collision(physics)
        assert collided and found == kind


def test_free_space_control_step_follows_triple_integrator():
    """A control step in free space lands on the triple-integrator prediction (< 0.05 mm)."""
    sim, physics = _build(load_task("stage1"))
    sim.initialize_episode(physics, np.random.default_rng(0))
    jerk = np.array([8.0, -5.0])
    for _ in range(3):
        p, v, a = sim.robot_state(physics)
        sim.control_step(physics, jerk)
        t = sim.config.timing.control_period
        p1, v1, a1 = sim.robot_state(physics)
        np.testing.assert_allclose(p1, p + v * t + a * t**2 / 2 + jerk * t**3 / 6, atol=5e-5)
        np.testing.assert_allclose(v1, v + a * t + jerk * t**2 / 2, atol=1e-9)
        np.testing.assert_allclose(a1, a + jerk * t, atol=1e-12)


class _Task(composer.Task):
    """Minimal composer wrapper used to check NavSim's hooks inside composer."""

    def __init__(self, sim: NavSim) -> None:
        self.sim = sim
        self.set_timesteps(sim.config.timing.control_period, sim.config.timing.physics_timestep)

    @property
    def root_entity(self):
        return self.sim.root_entity

    def initialize_episode(self, physics, random_state):
        self.sim.initialize_episode(physics, np.random.default_rng(random_state.randint(2**31)))

    def before_step(self, physics, action, random_state):
        self.sim.apply_command(physics, action)

    def before_substep(self, physics, action, random_state):
        self.sim.before_substep(physics)

    def get_reward(self, physics):
        return 0.0


def test_composer_environment_matches_direct_stepping():
    """Inside composer (legacy stepping, no per-episode recompile) NavSim steps exactly like control_step."""
    config = load_task("stage6")
    env = composer.Environment(_Task(NavSim(config)), random_state=3, recompile_mjcf_every_episode=False)
    env.reset()
    physics = env.physics
    model = physics.model.ptr
    sim, direct = _build(config)
    sim.initialize_episode(direct, np.random.default_rng(np.random.RandomState(3).randint(2**31)))
    np.testing.assert_array_equal(direct.data.qpos, physics.data.qpos)
    for k in range(10):
        jerk = np.array([4.0, -4.0]) * np.cos(k)
        env.step(jerk)
        sim.control_step(direct, jerk)
    np.testing.assert_array_equal(direct.data.qpos, physics.data.qpos)
    np.testing.assert_array_equal(direct.data.mocap_pos, physics.data.mocap_pos)
    env.reset()
    assert env.physics.model.ptr is model


def test_lidar_must_hit_the_scene():
    """A LiDAR above the walls (rays would pass over them) is rejected at build."""
    with pytest.raises(ValueError, match="lidar.height"):
        NavSim(_replace(load_task("stage1"), lidar={"height": 0.7}))


@pytest.mark.parametrize("fused", [True, False])
@pytest.mark.parametrize("substep", [-1, 2])
def test_contact_in_one_substep_counts(fused, substep):
    """A pedestrian that touches the robot during one physics step only is a collision.

    MuJoCo finds a step's contacts before integrating; the pedestrian is moved away before the
    end-of-period sync, so only that step's contacts show it (the last step's: only the sync
    sees them). Fused and Python substeps note them alike.
    """
    config = load_task("stage5")
    sim = NavSim(config, fused=fused)
    physics = sim.make_physics()
    sim.initialize_episode(physics, np.random.default_rng(1))
    data = physics.data.ptr
    robot = sim.robot_state(physics)[0]
    far = sim.pedestrian_circles()[:, :2]
    for touching in (False, True):
        sim.apply_command(physics, np.zeros(2))
        track = np.repeat(far[None], config.timing.substeps, axis=0)
        if touching:
            track[substep, 0] = robot  # pedestrian 0 on the robot for that physics step only
        sim._crowd_track = track
        sim.run_period(physics)
        data.mocap_pos[sim.crowd.mocap_ids(physics)[0], :2] = far[0]  # gone by the period's end
        sim.sync(physics)
        assert sim.robot_in_collision(physics) == ((True, "pedestrian") if touching else (False, None))
    assert sim.fused is fused


@pytest.mark.parametrize("model", ["random_walk", "social_force"])
def test_crowd_lookahead_changes_nothing(monkeypatch, model):
    """Crowd steps computed many periods ahead give the same world as computing them period by period.

    25 periods cross the look-ahead block boundary; a social-force crowd reacts to the robot and is
    always advanced period by period. The LiDAR's pedestrians are the mocap bodies' positions.
    """
    import mjnav.sim as sim_module

    config = _replace(load_task("stage7"), crowd={"model": model})
    traces = []
    for lookahead in (1, 3, sim_module.CROWD_LOOKAHEAD):
        monkeypatch.setattr(sim_module, "CROWD_LOOKAHEAD", lookahead)
        sim, physics = _build(config)
        sim.initialize_episode(physics, np.random.default_rng(5))
        mocap = sim.crowd.mocap_ids(physics)[: config.crowd.count]
        trace = []
        for k in range(25):
            sim.control_step(physics, np.array([np.sin(k), np.cos(k)]) * 4.0)
            np.testing.assert_array_equal(sim.pedestrian_circles()[:, :2], physics.data.mocap_pos[mocap, :2])
            trace.append(np.concatenate([physics.data.qpos, physics.data.mocap_pos.ravel(), sim.scan(physics, noise=False)]))
        traces.append(np.asarray(trace))
    assert np.array_equal(traces[0], traces[1]) and np.array_equal(traces[0], traces[2])
    assert not np.allclose(traces[0][0], traces[0][-1])  # the crowd moved


def _contacts(data) -> list[tuple]:
    """The current contacts, order-free: geom pair, dim, distance, position, normal, friction, solref."""
    rows = []
    for c in data.contact[: data.ncon]:
        rows.append((*sorted(c.geom.tolist()), int(c.dim), *np.round(np.r_[c.dist, c.pos, c.frame[:3]], 12),
                     *c.friction.tolist(), *c.solref.tolist(), *c.solimp.tolist()))
    return sorted(rows)


def test_contact_pairs_find_the_same_contacts():
    """Explicit robot pairs give the contacts MuJoCo's contype/conaffinity filtering gives.

    The robot is placed at random near walls, obstacles and pedestrians; both builds agree on
    every contact (geoms, distance, point, normal and its parameters), and only robot pairs appear.
    """
    config = load_task("stage4")
    sims = [NavSim(config, contact_pairs=flag) for flag in (True, False)]
    physics = [sim.make_physics() for sim in sims]
    assert physics[0].model.npair > 0 and physics[1].model.npair == 0
    for sim, phys in zip(sims, physics, strict=True):
        sim.initialize_episode(phys, np.random.default_rng(4))
    robot_geom = sims[0].robot.geom_id(physics[0])
    rng = np.random.default_rng(0)
    anchors = np.vstack([sims[0].pedestrian_circles()[:, :2],
                         *[p.mean(axis=0, keepdims=True) for p in sims[0].arena.obstacle_polygons(physics[0], 0.3)],
                         [[9.9, 0.0], [-9.9, 5.0], [3.0, 14.9], [0.0, -14.9]]])
    touching = 0
    for _ in range(300):
        xy = anchors[rng.integers(len(anchors))] + rng.uniform(-0.6, 0.6, 2)
        found = []
        for sim, phys in zip(sims, physics, strict=True):
            sim.robot.set_state(phys, xy)
            mujoco.mj_forward(phys.model.ptr, phys.data.ptr)
            found.append(_contacts(phys.data.ptr))
        assert found[0] == found[1]
        assert all(robot_geom in row[:2] for row in found[0])
        touching += bool(found[0])
    assert touching > 50
