"""World export: a standalone scene.xml that plain MuJoCo, MjSpec and dm_control load, whose
rangefinders reproduce mjnav's first scan and whose floor, walls, obstacles and pedestrians
collide with bodies a user adds; mjnav's robot as a standalone model; docs/export.md's examples."""

from __future__ import annotations

import json
import os
import re
import subprocess
import sys
from pathlib import Path

import mujoco
import numpy as np
import pytest
from dm_control import mjcf

from mjnav.config import load_task
from mjnav.export import bake_layout, export_world, robot_mjcf, sanitize_mjcf
from mjnav.sim import NavSim

ROOT = Path(__file__).resolve().parents[1]
DOCS = ROOT / "docs" / "export.md"

# Runs in a fresh interpreter that never imports mjnav: plain MuJoCo only.
_LOADER = """
import json, sys
import mujoco, numpy as np
model = mujoco.MjModel.from_xml_path(sys.argv[1])
data = mujoco.MjData(model)
mujoco.mj_forward(model, data)
rays = [i for i in range(model.nsensor) if model.sensor_type[i] == mujoco.mjtSensor.mjSENS_RANGEFINDER]
traj = np.load(sys.argv[2])
names = [mujoco.mj_id2name(model, mujoco.mjtObj.mjOBJ_SENSOR, i) for i in rays]
affinity = lambda name: int(model.geom_conaffinity[mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_GEOM, name)])
print(json.dumps({
    "ranges": data.sensordata[model.sensor_adr[rays]].tolist(), "names": names[:2],
    "qpos": data.qpos.tolist(), "mocap_error": float(np.abs(data.mocap_pos - traj["mocap_pos"][0]).max()),
    "mjnav_imported": any(m.startswith("mjnav") for m in sys.modules),
    "wall_conaffinity": affinity("wall_px"), "floor_conaffinity": affinity("floor"),
    "npair": int(model.npair),
}))
"""


def _baked(task: str, seed: int = 7) -> tuple[NavSim, mjcf.Physics, mjcf.RootElement]:
    """A live simulation at the start of episode ``seed`` and the MJCF that export_world bakes from it."""
    config = load_task(task)
    sim = NavSim(config)
    physics = sim.make_physics()
    layout = sim.initialize_episode(physics, np.random.default_rng(seed))
    peds = physics.data.ptr.mocap_pos[sim.crowd.mocap_ids(physics)[: len(layout.ped_radii)], :2]
    return sim, physics, bake_layout(NavSim(config), layout, peds.copy())


