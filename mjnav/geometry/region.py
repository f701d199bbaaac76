"""Convex obstacle-free region from a LiDAR scan (GALAXY, Zhong et al.; spec §3).

:func:`compute_region` turns one scan into a convex polygon around the robot, in the robot frame
(metres), that contains no scan point shrunk by the safety inflation: a configuration space for
the robot's centre. Steps (spec §3):

1. shrink every beam by ``inflation`` (clipped at 0) and flip the points spherically with radius
   ``flip_radius``;
2. the original points whose flips are hull vertices form the visible star set ``vertexs``;
3. hull of ``vertexs``; fail unless the origin is strictly inside;
4. push each hull edge inward to the dented-in star vertices between its ends (+``push``);
5. intersect the half-planes (dual hull of ``n / c``); vertices clockwise;
6. thin to a vertex subset when there are more than ``max_vertices`` (polar step > 2π/60);
7. fail unless the origin is strictly inside the final polygon;
8. resample the boundary to ``num_points`` (r, θ) points, CCW, θ ascending from the smallest.

Conventions and documented choices:

* Ranges above ``max_range`` and below 0 are clipped into ``[0, max_range]``; non-finite ranges
  raise ``ValueError`` naming the beam indices (the LiDAR never produces them).
* A shrunk point within 1e-6 m of the origin is skipped by the flip (spec) but it puts the
  origin on an obstacle, so the scan fails (status ``touching``): the region must never hold a
  shrunk scan point strictly inside.
* Step 6 also applies when more than ``num_points`` vertices remain (``max_vertices`` = 61 would
  otherwise leave 61 vertices for 60 boundary points); the thinned rule yields at most 60.
* On failure (``on_failure='paper'``) the boundary is every ``n/num_points``-th beam's shrunk
  point (beams 0, 6, 12, ... for 360 beams): a star polygon, not convex; ``vertices`` is then
  empty and the MPC runs without the polygon constraint (:attr:`Region.constraint_polygon` is
  ``None``). This is the paper's behaviour, and it lets a robot within R_inf of an obstacle
  press on into it.
* ``on_failure='recover'`` (default): the scan still fails (``success`` False, the observation's
  flag stays 0, ``status`` names the failure), but the region is recomputed with less inflation
  so the MPC keeps a convex constraint that holds the robot clear of every scan point
  (``recovered`` True, ``inflation`` the value used; the MPC then plans at most ``recover_speed``
  per axis): first with ``recover_inflation`` (0.275 m =
  robot radius 0.225 + one noise σ), then with ``recover_floor`` (0.235 m), each only while the
  smallest range exceeds it by ``recover_gap``. The levels are fixed, not taken from the current
  clearance, so a robot cannot ratchet closer step by step. Below the floor there is no polygon
  and the task backs the robot away from its nearest returns at ``escape_speed``
  (:func:`mjnav.control.dynamics.escape`) instead of planning unconstrained; a braking MPC
  had left it creeping in at ~1 cm/s.

The pipeline is jitted with numba (``cache=True``); call :func:`warm_up` once at start-up to
pay the compile/cache-load cost (seconds on a cold cache) outside the control loop.
"""

from __future__ import annotations

import dataclasses
import math
from typing import Literal

import numpy as np
from numba import njit

from mjnav.geometry.polygon import graham_scan, monotone_chain
from mjnav.geometry.raycast import beam_trig
from mjnav.schema import check as _check

__all__ = ["STATUS_NAMES", "Region", "RegionConfig", "RegionFinder", "compute_region", "scan_polygon", "warm_up"]

OnFailure = Literal["recover", "paper"]

STATUS_NAMES = (
    "ok",
    "touching",
    "origin_outside_hull",
    "origin_outside_pushed",
    "degenerate",
    "origin_outside_final",
)
_TOUCH = 1e-6  # flip skip radius of spec §3 step 1, metres
_MARGIN = 1e-9  # strictness of "origin strictly inside", metres



