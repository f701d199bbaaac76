"""Drawing a navigation scene off-screen: views, cameras, overlays and captions.

:class:`OffscreenView` opens its own GL context (backend from :func:`mjnav.viz.gl.select_gl_backend`:
EGL, else OSMesa), so it works whatever MuJoCo chose at import, and renders the arena's top-down
camera (``view=top``), the robot-following camera (``track``) or both, with overlays added as
``mjvScene`` user geoms (:func:`make_drawer`):

* the free-space polygon of the step (cyan capsules; grey when the region failed),
* Q_s (orange sphere), Q_l (magenta sphere), the MPC's predicted trajectory (blue), the goal
  (green sphere and its 0.7 m tolerance disc), optionally every 6th LiDAR ray (red lines).

Baselines draw their own points when they expose ``planner.debug`` (``mpc_goal``). A caption
(time, speed, outcome) is drawn onto each frame with matplotlib's Agg canvas (:class:`Captioner`).
The Gymnasium environment renders with this module; :mod:`mjnav.eval.render` writes whole
episodes to MP4.
"""

from __future__ import annotations

import atexit
import dataclasses
import importlib
import weakref
from collections.abc import Callable, Sequence
from typing import TYPE_CHECKING, Any

import mujoco
import numpy as np

__all__ = ["Captioner", "OffscreenView", "RenderConfig", "camera_ids", "make_drawer", "render_frame"]

if TYPE_CHECKING:
    from dm_control import mjcf

    from mjnav.tasks.nav import CrowdNavTask

_Z = 0.05  # m: overlay height above the floor


@dataclasses.dataclass(frozen=True)
class RenderConfig:
    """What to render.

    Attributes:
        view: ``top``, ``track`` or ``both``.
        width: Width of one view, pixels (≤ the model's offscreen width, 640).
        height: Height of one view, pixels (≤ 480).
        max_frames: Stop after this many frames (None: the whole episode).
        rays: Draw every 6th LiDAR ray.
    """

    view: str = "top"
    width: int = 480
    height: int = 480
    max_frames: int | None = None
    rays: bool = False

    def __post_init__(self) -> None:
        """Raises ValueError on an unknown view or a size MuJoCo's default offscreen buffer cannot hold."""
        if self.view not in ("top", "track", "both"):
            raise ValueError(f"view: expected top, track or both, got {self.view!r}")
        if not (1 <= self.width <= 640 and 1 <= self.height <= 480):
            raise ValueError(f"width x height: must be within 640 x 480 pixels, got {self.width} x {self.height}")
        if self.max_frames is not None and self.max_frames < 1:
            raise ValueError(f"frames: must be >= 1, got {self.max_frames}")


class OffscreenView:
    """An off-screen MuJoCo render target with its own GL context."""

    def __init__(
        self, model: mujoco.MjModel, width: int, height: int, backend: str, max_geom: int = 4000
    ) -> None:
        """Open the context and the scene for ``model`` (an ``mujoco.MjModel``)."""
        self._mj = mujoco
        self.width, self.height = width, height
        self._ctx = importlib.import_module(f"mujoco.{backend}").GLContext(width, height)
        self._ctx.make_current()
        self._con = mujoco.MjrContext(model, mujoco.mjtFontScale.mjFONTSCALE_150)
        # Freed by close(), when the view is collected, or at interpreter exit before MuJoCo's own
        # exit hook terminates the EGL display (registered later, so run earlier): an unclosed
        # environment otherwise printed an EGLError traceback from GLContext.__del__ at exit.
        self._free = weakref.finalize(self, _free_gl, self._con, self._ctx)
        atexit.register(self._free)
        mujoco.mjr_setBuffer(mujoco.mjtFramebuffer.mjFB_OFFSCREEN, self._con)
        self.scene = mujoco.MjvScene(model, maxgeom=max_geom)
        self._opt, self._cam = mujoco.MjvOption(), mujoco.MjvCamera()
        self._model = model

    def render(self, data: mujoco.MjData, camera_id: int, draw: Callable | None = None) -> np.ndarray:
        """(height, width, 3) uint8 image from a fixed camera; ``draw(scene)`` adds user geoms."""
        mj = self._mj
        self._ctx.make_current()
        self._cam.type, self._cam.fixedcamid = mj.mjtCamera.mjCAMERA_FIXED, camera_id
        mj.mjv_updateScene(self._model, data, self._opt, None, self._cam, mj.mjtCatBit.mjCAT_ALL, self.scene)
        if draw is not None:
            draw(self.scene)
        rect = mj.MjrRect(0, 0, self.width, self.height)
        mj.mjr_render(rect, self.scene, self._con)
        image = np.empty((self.height, self.width, 3), dtype=np.uint8)
        mj.mjr_readPixels(image, None, rect, self._con)
        return image[::-1].copy()

    def close(self) -> None:
        """Free the GL resources; closing again does nothing."""
        self._free()
        atexit.unregister(self._free)
        self._con = None