@pytest.fixture(scope="module")
def stage4_scene(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """``world/scene.xml`` of stage 4 (obstacles and pedestrians), seed 7, as docs/export.md makes it."""
    return export_world(load_task("stage4"), seed=7, out_dir=tmp_path_factory.mktemp("docs") / "world", steps=20)


@pytest.mark.parametrize("task", ["stage3", "stage6"])
def test_exported_scene_reproduces_first_scan(tmp_path: Path, task: str):
    """A plain-MuJoCo load of scene.xml reads mjnav's noise-free first scan to 1e-6 m, robot at start.

    The scene keeps the robot's explicit contact pairs; floor and scene geoms have conaffinity 1.
    """
    config = load_task(task)
    scene = export_world(config, seed=7, out_dir=tmp_path / "world", steps=5)
    trajectory = scene.parent / "trajectory.npz"
    env = {k: v for k, v in os.environ.items() if k != "PYTHONPATH"}
    result = subprocess.run([sys.executable, "-c", _LOADER, str(scene), str(trajectory)], cwd=tmp_path,
                            env=env, capture_output=True, text=True, check=True)
    out = json.loads(result.stdout.strip().splitlines()[-1])
    assert not out["mjnav_imported"]
    sim = NavSim(config)
    physics = sim.make_physics()
    layout = sim.initialize_episode(physics, np.random.default_rng(7))
    expected = sim.scan(physics, noise=False)
    ranges = np.asarray(out["ranges"])
    ranges[(ranges < 0) | (ranges > config.lidar.max_range)] = config.lidar.max_range
    np.testing.assert_allclose(ranges, expected, atol=1e-6)
    np.testing.assert_allclose(out["qpos"], layout.start, atol=1e-12)
    assert out["names"] == ["robot_ray_000", "robot_ray_001"]
    assert out["mocap_error"] < 1e-12
    assert out["wall_conaffinity"] == out["floor_conaffinity"] == 1  # added bodies collide with them
    assert out["npair"] == len(sim.scene_geoms)  # the robot's contacts, as in mjnav
    data = np.load(trajectory)
    assert data["mocap_pos"].shape == (6, physics.model.nmocap, 3)
    assert list(data["mocap_names"][:2]) == ["ped_00_", "ped_01_"]
    np.testing.assert_array_equal(data["goal"], layout.goal)


def _model_arrays(model: mujoco.MjModel) -> dict[str, np.ndarray]:
    """Every array of a compiled model except the name tables."""
    out = {}
    for key in dir(model):
        value = getattr(model, key, None) if not key.startswith("_") else None
        if isinstance(value, np.ndarray) and not key.startswith("name"):
            out[key] = value
    return out


def test_sanitizing_keeps_the_compiled_model():
    """dm_control's XML and the sanitized XML compile to equal arrays (plain MuJoCo); only names change."""
    _, _, baked = _baked("stage4")
    raw = baked.to_xml_string(precision=17)
    clean = sanitize_mjcf(raw)
    assert 'class="/"' in raw and "robot/ray_000" in raw  # what dm_control's parser refuses
    assert "/" not in "".join(re.findall(r'(?:name|class)="([^"]*)"', clean)) and "<default" not in clean
    before, after = mujoco.MjModel.from_xml_string(raw), mujoco.MjModel.from_xml_string(clean)
    arrays_before, arrays_after = _model_arrays(before), _model_arrays(after)
    assert arrays_before.keys() == arrays_after.keys() and len(arrays_before) > 300
    for key, value in arrays_before.items():
        np.testing.assert_array_equal(arrays_after[key], value, err_msg=key)
    assert after.names == before.names.replace(b"/", b"_")  # readable: robot_base, ped_00_, ped_00_body


def test_sanitize_renames_clashes_and_keeps_classes_with_settings():
    """A clash gets a suffix everywhere it is referenced; a class with settings survives, renamed."""
    xml = """<mujoco><default><default class="/"><default class="arm/"><geom rgba="1 0 0 1"/>
      <default class="arm/sub/"/></default></default></default>
      <worldbody><body name="arm/"><geom name="arm/g" class="arm/sub/" size="0.1"/></body>
      <body name="arm_"><geom name="g2" class="/" size="0.2"/></body></worldbody>
      <contact><exclude body1="arm/" body2="arm_"/></contact></mujoco>"""
    clean = sanitize_mjcf(xml)
    model = mujoco.MjModel.from_xml_string(clean)
    assert model.body(1).name == "arm__1" and model.body(2).name == "arm_"
    assert model.exclude_signature.size == 1 and 'body1="arm__1"' in clean
    np.testing.assert_array_equal(model.geom("arm_g").rgba, [1, 0, 0, 1])  # class arm/sub/ -> arm_
    assert 'class="arm__1"' in clean and 'class="/"' not in clean and model.geom("g2").rgba[0] == 0.5
    mjcf.from_xml_string(clean)  # dm_control accepts it


def test_exported_scene_matches_live_sim(stage4_scene: Path):
    """Same bodies and geoms, sizes and poses as mjnav's physics at the episode start."""
    sim = NavSim(load_task("stage4"))
    physics = sim.make_physics()
    sim.initialize_episode(physics, np.random.default_rng(7))
    live = physics.model.ptr
    model = mujoco.MjModel.from_xml_path(str(stage4_scene))
    data = mujoco.MjData(model)
    mujoco.mj_forward(model, data)
    assert (model.nbody, model.ngeom, model.nmocap, model.nsensor, model.nu) == (
        live.nbody, live.ngeom, live.nmocap, live.nsensor, live.nu)
    for name in ("geom_type", "geom_contype", "geom_dataid", "body_mocapid"):
        np.testing.assert_array_equal(getattr(model, name), getattr(live, name), err_msg=name)
    np.testing.assert_allclose(model.geom_size, live.geom_size, atol=1e-12)
    np.testing.assert_allclose(data.geom_xpos, physics.data.geom_xpos, atol=1e-9)
    np.testing.assert_allclose(data.geom_xmat, physics.data.geom_xmat, atol=1e-9)
    scene = [mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_GEOM, n) for n in ("floor", "wall_px", "ped_00_body")]
    assert model.geom_conaffinity[scene].tolist() == [1, 1, 1] and model.geom_contype[scene].tolist() == [0, 0, 0]
    assert live.geom_conaffinity[scene].tolist() == [0, 0, 0]  # mjnav itself: pairs only


