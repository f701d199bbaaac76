"""``NavArena``: walled floor, top-down camera and static obstacle slots (spec §9).

The arena is compiled once per environment. Every shape of the task's
:class:`~mjnav.world.shapes.ShapeBank` becomes one extruded-prism mesh asset; the
``ObstacleConfig.num_slots`` obstacle geoms are mesh geoms in the worldbody whose mesh is chosen
per episode by writing ``geom_dataid`` (the "slot" mechanism), so a new layout never recompiles.

MuJoCo re-centres every mesh at compile time: vertices are stored in the mesh's inertial frame
(``model.mesh_pos``/``mesh_quat`` give that frame in the asset frame) and a geom's pose is the
pose of that frame. Placing shape ``s`` with its local (circle-centre) frame at ``(x, y, yaw)``
therefore writes ``geom_pos = (x, y, 0) + R(yaw) mesh_pos[s]`` and ``geom_quat = q(yaw) ⊗
mesh_quat[s]``, plus the per-mesh bounds MuJoCo would have compiled (``geom_size``: ray box,
``geom_aabb``, ``geom_rbound``). Moving worldbody geoms also stales the worldbody's bounding
volume hierarchy (``bvh_aabb``, used by the collision midphase and ``mj_multiRay``), so it is
refitted bottom-up after every placement. Parked slots sit far below the floor: no collision
(the robot cannot reach them) and no horizontal LiDAR ray can hit them.
"""

from __future__ import annotations

import dataclasses

import mujoco
import numpy as np
from dm_control import composer, mjcf

from mjnav.schema import ArenaConfig, ObstacleConfig
from mjnav.world.shapes import ShapeBank, make_shape_bank

__all__ = ["PARK_DEPTH", "NavArena", "body_bvh_order", "prism_mesh", "quat_to_mat", "refit_body_bvh"]

#: Parked items (obstacle slots, pedestrians) sit this far below the floor, metres.
PARK_DEPTH = 100.0
#: Contact bits: only the robot (contype 1) collides; everything else has conaffinity 1 (NavSim
#: sets it to 0 and lists the robot's contacts as explicit pairs; exported scenes have it back).
SCENE_CONTYPE, SCENE_CONAFFINITY = 0, 1
_WALL_RGBA = (0.55, 0.55, 0.6, 1.0)
_OBSTACLE_RGBA = (0.85, 0.45, 0.2, 1.0)


def prism_mesh(polygon: np.ndarray, height: float) -> tuple[np.ndarray, np.ndarray]:
    """Vertices and outward-facing triangles of a convex polygon extruded from z = 0 to height.

    Args:
        polygon: (n, 2) counter-clockwise vertices, metres.
        height: Prism height, metres.

    Returns:
        ``(2n, 3)`` vertices (bottom ring, then top ring) and ``(4n - 4, 3)`` int faces.
    """
    n = len(polygon)
    ring = np.asarray(polygon, dtype=np.float64)
    verts = np.vstack([np.c_[ring, np.zeros(n)], np.c_[ring, np.full(n, height)]])
    faces = [(0, i + 1, i) for i in range(1, n - 1)] + [(n, n + i, n + i + 1) for i in range(1, n - 1)]
    for i in range(n):
        j = (i + 1) % n
        faces += [(i, j, n + j), (i, n + j, n + i)]
    return verts, np.asarray(faces, dtype=np.int64)


@dataclasses.dataclass
class _SlotCache:
    """Per-physics ids and per-mesh compiled data of the obstacle slots."""

    model: mujoco.MjModel
    geom_ids: np.ndarray  # (slots,)
    mesh_ids: np.ndarray  # (B,) model mesh id of bank shape b
    mesh_pos: np.ndarray  # (B, 3)
    mesh_quat: np.ndarray  # (B, 4)
    size: np.ndarray  # (B, 3)
    aabb: np.ndarray  # (B, 6)
    rbound: np.ndarray  # (B,)
    rings: list[np.ndarray]  # B arrays (2, n, 3): bottom and top rings in the mesh frame
    bvh_order: np.ndarray  # worldbody BVH nodes, children before parents
    bvh_leaf_geom: np.ndarray  # geom id of each node (-1 for inner nodes)