@dataclasses.dataclass(frozen=True)
class RegionConfig:
    """Parameters of the convex region (spec §3).

    Attributes:
        inflation: Safety inflation R_inf subtracted from every range, metres.
        margin: Extra clearance kept beyond ``inflation`` while it can be, metres (not in the paper;
            0 gives the paper's region): the region is first computed at ``inflation + margin``
            and, where that fails, at ``inflation`` as a normal success, before any failure or
            recovery. The collision rule and rewards keep R_inf = ``inflation``; the observation
            adds R_inf back to the boundary, so with a margin the policy sees the tighter polygon.
        flip_radius: Spherical-flip radius R, metres (must exceed ``max_range``).
        num_points: Resampled boundary points rnum_v.
        max_vertices: Thinning threshold on the polygon's vertex count.
        max_range: LiDAR range; readings are clipped into ``[0, max_range]``, metres.
        push: Slack added to every pushed half-plane (spec step 4), metres.
        on_failure: ``recover`` (default: a reduced-inflation convex region, see the module
            docstring) or ``paper`` (no polygon, the MPC runs unconstrained).
        recover_inflation: First inflation of the recovery ladder, metres.
        recover_floor: Second and last inflation of the recovery ladder, metres.
        recover_gap: A ladder level is tried only while the smallest range exceeds it by this, metres.
        escape_speed: Below the last level the robot backs away from its nearest returns at this
            speed (m/s) instead of planning (:func:`mjnav.control.dynamics.escape`).
        recover_speed: Per-axis velocity limit of the MPC while it plans in a recovered region, m/s
            (a faster robot brakes through the MPC's fallback ladder first).
    """

    inflation: float = 0.325
    margin: float = 0.0
    flip_radius: float = 15.0
    num_points: int = 60
    max_vertices: int = 61
    max_range: float = 10.0
    push: float = 1e-6
    on_failure: OnFailure = "recover"
    recover_inflation: float = 0.275
    recover_floor: float = 0.235
    recover_gap: float = 0.01
    escape_speed: float = 0.2
    recover_speed: float = 0.5

    def __post_init__(self) -> None:
        _check(
            math.isfinite(self.inflation) and self.inflation >= 0.0, "inflation", "must be finite and >= 0"
        )
        _check(math.isfinite(self.max_range) and self.max_range > 0.0, "max_range", "must be finite and > 0")
        _check(
            math.isfinite(self.margin) and 0.0 <= self.margin and self.inflation + self.margin < self.max_range,
            "margin", "must be finite, >= 0 and leave inflation + margin below max_range",
        )  # fmt: skip
        _check(
            math.isfinite(self.flip_radius) and self.flip_radius > self.max_range,
            "flip_radius",
            "must exceed max_range",
        )
        _check(self.num_points >= 3, "num_points", "must be >= 3")
        _check(self.max_vertices >= 3, "max_vertices", "must be >= 3")
        _check(math.isfinite(self.push) and 0.0 <= self.push < 1e-3, "push", "must be in [0, 1e-3)")
        _check(self.on_failure in ("recover", "paper"), "on_failure", "must be 'recover' or 'paper'")
        for name in ("recover_inflation", "recover_gap", "recover_floor", "escape_speed", "recover_speed"):
            value = getattr(self, name)
            _check(math.isfinite(value) and value >= 0.0, name, "must be finite and >= 0")