def _free_gl(con: mujoco.MjrContext, ctx: Any) -> None:
    """Free a MuJoCo render context, then its GL context."""
    con.free()
    ctx.free()


class Captioner:
    """Draws one line of text onto the top of frames (matplotlib Agg, no display)."""

    def __init__(self, width: int, bar: int = 26) -> None:
        """A ``bar``-pixel high caption strip for frames ``width`` pixels wide."""
        # deferred: matplotlib costs ~1 s at import (python -X importtime) and the environment's own
        # render() draws no caption
        from matplotlib.backends.backend_agg import FigureCanvasAgg
        from matplotlib.figure import Figure

        self.bar = bar
        self._fig = Figure(figsize=(width / 100, bar / 100), dpi=100)
        self._canvas = FigureCanvasAgg(self._fig)
        self._fig.patch.set_alpha(0.0)
        self._text = self._fig.text(0.01, 0.5, "", va="center", ha="left", color="white", fontsize=11,
                                    family="monospace")

    def __call__(self, frame: np.ndarray, text: str) -> np.ndarray:
        """The frame with ``text`` on a darkened top strip."""
        self._text.set_text(text)
        self._canvas.draw()
        rgba = np.asarray(self._canvas.buffer_rgba())[: self.bar, : frame.shape[1]]
        out = frame.copy()
        strip = out[: rgba.shape[0], : rgba.shape[1]].astype(np.float32) * 0.45
        alpha = rgba[..., 3:4].astype(np.float32) / 255.0
        out[: rgba.shape[0], : rgba.shape[1]] = (strip * (1 - alpha) + rgba[..., :3] * alpha).astype(np.uint8)
        return out


# ---------------------------------------------------------------------------- overlays


def _add(scene: mujoco.MjvScene, kind: int, size: Sequence[float], pos: Sequence[float],
         rgba: Sequence[float]) -> mujoco.MjvGeom | None:
    if scene.ngeom >= scene.maxgeom:
        return None
    geom = scene.geoms[scene.ngeom]
    mujoco.mjv_initGeom(geom, kind, np.asarray(size, float), np.asarray(pos, float), np.eye(3).ravel(),
                        np.asarray(rgba, np.float32))
    scene.ngeom += 1
    return geom


def _segment(scene: mujoco.MjvScene, a: np.ndarray, b: np.ndarray, width: float, rgba: Sequence[float],
             kind: int | None = None) -> None:
    kind = mujoco.mjtGeom.mjGEOM_CAPSULE if kind is None else kind
    geom = _add(scene, kind, [width, 0, 0], [0, 0, 0], rgba)
    if geom is not None:
        mujoco.mjv_connector(geom, kind, width, np.array([a[0], a[1], _Z]), np.array([b[0], b[1], _Z]))


def _polyline(
    scene: mujoco.MjvScene, points: np.ndarray, width: float, rgba: Sequence[float], closed: bool
) -> None:
    pts = np.asarray(points, float)
    ends = len(pts) if closed else len(pts) - 1
    for i in range(max(ends, 0)):
        _segment(scene, pts[i], pts[(i + 1) % len(pts)], width, rgba)