class NavArena(composer.Arena):
    """Walled rectangle (interior centred on the origin), lights, cameras and obstacle slots."""

    def _build(
        self,
        config: ArenaConfig,
        obstacles: ObstacleConfig | None = None,
        bank: ShapeBank | None = None,
        name: str = "arena",
    ) -> None:
        """Builds the MJCF.

        Args:
            config: Interior size, wall thickness and height, metres.
            obstacles: Obstacle slots and prism height; None means no slots.
            bank: Shapes to compile as meshes; made from ``obstacles`` when None.
            name: MJCF model name.
        """
        super()._build(name=name)
        self._config = config
        self._obstacles = obstacles or ObstacleConfig(count=0, slots=0)
        slots = self._obstacles.num_slots
        self._bank = bank if bank is not None or slots == 0 else make_shape_bank(self._obstacles)
        root = self._mjcf_root
        root.compiler.angle = "radian"
        root.visual.quality.shadowsize = 4096
        self._add_floor_and_walls(config)
        self._add_lights_and_camera(config)
        self._meshes = self._add_meshes() if slots else []
        self._slots = [self._add_slot(i) for i in range(slots)]
        self._cache: _SlotCache | None = None
        self._shapes = np.zeros(0, np.int64)

    # ------------------------------------------------------------------ MJCF
    def _add_floor_and_walls(self, config: ArenaConfig) -> None:
        root = self._mjcf_root
        hx, hy = 0.5 * config.size[0], 0.5 * config.size[1]
        t, h = config.wall_thickness, config.wall_height
        grid = root.asset.add("texture", name="grid", type="2d", builtin="checker", width=512, height=512,
                              rgb1=(0.22, 0.25, 0.3), rgb2=(0.27, 0.3, 0.35))
        mat = root.asset.add("material", name="floor", texture=grid, texrepeat=(hx, hy), reflectance=0.05)
        self._floor = root.worldbody.add("geom", name="floor", type="plane", size=(hx + t, hy + t, 0.1),
                                         material=mat, contype=0, conaffinity=0)
        spans = {  # name: (centre, half sizes); x walls span the corners
            "wall_px": ((hx + t / 2, 0.0), (t / 2, hy + t)),
            "wall_nx": ((-hx - t / 2, 0.0), (t / 2, hy + t)),
            "wall_py": ((0.0, hy + t / 2), (hx, t / 2)),
            "wall_ny": ((0.0, -hy - t / 2), (hx, t / 2)),
        }
        self._walls = [
            root.worldbody.add("geom", name=wall, type="box", pos=(c[0], c[1], h / 2),
                               size=(s[0], s[1], h / 2), rgba=_WALL_RGBA,
                               contype=SCENE_CONTYPE, conaffinity=SCENE_CONAFFINITY)
            for wall, (c, s) in spans.items()
        ]

    def _add_lights_and_camera(self, config: ArenaConfig) -> None:
        root = self._mjcf_root
        extent = 0.5 * max(config.size) + config.wall_thickness + 0.5
        fovy = 45.0
        height = extent / np.tan(np.deg2rad(fovy / 2))
        root.worldbody.add("light", name="sun", pos=(0, 0, height), dir=(0, 0, -1), directional=True,
                           diffuse=(0.6, 0.6, 0.6), castshadow=False)
        root.worldbody.add("light", name="spot", pos=(0, 0, 6), dir=(0, 0, -1), diffuse=(0.3, 0.3, 0.3))
        self._top_camera = root.worldbody.add("camera", name="top", pos=(0, 0, height), quat=(1, 0, 0, 0),
                                              fovy=fovy)
        root.statistic.center = (0, 0, 0)
        root.statistic.extent = 2 * extent

    def _add_meshes(self) -> list[mjcf.Element]:
        height = self._obstacles.height
        meshes = []
        for b in range(len(self._bank)):
            verts, faces = prism_mesh(self._bank.polygon(b), height)
            meshes.append(self._mjcf_root.asset.add("mesh", name=f"shape_{b:03d}", vertex=verts.ravel(),
                                                    face=faces.ravel()))
        return meshes

    def _add_slot(self, index: int) -> mjcf.Element:
        return self._mjcf_root.worldbody.add(
            "geom", name=f"obstacle_{index:02d}", type="mesh", mesh=self._meshes[0],
            pos=(3.0 * index, 0.0, -PARK_DEPTH), rgba=_OBSTACLE_RGBA,
            contype=SCENE_CONTYPE, conaffinity=SCENE_CONAFFINITY,
        )

    # ------------------------------------------------------------------ properties
    @property
    def config(self) -> ArenaConfig:
        """The arena config."""
        return self._config

    @property
    def bank(self) -> ShapeBank | None:
        """The compiled shape bank (None without slots)."""
        return self._bank

    @property
    def floor(self) -> mjcf.Element:
        """The floor plane geom."""
        return self._floor

    @property
    def walls(self) -> list[mjcf.Element]:
        """The four wall box geoms."""
        return list(self._walls)

    @property
    def obstacle_slots(self) -> list[mjcf.Element]:
        """The obstacle slot mesh geoms."""
        return list(self._slots)

    @property
    def meshes(self) -> list[mjcf.Element]:
        """One prism mesh asset per bank shape."""
        return list(self._meshes)

    @property
    def top_camera(self) -> mjcf.Element:
        """Top-down camera covering the whole arena."""
        return self._top_camera

    # ------------------------------------------------------------------ runtime
    def set_obstacles(self, physics: mjcf.Physics, shapes: np.ndarray, poses: np.ndarray) -> None:
        """Places the first K slots (bank ``shapes`` at ``poses``), parks the rest, refits the BVH.

        Args:
            physics: The compiled physics.
            shapes: (K,) bank indices, K <= slots.
            poses: (K, 3) ``(x, y, yaw)`` of each shape's local frame, metres and radians.
        """
        shapes = np.asarray(shapes, dtype=np.int64).reshape(-1)
        poses = np.asarray(poses, dtype=np.float64).reshape(-1, 3)
        if len(shapes) > len(self._slots):
            raise ValueError(f"{len(shapes)} obstacles do not fit {len(self._slots)} slots")
        if not self._slots:
            return
        cache = self._bind(physics)
        model = cache.model
        ids = cache.geom_ids
        pos, quat = _compose_poses(poses, cache.mesh_pos[shapes], cache.mesh_quat[shapes])
        park = len(ids) - len(shapes)
        chosen = np.concatenate([shapes, np.zeros(park, np.int64)])  # parked slots keep mesh 0
        model.geom_dataid[ids] = cache.mesh_ids[chosen]
        model.geom_pos[ids] = np.vstack([pos, _park_positions(park)])
        model.geom_quat[ids] = np.vstack([quat, np.tile([1.0, 0.0, 0.0, 0.0], (park, 1))])
        model.geom_size[ids] = cache.size[chosen]
        model.geom_aabb[ids] = cache.aabb[chosen]
        model.geom_rbound[ids] = cache.rbound[chosen]
        self._shapes = shapes.copy()
        refit_body_bvh(model, cache.bvh_order, cache.bvh_leaf_geom)

    def obstacle_polygons(self, physics: mjcf.Physics, height: float) -> list[np.ndarray]:
        """World-frame cross-sections of the placed prisms at ``height``, as MuJoCo compiled them.

        The compiled mesh vertices are float32, so these polygons differ from the layout's
        float64 polygons by ~1e-7 m; both LiDAR backends use these so that they agree exactly.

        Args:
            physics: The physics after :meth:`set_obstacles` and a kinematics pass (``geom_xmat``).
            height: Cross-section height above the floor, metres.

        Returns:
            K (n, 2) counter-clockwise vertex arrays.
        """
        if not self._slots:
            return []
        cache = self._bind(physics)
        data = physics.data.ptr
        frac = height / self._obstacles.height
        out = []
        for slot, shape in enumerate(self._shapes):
            gid = cache.geom_ids[slot]
            rot = data.geom_xmat[gid].reshape(3, 3)
            world = data.geom_xpos[gid] + cache.rings[shape] @ rot.T  # (2, n, 3): bottom, top ring
            out.append(((1.0 - frac) * world[0] + frac * world[1])[:, :2].copy())
        return out

    def _bind(self, physics: mjcf.Physics) -> _SlotCache:
        model = physics.model.ptr
        if self._cache is None or self._cache.model is not model:
            self._cache = self._make_cache(physics, model)
        return self._cache

    def _make_cache(self, physics: mjcf.Physics, model: mujoco.MjModel) -> _SlotCache:
        mesh_ids = np.asarray(physics.bind(self._meshes).element_id, dtype=np.int64)
        size, aabb, rbound, rings = [], [], [], []
        for b, mid in enumerate(mesh_ids):
            adr, num = model.mesh_vertadr[mid], model.mesh_vertnum[mid]
            verts = model.mesh_vert[adr:adr + num].astype(np.float64)
            lo, hi = verts.min(0), verts.max(0)
            size.append(np.maximum(-lo, hi))
            aabb.append(np.r_[(lo + hi) / 2, (hi - lo) / 2])
            rbound.append(np.linalg.norm(size[-1]))
            n = int(self._bank.counts[b])
            rings.append(verts[: 2 * n].reshape(2, n, 3))
        order, leaf_geom = body_bvh_order(model, 0)
        return _SlotCache(
            model=model,
            geom_ids=np.asarray(physics.bind(self._slots).element_id, dtype=np.int64),
            mesh_ids=mesh_ids,
            mesh_pos=model.mesh_pos[mesh_ids].copy(),
            mesh_quat=model.mesh_quat[mesh_ids].copy(),
            size=np.asarray(size), aabb=np.asarray(aabb), rbound=np.asarray(rbound), rings=rings,
            bvh_order=order, bvh_leaf_geom=leaf_geom,
        )