@dataclasses.dataclass(eq=False, slots=True)
class Region:
    """Output of :func:`compute_region` (robot frame, metres; made every step, so not frozen: read-only by convention).

    Attributes:
        vertices: ``(K, 2)`` convex polygon, clockwise, starting at the smallest polar angle;
            ``(0, 2)`` on failure.
        normals: ``(K, 2)`` outward unit normals of the edges ``vertices[j] -> vertices[j+1]``.
        offsets: ``(K,)`` offsets: the polygon is ``normals @ x <= offsets``.
        boundary: ``(num_points, 2)`` boundary points as (r [m], θ [rad] in [0, 2π)), CCW with θ
            ascending; on failure the fallback beams' shrunk points.
        boundary_xy: The same points in Cartesian coordinates.
        success: Whether the region was computed at the configured inflation, or at inflation +
            margin (spec's flag).
        status: One of :data:`STATUS_NAMES` (the first attempt's, also when recovered).
        recovered: The first attempt failed and the polygon comes from the recovery ladder.
        inflation: The inflation the polygon was computed with, metres (NaN without a polygon).
    """

    vertices: np.ndarray
    normals: np.ndarray
    offsets: np.ndarray
    boundary: np.ndarray
    boundary_xy: np.ndarray
    success: bool
    status: str
    recovered: bool = False
    inflation: float = math.nan

    @property
    def has_polygon(self) -> bool:
        """Whether ``vertices``/``normals``/``offsets`` hold a convex polygon (found or recovered)."""
        return self.success or self.recovered

    @property
    def constraint_polygon(self) -> np.ndarray | None:
        """Clockwise vertices for the MPC constraint, or ``None`` when there is no polygon."""
        return self.vertices if self.has_polygon else None


def compute_region(ranges: np.ndarray, angles: np.ndarray, config: RegionConfig | None = None) -> Region:
    """Compute the convex obstacle-free region of one scan (spec §3).

    Args:
        ranges: ``(n,)`` beam ranges in metres (unshrunk; clipped into ``[0, max_range]``).
        angles: ``(n,)`` beam angles in radians in the robot frame (beam 0 along +x, CCW).
        config: Region parameters; defaults to :class:`RegionConfig()`.

    Returns:
        The :class:`Region`; on failure ``success`` is False and the boundary is the fallback.

    Raises:
        ValueError: On shape mismatch, fewer than ``num_points`` beams, a non-numeric dtype, or
            non-finite ranges or angles (the message lists the offending beam indices). Ranges
            below 0 (sensor noise very close to a surface) or above ``max_range`` are clipped.
    """
    cfg = config if config is not None else _DEFAULT
    r, th = _validate(ranges, angles, cfg.num_points)
    return _region(r, th, *beam_trig(th), cfg)


class RegionFinder:
    """:func:`compute_region` for one fixed beam layout, as a LiDAR scanning every step uses it.

    The angles are checked and their trigonometry computed once; each call then checks only
    the ranges. Results equal :func:`compute_region`'s for the same scan.
    """

    def __init__(self, angles: np.ndarray, config: RegionConfig | None = None) -> None:
        """Args: angles: ``(n,)`` beam angles, radians (robot frame); config: region parameters.

        Raises:
            ValueError: On fewer than ``num_points`` beams or non-finite angles.
        """
        self.config = config if config is not None else _DEFAULT
        _, th = _validate(np.zeros(np.size(angles)), angles, self.config.num_points)
        self.angles = th.copy()
        self._trig = beam_trig(self.angles)  # shared by every finder of this layout in the process (never written)

    def __call__(self, ranges: np.ndarray) -> Region:
        """The region of one scan of ``(n,)`` ranges, metres (see :func:`compute_region`).

        Raises:
            ValueError: On a shape other than the angles' or non-finite ranges.
        """
        r = np.asarray(ranges, dtype=np.float64).ravel()
        if r.shape != self.angles.shape:
            raise ValueError(f"ranges: expected {self.angles.shape[0]} beams, got {r.shape}")
        if not math.isfinite(float(r.sum())):
            _validate(r, self.angles, self.config.num_points)  # raises, naming the beams
        return _region(r, self.angles, *self._trig, self.config)


