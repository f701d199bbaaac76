"""World export: a standalone scene.xml whose rangefinders reproduce mjnav's first scan."""

from __future__ import annotations

import json
import os
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from mjnav.config import load_task
from mjnav.export import export_world
from mjnav.sim import NavSim

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
print(json.dumps({
    "ranges": data.sensordata[model.sensor_adr[rays]].tolist(), "names": names[:2],
    "qpos": data.qpos.tolist(), "mocap_error": float(np.abs(data.mocap_pos - traj["mocap_pos"][0]).max()),
    "mjnav_imported": any(m.startswith("mjnav") for m in sys.modules),
    "wall_conaffinity": int(model.geom_conaffinity[mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_GEOM, "wall_px")]),
    "npair": int(model.npair),
}))
"""


@pytest.mark.parametrize("task", ["stage3", "stage6"])
def test_exported_scene_reproduces_first_scan(tmp_path: Path, task: str):
    """A plain-MuJoCo load of scene.xml reads mjnav's noise-free first scan to 1e-6 m, robot at start.

    The scene keeps the robot's explicit contact pairs and the scene geoms' conaffinity 1.
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
    assert out["names"] == ["robot/ray_000", "robot/ray_001"]
    assert out["mocap_error"] < 1e-12
    assert out["wall_conaffinity"] == 1  # bodies added to the scene collide with it as usual
    assert out["npair"] == len(sim.scene_geoms)  # the robot's contacts, as in mjnav
    data = np.load(trajectory)
    assert data["mocap_pos"].shape == (6, physics.model.nmocap, 3)
    np.testing.assert_array_equal(data["goal"], layout.goal)


@pytest.mark.parametrize("override", ["crowd.bogus=1", "task.crowd.bogus=1"])
def test_export_script_rejects_unknown_keys(tmp_path: Path, override: str):
    """Non-script keys (``task.`` prefix optional) go to load_task, whose error is one line."""
    script = Path(__file__).resolve().parents[1] / "scripts" / "export_world.py"
    result = subprocess.run([sys.executable, str(script), "task=stage1", f"out={tmp_path}", override],
                            capture_output=True, text=True, cwd=script.parents[1], check=False,
                            env={**os.environ, "PYTHONPATH": str(script.parents[1])})
    assert result.returncode != 0
    assert result.stderr.startswith("error: override crowd.bogus=1") and "Traceback" not in result.stderr
    assert not any(tmp_path.iterdir())