def _park_positions(count: int) -> np.ndarray:
    """(count, 3) distinct parking spots far below the floor."""
    return np.c_[3.0 * np.arange(count), np.zeros(count), np.full(count, -PARK_DEPTH)]


def _compose_poses(
    poses: np.ndarray, mesh_pos: np.ndarray, mesh_quat: np.ndarray
) -> tuple[np.ndarray, np.ndarray]:
    """Geom pos/quat that put each mesh's asset frame at the planar pose ``(x, y, yaw)``."""
    c, s = np.cos(poses[:, 2]), np.sin(poses[:, 2])
    pos = np.c_[poses[:, 0] + c * mesh_pos[:, 0] - s * mesh_pos[:, 1],
                poses[:, 1] + s * mesh_pos[:, 0] + c * mesh_pos[:, 1], mesh_pos[:, 2]]
    return pos, _yaw_times(poses[:, 2], mesh_quat)


def body_bvh_order(model: mujoco.MjModel, body: int) -> tuple[np.ndarray, np.ndarray]:
    """A body's BVH node ids (children before parents) and each node's geom id (-1 inner).

    Args:
        model: Compiled model.
        body: Body id.

    Returns:
        ``(order, leaf_geom)``: absolute node ids in post-order, and per node (same order) the
        absolute geom id for leaves or -1.
    """
    adr, num = int(model.body_bvhadr[body]), int(model.body_bvhnum[body])
    if adr < 0 or num == 0:
        return np.zeros(0, np.int64), np.zeros(0, np.int64)
    order: list[int] = []
    stack = [(0, False)]
    while stack:
        node, expanded = stack.pop()
        children = [c for c in model.bvh_child[adr + node] if c >= 0]
        if expanded or not children:
            order.append(node)
            continue
        stack.append((node, True))
        stack.extend((c, False) for c in children)
    leaf = model.bvh_nodeid[adr + np.asarray(order)]  # absolute geom ids, -1 for inner nodes
    return adr + np.asarray(order, dtype=np.int64), leaf.astype(np.int64)