def test_robot_contacts_are_not_doubled(stage4_scene: Path):
    """With conaffinity 1 back on the scene, a pedestrian touching the robot still gives one contact (its pair)."""
    model = mujoco.MjModel.from_xml_path(str(stage4_scene))
    data = mujoco.MjData(model)
    mujoco.mj_forward(model, data)
    data.mocap_pos[model.body("ped_00_").mocapid[0], :2] = data.body("robot_base").xpos[:2] + [0.3, 0.0]
    mujoco.mj_forward(model, data)
    pairs = [{int(c.geom1), int(c.geom2)} for c in data.contact[: data.ncon]]
    assert pairs.count({model.geom("robot_disc").id, model.geom("ped_00_body").id}) == 1


def test_scene_loads_with_mjspec_and_dm_control(stage4_scene: Path):
    """MjSpec compiles it and dm_control parses, compiles and re-exports it."""
    spec_model = mujoco.MjSpec.from_file(str(stage4_scene)).compile()
    world = mjcf.from_path(str(stage4_scene))
    physics = mjcf.Physics.from_mjcf_model(world)
    assert spec_model.ngeom == physics.model.ngeom == mujoco.MjModel.from_xml_path(str(stage4_scene)).ngeom
    assert world.find("body", "ped_00_") is not None and world.find("sensor", "robot_ray_359") is not None
    mujoco.MjModel.from_xml_string(world.to_xml_string())


_BALL = 0.2  # radius of the test body, metres


def _with_ball(scene: Path, pos: np.ndarray) -> tuple[mujoco.MjModel, mujoco.MjData]:
    """The exported scene plus a free 2 kg sphere (MuJoCo's default collision bits) at ``pos``."""
    spec = mujoco.MjSpec.from_file(str(scene))
    ball = spec.worldbody.add_body(name="ball", pos=pos)
    ball.add_freejoint()
    ball.add_geom(name="ball", type=mujoco.mjtGeom.mjGEOM_SPHERE, size=[_BALL, 0, 0], mass=2.0)
    model = spec.compile()
    data = mujoco.MjData(model)
    mujoco.mj_forward(model, data)
    return model, data


def test_added_body_rests_on_the_floor(stage4_scene: Path):
    """A sphere dropped from 1 m at the goal settles on the floor and stays there."""
    goal = np.load(stage4_scene.parent / "trajectory.npz")["goal"]
    model, data = _with_ball(stage4_scene, np.r_[goal, 1.0])
    heights = []
    for _ in range(150):
        mujoco.mj_step(model, data)
        heights.append(data.body("ball").xpos[2])
    assert min(heights) > _BALL - 0.03 and abs(heights[-1] - _BALL) < 0.005


def _clear_approach(model: mujoco.MjModel, target: int, centre: np.ndarray,
                    reach: float) -> tuple[np.ndarray, np.ndarray]:
    """A start (x, y) and unit direction from which a ball rolls straight into geom ``target``.

    Tries starts on a circle of radius ``reach`` around ``centre``; the one kept has three parallel
    rays (centre line and both sides of the ball) at ball height hitting ``target`` first.
    """
    data = mujoco.MjData(model)
    mujoco.mj_forward(model, data)
    half = 0.5 * np.asarray(load_task("stage4").arena.size)  # interior half sizes, metres
    for angle in np.deg2rad(np.arange(0, 360, 10)):
        u = np.array([np.cos(angle), np.sin(angle)])
        start = centre - reach * u
        if np.any(np.abs(start) > half - 2 * _BALL):
            continue
        side = np.array([-u[1], u[0]]) * 0.9 * _BALL
        hits = []
        for offset in (0.0 * side, side, -side):
            geom = np.array([-1], dtype=np.int32)
            dist = mujoco.mj_ray(model, data, np.r_[start + offset, _BALL], np.r_[u, 0.0], None, 1, -1, geom)
            hits.append((int(geom[0]), dist))
        if all(g == target for g, _ in hits) and hits[0][1] > 2 * _BALL:
            return start, u
    raise AssertionError(f"no clear approach to geom {target}")