def _sphere(scene: mujoco.MjvScene, p: np.ndarray, radius: float, rgba: Sequence[float]) -> None:
    _add(scene, mujoco.mjtGeom.mjGEOM_SPHERE, [radius, 0, 0], [p[0], p[1], _Z + radius], rgba)


def _overlay_points(task: CrowdNavTask) -> dict[str, Any]:
    record, planner = task.core.record, task.planner
    debug = getattr(getattr(planner, "planner", planner), "debug", None) or {}
    if record is None:
        return {}
    own = planner is None
    return {
        "polygon": record.polygon,
        "q_s": record.q_s if own else debug.get("q_s"),
        "q_l": record.q_l if own else debug.get("q_l"),
        "predicted": record.predicted if own else debug.get("predicted"),
        "region_ok": record.region_ok,
    }


def make_drawer(task: CrowdNavTask, physics: mjcf.Physics, rays: bool) -> Callable[[mujoco.MjvScene], None]:
    """Build the ``draw(scene)`` callback that adds the current step's overlays of ``task``."""
    goal, tol = task.layout.goal, task.config.reward.goal_tolerance
    p = task.sim.robot_state(physics)[0]
    scan = task.sim.scan(physics, noise=False) if rays else None
    pts = _overlay_points(task)

    def draw(scene: mujoco.MjvScene) -> None:
        disc = mujoco.mjtGeom.mjGEOM_CYLINDER
        _add(scene, disc, [tol, 0.005, 0], [goal[0], goal[1], 0.01], [0.1, 0.8, 0.2, 0.25])
        _sphere(scene, goal, 0.12, [0.1, 0.9, 0.2, 1])
        if pts.get("polygon") is not None:
            color = [0.1, 0.9, 0.9, 0.9] if pts["region_ok"] else [0.6, 0.6, 0.6, 0.9]
            _polyline(scene, pts["polygon"], 0.02, color, closed=True)
        if pts.get("predicted") is not None:
            _polyline(scene, np.vstack([p, pts["predicted"]]), 0.03, [0.2, 0.3, 1.0, 1], closed=False)
        for key, color in (("q_s", [1.0, 0.55, 0.0, 1]), ("q_l", [0.9, 0.1, 0.9, 1])):
            if pts.get(key) is not None:
                _sphere(scene, pts[key], 0.09, color)
        if scan is not None:
            angles = 2 * np.pi * np.arange(len(scan)) / len(scan)
            for r, th in zip(scan[::6], angles[::6]):
                _segment(scene, p, p + r * np.array([np.cos(th), np.sin(th)]), 1.0, [1, 0.2, 0.2, 0.5],
                         kind=mujoco.mjtGeom.mjGEOM_LINE)

    return draw


# ---------------------------------------------------------------------------- frames


def camera_ids(task: CrowdNavTask, physics: mjcf.Physics, view: str) -> list[int]:
    """MuJoCo ids of the cameras of ``view`` (``top``, ``track`` or ``both``)."""
    sim = task.sim
    top = int(physics.bind(sim.arena.top_camera).element_id)
    track = int(physics.bind(sim.robot.camera).element_id)
    return {"top": [top], "track": [track], "both": [top, track]}[view]


def render_frame(task: CrowdNavTask, physics: mjcf.Physics, views: list[OffscreenView], cams: list[int],
                 captioner: Captioner, rays: bool, outcome: str) -> np.ndarray:
    """One captioned frame: the views side by side with the overlays, time, speed and ``outcome``."""
    draw = make_drawer(task, physics, rays)
    image = np.hstack([v.render(physics.data.ptr, c, draw) for v, c in zip(views, cams)])
    v = task.sim.robot_state(physics)[1]
    t = task.core.steps * task.config.timing.control_period
    return captioner(image, f"t={t:5.1f} s  speed={np.hypot(*v):4.2f} m/s  {outcome}")