def _region(
    r: np.ndarray, th: np.ndarray, cos: np.ndarray, sin: np.ndarray, ordered: bool, cfg: RegionConfig
) -> Region:
    """The GALAXY pipeline on checked ranges and angles with their trigonometry."""
    # with a margin, the paper's region where the margin cannot be kept
    levels = (cfg.inflation + cfg.margin, cfg.inflation) if cfg.margin > 0.0 else (cfg.inflation,)
    for inflation in levels:
        status, verts, normals, offsets, polar, xy = _galaxy_scan(
            r, cos, sin, cfg.max_range, inflation, cfg.flip_radius, cfg.push, cfg.max_vertices, cfg.num_points,
            ordered,
        )  # fmt: skip
        if status == 0:
            return Region(verts, normals, offsets, polar, xy, True, "ok", False, inflation)
    failed = _fallback(_shrink(r, cfg.max_range, cfg.inflation), th, cfg.num_points, STATUS_NAMES[status])
    return _recover(r, cos, sin, ordered, cfg, failed) if cfg.on_failure == "recover" else failed


def _recover(r: np.ndarray, cos: np.ndarray, sin: np.ndarray, ordered: bool, cfg: RegionConfig,
             failed: Region) -> Region:
    """The recovery ladder (module docstring); ``failed`` (no polygon) when no level applies."""
    d = min(max(float(r.min()), 0.0), cfg.max_range)
    levels = sorted({min(cfg.recover_inflation, cfg.inflation), min(cfg.recover_floor, cfg.inflation)}, reverse=True)
    for inflation in levels:
        if d - inflation > cfg.recover_gap:
            status, verts, normals, offsets, polar, xy = _galaxy_scan(
                r, cos, sin, cfg.max_range, inflation, cfg.flip_radius, cfg.push, cfg.max_vertices, cfg.num_points,
                ordered,
            )  # fmt: skip
            if status == 0:
                return Region(verts, normals, offsets, polar, xy, False, failed.status, True, inflation)
    return failed


def scan_polygon(ranges: np.ndarray, angles: np.ndarray, config: RegionConfig | None = None) -> Region:
    """The scan at the region's resolution, as a :class:`Region` without a convex polygon.

    Its boundary is every ``n/num_points``-th beam's shrunk point (the paper's ``scan'``, which
    Designs 1 and 4 observe and Design 4 samples its points in); status ``scan``.

    Raises:
        ValueError: As :func:`compute_region`.
    """
    cfg = config if config is not None else _DEFAULT
    r, th = _validate(ranges, angles, cfg.num_points)
    return _fallback(_shrink(r, cfg.max_range, cfg.inflation), th, cfg.num_points, "scan")


def warm_up() -> None:
    """Compile (or load from the numba cache) the jitted kernels with a small synthetic scan."""
    angles = np.linspace(0.0, 2.0 * math.pi, 360, endpoint=False)
    compute_region(np.full(360, 4.0) + np.sin(3.0 * angles), angles)
    compute_region(np.full(360, 10.0), angles)


_DEFAULT = RegionConfig()


def _validate(ranges: np.ndarray, angles: np.ndarray, num_points: int) -> tuple[np.ndarray, np.ndarray]:
    for name, arr in (("ranges", ranges), ("angles", angles)):
        kind = np.asarray(arr).dtype.kind
        if kind not in "biuf":
            raise ValueError(f"{name}: expected real numbers, got dtype {np.asarray(arr).dtype}")
    r = np.asarray(ranges, dtype=np.float64).ravel()
    th = np.asarray(angles, dtype=np.float64).ravel()
    if r.shape != th.shape:
        raise ValueError(f"ranges/angles: shapes differ ({r.shape} vs {th.shape})")
    if r.size < num_points:
        raise ValueError(f"ranges: need at least num_points={num_points} beams, got {r.size}")
    if not math.isfinite(float(r.sum()) + float(th.sum())):  # fast path; sums overflow only on huge values
        for name, arr in (("ranges", r), ("angles", th)):
            bad = np.flatnonzero(~np.isfinite(arr))
            if bad.size:
                raise ValueError(f"{name}: non-finite values at beam indices {bad[:20].tolist()}")
    return r, th


