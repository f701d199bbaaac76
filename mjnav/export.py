"""Export one episode's world as a standalone MuJoCo scene plus the pedestrian trajectories.

``export_world(config, seed, out_dir)`` writes ``scene.xml`` (arena, obstacles baked at their
poses for that seed, the robot with its rangefinders at the start, pedestrians at their initial
positions; meshes are inline, so the file needs no other asset) and ``trajectory.npz`` (the
pedestrian mocap positions per control step of the episode with the robot holding still at the
start, plus start, goal and the first noise-free scan). The format is documented in
the export page of the documentation; the scene loads with plain ``mujoco.MjModel.from_xml_path``.
"""

from __future__ import annotations

from pathlib import Path
from typing import TYPE_CHECKING

import mujoco
import numpy as np
from dm_control import mjcf

from mjnav.entities.arena import SCENE_CONAFFINITY
from mjnav.sim import NavSim
from mjnav.world.layout import Layout

if TYPE_CHECKING:
    from mjnav.config import TaskConfig

__all__ = ["bake_layout", "export_world", "record_episode"]


def record_episode(sim: NavSim, physics: mjcf.Physics, seed: int, steps: int) -> dict[str, np.ndarray]:
    """Runs an episode with zero jerk (the robot holds still) and records the world.

    Args:
        sim: The simulation (its physics compiled).
        physics: Physics compiled from ``sim``.
        seed: Episode seed (``np.random.default_rng(seed)`` as in the tasks).
        steps: Control steps to record after the initial state.

    Returns:
        Arrays of the export format (``time``, ``mocap_pos``, ``robot_qpos``, ``start``,
        ``goal``, ``ranges``, ``obstacle_shapes``, ``obstacle_poses``, ``ped_radii``).
    """
    rng = np.random.default_rng(seed)
    layout = sim.initialize_episode(physics, rng)
    data = physics.data.ptr
    ranges = sim.scan(physics, noise=False)
    mocap, qpos = [data.mocap_pos.copy()], [sim.robot_state(physics)[0]]
    for _ in range(steps):
        sim.control_step(physics, np.zeros(2))
        mocap.append(data.mocap_pos.copy())
        qpos.append(sim.robot_state(physics)[0])
    period = sim.config.timing.control_period
    return {
        "time": period * np.arange(steps + 1),
        "mocap_pos": np.asarray(mocap),
        "robot_qpos": np.asarray(qpos),
        "start": np.asarray(layout.start),
        "goal": np.asarray(layout.goal),
        "ranges": ranges,
        "obstacle_shapes": np.asarray(layout.obstacle_shapes),
        "obstacle_poses": np.asarray(layout.obstacle_poses),
        "ped_radii": np.asarray(layout.ped_radii),
    }


def bake_layout(sim: NavSim, layout: Layout, ped_positions: np.ndarray) -> mjcf.RootElement:
    """Writes an episode into the (never compiled) MJCF of ``sim``: the initial state becomes the default.

    Obstacle slots take their bank mesh and pose, pedestrians their radius and position (unused
    slots stay parked), the robot body moves to the start with joint ``ref`` = start, so
    ``qpos`` still reads world coordinates and ``qpos0`` is the start. The scene geoms get back
    conaffinity 1, so that bodies added to the scene collide with them; the robot's explicit
    contact pairs stay (MuJoCo does not repeat a pair's contacts in its dynamic search).

    Args:
        sim: A fresh simulation used only for export (its MJCF is modified).
        layout: The episode layout.
        ped_positions: (P, 2) pedestrian centres at the first step, metres.

    Returns:
        The baked MJCF root.
    """
    for slot, shape, pose in zip(sim.arena.obstacle_slots, layout.obstacle_shapes, layout.obstacle_poses,
                                 strict=False):
        slot.mesh = sim.arena.meshes[int(shape)]
        slot.pos = (pose[0], pose[1], 0.0)
        slot.quat = (np.cos(pose[2] / 2), 0.0, 0.0, np.sin(pose[2] / 2))
    frames, peds = sim.crowd.frames, sim.crowd.pedestrians
    for i, (radius, pos) in enumerate(zip(layout.ped_radii, ped_positions, strict=True)):
        frames[i].pos = (pos[0], pos[1], 0.0)
        peds[i].geom.size = (radius, sim.config.crowd.height / 2)
    start = np.asarray(layout.start, dtype=np.float64)
    body = sim.robot.body
    body.pos = (start[0], start[1], body.pos[2])
    for joint, value in zip(sim.robot.joints, start, strict=True):
        joint.ref = value
    for geom in sim.scene_geoms:
        geom.conaffinity = SCENE_CONAFFINITY
    return sim.mjcf_model


def export_world(config: TaskConfig, seed: int, out_dir: str | Path, steps: int = 300) -> Path:
    """Writes ``scene.xml`` and ``trajectory.npz`` for one episode of ``config``.

    Args:
        config: A ``TaskConfig``.
        seed: Episode seed (``np.random.default_rng(seed)``).
        out_dir: Output folder (created when missing).
        steps: Control steps of pedestrian trajectory to record.

    Returns:
        Path of ``scene.xml``.

    Raises:
        ValueError: ``seed`` outside [0, 2**63) or ``steps`` < 1.
        FileExistsError: ``out_dir`` is an existing file.
    """
    if isinstance(seed, bool) or not isinstance(seed, (int, np.integer)) or not 0 <= int(seed) < 2**63:
        raise ValueError(f"seed: expected an integer in [0, 2**63), got {seed!r}")
    if isinstance(steps, bool) or not isinstance(steps, (int, np.integer)) or steps < 1:
        raise ValueError(f"steps: expected an integer >= 1, got {steps!r}")
    out = Path(out_dir)
    if out.exists() and not out.is_dir():
        raise FileExistsError(f"out: {str(out)!r} is a file, not a folder")
    out.mkdir(parents=True, exist_ok=True)
    sim = NavSim(config)
    physics = sim.make_physics()
    record = record_episode(sim, physics, seed, steps)
    active = sim.crowd.mocap_ids(physics)[: len(record["ped_radii"])]
    baked = bake_layout(NavSim(config), sim.layout, record["mocap_pos"][0][active, :2])
    mjcf.export_with_assets(baked, str(out), "scene.xml")
    model = physics.model.ptr
    bodies = np.argsort(np.where(model.body_mocapid >= 0, model.body_mocapid, np.iinfo(np.int32).max))
    names = [mujoco.mj_id2name(model, mujoco.mjtObj.mjOBJ_BODY, int(b)) for b in bodies[: model.nmocap]]
    np.savez(out / "trajectory.npz", **record, mocap_names=np.asarray(names), seed=np.int64(seed),
             task=np.asarray(getattr(config, "name", "custom")))
    return out / "scene.xml"
