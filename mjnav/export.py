"""Export one episode's world as a standalone MuJoCo scene, and mjnav's robot as a standalone model.

``export_world(config, seed, out_dir)`` writes ``scene.xml`` (arena, obstacles baked at their
poses for that seed, the robot with its rangefinders at the start, pedestrians at their initial
positions; meshes are inline, so the file needs no other asset) and ``trajectory.npz`` (the
pedestrian mocap positions per control step of the episode with the robot holding still at the
start, plus start, goal and the first noise-free scan). ``robot_mjcf()`` returns the robot alone
(disc, slide joints, force motors, 360 rangefinders) for attaching into another world.

Both are written through :func:`sanitize_mjcf`, so they load with plain
``mujoco.MjModel.from_xml_path``, with ``mujoco.MjSpec`` and with ``dm_control.mjcf``: dm_control
writes an attached model's names with its scoping separator (``robot/base``, default classes
``/`` and ``ped_00/``), which its own parser refuses. In the exported scene the floor, walls,
obstacles and pedestrians keep contype 0 (they never collide with each other) and have
conaffinity 1, so any geom with contype bit 1 (MuJoCo's default) collides with them. The format
is documented on mjnav's export page.
"""

from __future__ import annotations

import xml.etree.ElementTree as ET
from pathlib import Path
import mujoco
import numpy as np
from dm_control import mjcf

from mjnav.config import TaskConfig
from mjnav.entities.arena import SCENE_CONAFFINITY
from mjnav.entities.robot import OmniRobot
from mjnav.sim import NavSim
from mjnav.world.layout import Layout

__all__ = ["bake_layout", "export_world", "record_episode", "robot_mjcf", "sanitize_mjcf", "write_mjcf"]