def _fallback(shrunk: np.ndarray, angles: np.ndarray, num_points: int, status: str) -> Region:
    n = shrunk.size
    idx = (np.arange(num_points) * n) // num_points
    theta = np.mod(angles[idx], 2.0 * math.pi)
    theta[theta >= 2.0 * math.pi] = 0.0
    order = np.argsort(theta, kind="stable")
    boundary = np.stack([shrunk[idx][order], theta[order]], axis=1)
    xy = np.stack([boundary[:, 0] * np.cos(boundary[:, 1]), boundary[:, 0] * np.sin(boundary[:, 1])], axis=1)
    empty = np.zeros((0, 2))
    return Region(empty, empty.copy(), np.zeros(0), boundary, xy, False, status)


# ----------------------------------------------------------------------------- numba kernels


@njit(cache=True)
def _galaxy_scan(
    r: np.ndarray, cos: np.ndarray, sin: np.ndarray, max_range: float, inflation: float, flip_radius: float,
    push: float, max_vertices: int, num_points: int, ordered: bool,
) -> tuple[int, np.ndarray, np.ndarray, np.ndarray, np.ndarray, np.ndarray]:  # pragma: no cover - numba; fmt: skip
    """:func:`_galaxy` on the ranges, shrunk by :func:`_shrink`."""
    shrunk = _shrink(r, max_range, inflation)
    return _galaxy(shrunk * cos, shrunk * sin, flip_radius, push, max_vertices, num_points, ordered)


@njit(cache=True)
def _shrink(r: np.ndarray, max_range: float, inflation: float) -> np.ndarray:  # pragma: no cover - numba
    """Ranges clipped to ``max_range`` and shrunk by ``inflation``, at least 0 (spec step 1)."""
    shrunk = np.empty(r.shape[0])
    for i in range(r.shape[0]):
        shrunk[i] = max(min(r[i], max_range) - inflation, 0.0)  # r < 0 ends at 0 as well
    return shrunk


@njit(cache=True)
def _galaxy(
    px: np.ndarray,
    py: np.ndarray,
    flip_radius: float,
    push: float,
    max_vertices: int,
    num_points: int,
    ordered: bool,
) -> tuple[int, np.ndarray, np.ndarray, np.ndarray, np.ndarray, np.ndarray]:  # pragma: no cover - numba
    """Run steps 1-8: status, clockwise vertices, normals, offsets, boundary (r, θ) and (x, y)."""
    e2, e1 = np.zeros((0, 2)), np.zeros(0)
    status, nx, ny, c = _pushed_halfplanes(px, py, flip_radius, push, ordered)
    if status == 0:
        status, vx, vy = _intersect(nx, ny, c)
    if status != 0:
        return status, e2, e2, e1, e2, e2
    cw = _clockwise_from_smallest_angle(vx, vy)
    if cw.shape[0] > max_vertices or cw.shape[0] > num_points:
        cw = _thin(cw, 2.0 * np.pi / num_points)
    normals, offsets = _edge_halfplanes(cw)
    for j in range(offsets.shape[0]):
        if not offsets[j] > _MARGIN:
            return 5, e2, e2, e1, e2, e2
    polar, xy = _resample(cw, num_points)
    return 0, cw, normals, offsets, polar, xy