@pytest.mark.parametrize("name", ["wall_px", "wall_ny", "obstacle_00", "obstacle_03", "ped_00_body", "ped_04_body"])
def test_added_body_collides_with_walls_obstacles_and_pedestrians(stage4_scene: Path, name: str):
    """A sphere pushed at 5 N into a wall, obstacle or pedestrian touches it and does not pass."""
    bare = mujoco.MjModel.from_xml_path(str(stage4_scene))
    target = bare.geom(name).id
    centre = mujoco.MjData(bare)
    mujoco.mj_forward(bare, centre)
    xy = centre.geom_xpos[target, :2]
    if name.startswith("wall"):  # aim across the wall's middle
        xy = np.where(np.abs(xy) > 1.0, xy, 0.0)
    start, direction = _clear_approach(bare, target, xy, 2.5 if name.startswith("wall") else
                                                float(bare.geom_rbound[target]) + 1.0)
    model, data = _with_ball(stage4_scene, np.r_[start, _BALL + 0.002])
    ball = model.geom("ball").id
    touched, closest = False, np.inf  # closest: least signed distance ball-target, metres
    for _ in range(300):
        data.xfrc_applied[model.body("ball").id, :2] = 5.0 * direction
        mujoco.mj_step(model, data)
        touched |= any({int(c.geom1), int(c.geom2)} == {ball, target} for c in data.contact[: data.ncon])
        closest = min(closest, mujoco.mj_geomDistance(model, data, ball, target, 1.0, None))
    assert touched
    assert closest > -0.05  # it sinks in a little at impact (0.02 s steps) but never passes through
    assert data.body("ball").xpos[2] < 2 * _BALL  # and does not climb over it


def test_robot_mjcf_is_mjnav_robot():
    """The standalone robot has the live robot's mass, disc, collision bits, motors and beam directions."""
    config = load_task("stage6")
    model = mujoco.MjModel.from_xml_string(robot_mjcf(config))
    live = NavSim(config).make_physics().model
    disc, live_disc = model.geom("disc"), live.geom("robot/disc")
    np.testing.assert_array_equal(disc.size, live_disc.size)
    assert (int(disc.contype[0]), int(disc.conaffinity[0])) == (1, 0)
    assert model.body("base").mass[0] == live.body("robot/base").mass[0] == config.robot.mass
    assert model.nsensor == live.nsensor == 360 and model.nu == 2
    np.testing.assert_array_equal(model.actuator_ctrlrange, live.actuator_ctrlrange)
    rays = [live.site(f"robot/ray_{i:03d}").id for i in range(360)]
    np.testing.assert_allclose(model.site_quat, live.site_quat[rays], atol=1e-15)
    assert mujoco.MjModel.from_xml_string(robot_mjcf(config, rangefinders=False)).nsensor == 0


def _python_blocks(text: str) -> list[str]:
    """The ```python fenced blocks of a Markdown text."""
    return re.findall(r"^```python\n(.*?)^```", text, flags=re.S | re.M)


_BLOCKS = _python_blocks(DOCS.read_text(encoding="utf-8"))


def test_docs_have_examples_in_both_directions():
    """docs/export.md shows dm_control and MjSpec, their robot into our world and ours into theirs."""
    joined = "\n".join(_BLOCKS)
    assert len(_BLOCKS) >= 6
    for needle in ("mjcf.from_path", "MjSpec.from_file", "world.attach", "robot_mjcf()", "spec.attach"):
        assert needle in joined, needle


@pytest.mark.parametrize("index", range(len(_BLOCKS)))
def test_docs_example_runs(stage4_scene: Path, index: int):
    """Every Python block of docs/export.md runs, in a fresh interpreter, next to an exported world."""
    env = {**os.environ, "PYTHONPATH": str(ROOT), "MUJOCO_GL": os.environ.get("MUJOCO_GL", "egl")}
    result = subprocess.run([sys.executable, "-c", _BLOCKS[index]], cwd=stage4_scene.parent.parent, env=env,
                            capture_output=True, text=True, timeout=300, check=False)
    assert result.returncode == 0, f"block {index}:\n{_BLOCKS[index]}\n{result.stderr[-3000:]}"


@pytest.mark.parametrize("override", ["crowd.bogus=1", "task.crowd.bogus=1"])
def test_export_script_rejects_unknown_keys(tmp_path: Path, override: str):
    """Non-script keys (``task.`` prefix optional) go to load_task, whose error is one line."""
    script = ROOT / "scripts" / "export_world.py"
    result = subprocess.run([sys.executable, str(script), "task=stage1", f"out={tmp_path}", override],
                            capture_output=True, text=True, cwd=script.parents[1], check=False,
                            env={**os.environ, "PYTHONPATH": str(script.parents[1])})
    assert result.returncode != 0
    assert result.stderr.startswith("error: override crowd.bogus=1") and "Traceback" not in result.stderr
    assert not any(tmp_path.iterdir())