def refit_body_bvh(model: mujoco.MjModel, order: np.ndarray, leaf_geom: np.ndarray) -> None:
    """Recomputes a static body's BVH boxes from its geoms' current model poses and ``geom_aabb``.

    Leaves become the axis-aligned box of the geom's oriented ``geom_aabb``; inner nodes the
    union of their children. Only valid for bodies at the world origin (the worldbody).

    Args:
        model: Model to update in place (``bvh_aabb``).
        order: Absolute node ids, children before parents (:func:`body_bvh_order`).
        leaf_geom: Geom id per node of ``order``, -1 for inner nodes.
    """
    if not len(order):
        return
    boxes = model.bvh_aabb
    leaf = leaf_geom >= 0
    geoms = leaf_geom[leaf]
    mats = quat_to_mat(model.geom_quat[geoms])
    local = model.geom_aabb[geoms]
    boxes[order[leaf], :3] = model.geom_pos[geoms] + np.einsum("nij,nj->ni", mats, local[:, :3])
    boxes[order[leaf], 3:] = np.einsum("nij,nj->ni", np.abs(mats), local[:, 3:])
    root = order[-1]  # children are stored relative to the body's root node
    for node in order[~leaf]:
        kids = root + model.bvh_child[node][model.bvh_child[node] >= 0]
        lo = (boxes[kids, :3] - boxes[kids, 3:]).min(axis=0)
        hi = (boxes[kids, :3] + boxes[kids, 3:]).max(axis=0)
        boxes[node, :3], boxes[node, 3:] = (lo + hi) / 2, (hi - lo) / 2


def quat_to_mat(quat: np.ndarray) -> np.ndarray:
    """(N, 3, 3) rotation matrices of (N, 4) unit quaternions ``(w, x, y, z)``."""
    w, x, y, z = np.moveaxis(np.asarray(quat, dtype=np.float64), -1, 0)
    return np.stack([
        np.stack([1 - 2 * (y * y + z * z), 2 * (x * y - w * z), 2 * (x * z + w * y)], -1),
        np.stack([2 * (x * y + w * z), 1 - 2 * (x * x + z * z), 2 * (y * z - w * x)], -1),
        np.stack([2 * (x * z - w * y), 2 * (y * z + w * x), 1 - 2 * (x * x + y * y)], -1),
    ], -2)


def _yaw_times(yaw: np.ndarray, quat: np.ndarray) -> np.ndarray:
    """(N, 4) products q(yaw) ⊗ quat (rotation about +z first applied last)."""
    c, s = np.cos(yaw / 2), np.sin(yaw / 2)
    w, x, y, z = quat.T
    return np.stack([c * w - s * z, c * x - s * y, c * y + s * x, c * z + s * w], axis=1)