@njit(cache=True)
def _pushed_halfplanes(
    px: np.ndarray, py: np.ndarray, flip_radius: float, push: float, ordered: bool
) -> tuple[int, np.ndarray, np.ndarray, np.ndarray]:  # pragma: no cover - numba
    """Run steps 1-4: half-planes ``n·x <= c`` (one per hull edge of the star set, CCW)."""
    n = px.shape[0]
    fx = np.empty(n)
    fy = np.empty(n)
    none = np.zeros(0)
    for i in range(n):
        norm = math.hypot(px[i], py[i])
        if norm < _TOUCH:
            return 1, none, none, none
        scale = 2.0 * flip_radius / norm - 1.0
        fx[i] = px[i] * scale
        fy[i] = py[i] * scale
    star = graham_scan(fx, fy) if ordered else np.zeros(0, dtype=np.int64)
    if star.shape[0] == 0:  # unordered beams, or the flipped hull misses the origin
        star = monotone_chain(fx, fy)
    sx, sy = px[star], py[star]
    m = star.shape[0]
    hull = graham_scan(sx, sy) if ordered else monotone_chain(sx, sy)
    h = hull.shape[0]
    if h < 3:
        return 2, none, none, none
    nx, ny, c = np.empty(h), np.empty(h), np.empty(h)
    covered = 0
    for e in range(h):
        a, b = hull[e], hull[e + 1 if e + 1 < h else 0]  # wrap by compare: `%` divides
        ex, ey = sx[b] - sx[a], sy[b] - sy[a]
        length = math.hypot(ex, ey)
        nx[e], ny[e] = ey / length, -ex / length
        if nx[e] * sx[a] + ny[e] * sy[a] <= _MARGIN:
            return 2, none, none, none
        best = np.inf
        i = a
        while True:
            best = min(best, nx[e] * sx[i] + ny[e] * sy[i])
            covered += 1
            i = i + 1 if i + 1 < m else 0
            if i == b or covered > m:
                break
        c[e] = best + push
        if c[e] <= _MARGIN:
            return 3, none, none, none
    if covered != m:  # hull order does not match the star order: numerically degenerate
        return 4, none, none, none
    return 0, nx, ny, c


@njit(cache=True)
def _intersect(
    nx: np.ndarray, ny: np.ndarray, c: np.ndarray
) -> tuple[int, np.ndarray, np.ndarray]:  # pragma: no cover - numba
    """Step 5: vertices (CCW) of the intersection of ``n·x <= c`` (c > 0) via the dual hull.

    The normals come from a CCW hull, so the dual points are in angular order (O(n) hull).
    """
    dual = graham_scan(nx / c, ny / c)
    if dual.shape[0] == 0:
        dual = monotone_chain(nx / c, ny / c)
    k = dual.shape[0]
    none = np.zeros(0)
    if k < 3:
        return 4, none, none
    vx, vy = np.empty(k), np.empty(k)
    for i in range(k):
        a, b = dual[i], dual[i + 1 if i + 1 < k else 0]
        det = nx[a] * ny[b] - ny[a] * nx[b]
        if det <= 1e-12:
            return 4, none, none
        vx[i] = (c[a] * ny[b] - c[b] * ny[a]) / det
        vy[i] = (nx[a] * c[b] - nx[b] * c[a]) / det
    return 0, vx, vy


@njit(cache=True)
def _polar_angle(x: float, y: float) -> float:  # pragma: no cover - numba
    t = math.atan2(y, x)
    if t < 0.0:
        t += 2.0 * math.pi
    return 0.0 if t >= 2.0 * math.pi else t


@njit(cache=True)
def _clockwise_from_smallest_angle(vx: np.ndarray, vy: np.ndarray) -> np.ndarray:  # pragma: no cover - numba
    """CCW vertices -> clockwise (K, 2) array starting at the smallest polar angle."""
    k = vx.shape[0]
    start = 0
    best = 10.0
    for i in range(k):
        t = _polar_angle(vx[i], vy[i])
        if t < best:
            best, start = t, i
    out = np.empty((k, 2))
    for j in range(k):
        i = start - j if j <= start else start - j + k
        out[j, 0], out[j, 1] = vx[i], vy[i]
    return out