#: Digits of the floats written to XML (dm_control's default: doubles round-trip exactly).
XML_PRECISION = 17
#: dm_control's scoping separator: it may not appear in a name or class that its parser reads.
_SCOPE = "/"


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
    ``qpos`` still reads world coordinates and ``qpos0`` is the start. The floor and the scene
    geoms get conaffinity 1 (contype stays 0), so that bodies added to the scene collide with
    them; the robot's explicit contact pairs stay, named ``robot_<wall, obstacle slot or
    pedestrian>`` (MuJoCo does not repeat a pair's contacts in its dynamic search). mjnav's own
    simulation never sees these changes: only this copy of the MJCF is exported.

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
    for geom in [sim.arena.floor, *sim.scene_geoms]:
        geom.conaffinity = SCENE_CONAFFINITY
    root = sim.mjcf_model
    for pair in root.contact.pair:
        other = pair.geom2
        pair.name = f"robot_{other.name if other.root is root else other.root.model}"
    return root


def sanitize_mjcf(xml: str) -> str:
    """The same model with names and default classes that every MJCF reader accepts.

    Names holding dm_control's scoping separator ``/`` get ``_`` instead (``robot/ray_000`` ->
    ``robot_ray_000``, the attachment body ``ped_00/`` -> ``ped_00_``; a leading separator is
    dropped, a clash with an existing name gets a ``_1`` suffix), everywhere they are referenced.
    Default classes without settings of their own (dm_control writes one per attached model)
    are removed and their users take the class they inherit from. Everything else, floats
    included, is kept as written, so the compiled model differs only in its names.

    Args:
        xml: MJCF text (as ``mjcf.RootElement.to_xml_string`` writes it).

    Returns:
        The sanitized MJCF text.
    """
    return _sanitize(xml)[0]


def _sanitize(xml: str) -> tuple[str, dict[str, str]]:
    """:func:`sanitize_mjcf`, also returning the map of renamed names (old -> new)."""
    root = ET.fromstring(xml)
    _fold_empty_classes(root)
    renamed = _safe_names(root)
    for element in root.iter():
        for key, value in element.attrib.items():
            tokens = value.split()
            if any(token in renamed for token in tokens):  # references, incl. lists such as flex bodies
                element.set(key, " ".join(renamed.get(token, token) for token in tokens))
    ET.indent(root, space="  ")
    return ET.tostring(root, encoding="unicode") + "\n", renamed


def _fold_empty_classes(root: ET.Element) -> None:
    """Removes default classes without settings; their users take the class they inherit from."""
    top = root.find("default")
    if top is None:
        return
    equal: dict[str, str | None] = {}  # class -> the nearest class with settings (None: main)
    _resolve_classes(top, None, equal)
    empty = {name for name, target in equal.items() if target != name}
    _retarget_classes(root, equal, empty, inside_childclass=False)
    for parent in reversed(list(top.iter("default"))):  # children first: nested empties are gone
        for child in parent.findall("default"):
            if child.get("class") in empty:  # its nested classes inherit the same settings from here
                at = list(parent).index(child)
                parent.remove(child)
                parent[at:at] = list(child)
    if len(top) == 0:
        root.remove(top)


def _resolve_classes(node: ET.Element, inherited: str | None, equal: dict[str, str | None]) -> None:
    """Fills ``equal`` for the classes under ``node`` (whose settings are those of ``inherited``)."""
    for child in node.findall("default"):
        name = child.get("class", "")
        own = any(item.tag != "default" for item in child)
        equal[name] = name if own else inherited
        _resolve_classes(child, equal[name], equal)


def _retarget_classes(node: ET.Element, equal: dict[str, str | None], empty: set[str],
                      inside_childclass: bool) -> None:
    """Points ``class``/``childclass`` attributes at the class they equal (recursive)."""
    for child in node:
        if child.tag == "default":
            continue
        for key in ("class", "childclass"):
            name = child.get(key)
            if name in empty:
                target = equal[name]
                if target is not None:
                    child.set(key, target)
                elif inside_childclass:
                    child.set(key, "main")  # an outer childclass would otherwise apply
                else:
                    del child.attrib[key]
        _retarget_classes(child, equal, empty, inside_childclass or "childclass" in child.attrib)


def _safe_names(root: ET.Element) -> dict[str, str]:
    """New names (old -> new) for every name or class holding the scoping separator."""
    names = {value for element in root.iter() for key, value in element.attrib.items()
             if key == "name" or (key == "class" and element.tag == "default")}
    taken, renamed = set(names), {}
    for old in sorted(name for name in names if _SCOPE in name):
        base = old.lstrip(_SCOPE).replace(_SCOPE, "_") or "root"
        new, k = base, 0
        while new in taken:
            k += 1
            new = f"{base}_{k}"
        taken.add(new)
        renamed[old] = new
    return renamed


def write_mjcf(root: mjcf.RootElement, out_dir: str | Path, file_name: str) -> tuple[Path, dict[str, str]]:
    """Writes ``root`` as sanitized MJCF (:func:`sanitize_mjcf`) plus its asset files into ``out_dir``.

    Args:
        root: The MJCF model.
        out_dir: Existing output folder.
        file_name: XML file name (``scene.xml``).

    Returns:
        The XML path and the names that were renamed (dm_control name -> written name).
    """
    out = Path(out_dir)
    for name, contents in root.get_assets().items():
        (out / name).write_bytes(contents if isinstance(contents, bytes) else contents.encode())
    xml, renamed = _sanitize(root.to_xml_string(precision=XML_PRECISION))
    path = out / file_name
    path.write_text(xml, encoding="utf-8")
    return path, renamed


def robot_mjcf(config: TaskConfig | None = None, *, rangefinders: bool = True) -> str:
    """mjnav's robot as a standalone MJCF, to attach into another world (dm_control or MjSpec).

    One body ``base`` at LiDAR height with slide joints ``x`` and ``y`` (world axes; ``qpos`` is
    the displacement from where the model is attached), the cylinder ``disc`` (contype 1,
    conaffinity 0: it collides with every geom of conaffinity bit 1, MuJoCo's default), force
    motors ``force_x``/``force_y`` (N, clipped to ``robot.force_max``), the ``follow`` camera and,
    with ``rangefinders``, sites and rangefinder sensors ``ray_000`` ... (beam i at
    i·360°/beams from +x, counter-clockwise; -1 when nothing is hit).

    Args:
        config: The task whose ``robot`` and ``lidar`` sections build it (default ``TaskConfig()``).
        rangefinders: Include the per-beam sites and sensors.

    Returns:
        The MJCF text (model name ``robot``).
    """
    if config is None:
        config = TaskConfig()
    robot = OmniRobot(config.robot, config.lidar, rangefinders=rangefinders)
    return sanitize_mjcf(robot.mjcf_model.to_xml_string(precision=XML_PRECISION))


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
    scene, renamed = write_mjcf(baked, out, "scene.xml")
    model = physics.model.ptr
    bodies = np.argsort(np.where(model.body_mocapid >= 0, model.body_mocapid, np.iinfo(np.int32).max))
    names = [mujoco.mj_id2name(model, mujoco.mjtObj.mjOBJ_BODY, int(b)) for b in bodies[: model.nmocap]]
    np.savez(out / "trajectory.npz", **record, mocap_names=np.asarray([renamed.get(n, n) for n in names]),
             seed=np.int64(seed), task=np.asarray(getattr(config, "name", "custom")))
    return scene