@njit(cache=True)
def _thin(cw: np.ndarray, min_step: float) -> np.ndarray:  # pragma: no cover - numba
    """Step 6: keep a vertex only if its polar angle differs from the last kept one by > min_step."""
    keep = np.zeros(cw.shape[0], dtype=np.bool_)
    keep[0] = True
    last = math.atan2(cw[0, 1], cw[0, 0])
    for i in range(1, cw.shape[0]):
        t = math.atan2(cw[i, 1], cw[i, 0])
        d = (t - last + math.pi) % (2.0 * math.pi) - math.pi
        if abs(d) > min_step:
            keep[i] = True
            last = t
    return cw[keep]


@njit(cache=True)
def _edge_halfplanes(cw: np.ndarray) -> tuple[np.ndarray, np.ndarray]:  # pragma: no cover - numba
    """Outward unit normals and offsets of a clockwise polygon (zero-length edges give c = 0)."""
    k = cw.shape[0]
    normals, offsets = np.zeros((k, 2)), np.zeros(k)
    for i in range(k):
        j = i + 1 if i + 1 < k else 0
        ex, ey = cw[j, 0] - cw[i, 0], cw[j, 1] - cw[i, 1]
        length = math.hypot(ex, ey)
        if length > 0.0 and k >= 3:
            normals[i, 0], normals[i, 1] = -ey / length, ex / length
            offsets[i] = normals[i, 0] * cw[i, 0] + normals[i, 1] * cw[i, 1]
    return normals, offsets


@njit(cache=True)
def _resample(cw: np.ndarray, num_points: int) -> tuple[np.ndarray, np.ndarray]:  # pragma: no cover - numba
    """Step 8: emit each CCW edge's start vertex plus extra points in proportion to its angle."""
    k = cw.shape[0]
    ccw = np.empty((k, 2))
    ccw[0] = cw[0]
    for j in range(1, k):
        ccw[j] = cw[k - j]
    extra = _largest_remainder(ccw, num_points - k)
    out = np.empty((num_points, 2))
    row = 0
    for i in range(k):
        ax, ay = ccw[i, 0], ccw[i, 1]
        j = i + 1 if i + 1 < k else 0
        bx, by = ccw[j, 0], ccw[j, 1]
        for s in range(extra[i] + 1):
            f = s / (extra[i] + 1.0)
            out[row, 0] = ax + f * (bx - ax)
            out[row, 1] = ay + f * (by - ay)
            row += 1
    start = 0
    best = 10.0
    for i in range(num_points):
        t = _polar_angle(out[i, 0], out[i, 1])
        if t < best:
            best, start = t, i
    polar, xy = np.empty((num_points, 2)), np.empty((num_points, 2))
    for i in range(num_points):
        q = start + i if start + i < num_points else start + i - num_points
        x, y = out[q, 0], out[q, 1]
        xy[i, 0], xy[i, 1] = x, y
        polar[i, 0], polar[i, 1] = math.hypot(x, y), _polar_angle(x, y)
    return polar, xy


@njit(cache=True)
def _largest_remainder(ccw: np.ndarray, total: int) -> np.ndarray:  # pragma: no cover - numba
    """Split ``total`` extra points over the CCW edges in proportion to the angle each subtends."""
    k = ccw.shape[0]
    quota = np.empty(k)
    for i in range(k):
        j = i + 1 if i + 1 < k else 0
        t0 = math.atan2(ccw[i, 1], ccw[i, 0])
        t1 = math.atan2(ccw[j, 1], ccw[j, 0])
        quota[i] = ((t1 - t0) % (2.0 * math.pi)) / (2.0 * math.pi) * total
    counts = np.floor(quota).astype(np.int64)
    taken = np.zeros(k, dtype=np.bool_)
    for _ in range(total - counts.sum()):  # fewer than k rounds: largest remainder, lowest index on ties
        best, pick = -1.0, 0
        for i in range(k):
            if not taken[i] and quota[i] - counts[i] > best:
                best, pick = quota[i] - counts[i], i
        taken[pick] = True
        counts[pick] += 1
    return counts
