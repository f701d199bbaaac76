"""Scan → pedestrian detections: segmentation, structure removal, splitting and circle fits.

Numba kernels on one LiDAR scan in the world frame (the robot does not rotate: beam 0 points
along world +x, spec §2). Distances are metres, angles radians. The pipeline is

1. points: each beam's hit in the world; beams at or above ``limit`` (three noise σ below the
   maximum range) hit nothing; every hit also counts in its cell of the static map (step 5);
2. clusters: runs of consecutive hit beams whose ranges differ by at most ``range_jump`` plus
   ``range_jump_per_metre`` times the nearer range (an adaptive breakpoint: a wall seen at a
   grazing angle steps further between beams far away); the scan is unrolled to start at a
   discontinuity, so a cluster may cross beam 0;
3. structure: iterative end-point fit (split at the farthest point from the chord while it is
   above ``line_tolerance``); line pieces at least ``line_min_length`` long are walls or
   obstacle edges and are removed, leaving the bulges of pedestrians standing by them; a final
   piece beside line pieces that rises less than ``bump_depth`` above their line (a total-least-
   squares fit to the structure points around it) towards the robot is noise on the structure
   or a stub of it, and is removed too;
4. splitting: a remaining run wider than one pedestrian (``2 r_max + split_margin``), or with a
   concavity deeper than ``notch_depth``, is split at its deepest concavity (3-beam mean range
   above that of the beams two either side: the notch between two touching pedestrians),
   repeatedly; a run that cannot be split and is wider than
   ``max_width`` is structure;
5. static map: every hit counts in its cell of a world grid kept over the episode; a piece
   whose points mostly lie in cells hit in ``static_hits`` scans or more is structure (walls
   and obstacle corners are hit scan after scan; a walking pedestrian's surface moves on);
6. shape: a piece hollow towards the robot by more than ``line_tolerance`` (the inside of a
   corner) is structure;
7. circles: a Kasa (algebraic) fit gives the direction to the centre, the radius is the mean of
   the fitted and the chord-based radius clamped to the configured range, and the centre sits
   behind the points' centroid by the depth of a beam-sampled arc.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

__all__ = ["detect_kernel"]


@njit(cache=True, error_model="numpy")
def _jumps(r0: float, r1: float, jump: float, per_metre: float) -> bool:
    """Whether neighbouring ranges ``r0``, ``r1`` (m) are a discontinuity (adaptive breakpoint)."""
    return abs(r1 - r0) > jump + per_metre * min(r0, r1)


@njit(cache=True, error_model="numpy")
def _unroll(ranges: np.ndarray, limit: float, jump: float, per_metre: float) -> tuple[np.ndarray, np.ndarray]:
    """Beam order starting at a discontinuity, and each unrolled beam's validity."""
    n = ranges.shape[0]
    start = 0
    for i in range(n):
        j = i - 1 if i > 0 else n - 1
        if ranges[i] >= limit or ranges[j] >= limit or _jumps(ranges[j], ranges[i], jump, per_metre):
            start = i
            break
    order = np.empty(n, np.int64)
    valid = np.empty(n, np.bool_)
    for k in range(n):
        b = (start + k) % n
        order[k] = b
        valid[k] = ranges[b] < limit
    return order, valid


@njit(cache=True, error_model="numpy")
def _mark_lines(px: np.ndarray, py: np.ndarray, a: int, b: int, tol: float, min_len: float,
                structure: np.ndarray, stack: np.ndarray) -> None:
    """Iterative end-point fit of points ``a..b``; marks points of long line pieces as structure."""
    top = 0
    stack[0, 0], stack[0, 1] = a, b
    top = 1
    while top > 0:
        top -= 1
        i, j = stack[top, 0], stack[top, 1]
        ex, ey = px[j] - px[i], py[j] - py[i]
        length = math.sqrt(ex * ex + ey * ey)
        inv = 1.0 / max(length, 1e-9)
        worst, at = 0.0, -1
        for k in range(i + 1, j):
            d = abs((px[k] - px[i]) * ey - (py[k] - py[i]) * ex) * inv
            if d > worst:
                worst, at = d, k
        if worst > tol and top + 2 <= stack.shape[0]:
            stack[top, 0], stack[top, 1] = i, at
            stack[top + 1, 0], stack[top + 1, 1] = at, j
            top += 2
        elif length >= min_len:
            structure[i:j + 1] = True


@njit(cache=True, error_model="numpy")
def _smooth(rr: np.ndarray, i: int, a: int, b: int) -> float:
    """Mean range of beams ``i-1..i+1`` clipped to the run ``a..b``."""
    lo, hi = max(a, i - 1), min(b, i + 1)
    total = 0.0
    for k in range(lo, hi + 1):
        total += rr[k]
    return total / (hi - lo + 1)


@njit(cache=True, error_model="numpy")
def _notch(rr: np.ndarray, a: int, b: int) -> tuple[int, float]:
    """Deepest concavity of run ``a..b`` (two points kept either side): (index or -1, depth in m).

    Depth is the 3-beam mean range minus the mean of the 3-beam means two beams either side.
    """
    best, at = -1e9, -1
    for i in range(a + 2, b - 1):
        d = _smooth(rr, i, a, b) - 0.5 * (_smooth(rr, i - 2, a, b) + _smooth(rr, i + 2, a, b))
        if d > best:
            best, at = d, i
    return at, best


@njit(cache=True, error_model="numpy")
def _width(px: np.ndarray, py: np.ndarray, rr: np.ndarray, a: int, b: int, spacing: float) -> float:
    """Chord of run ``a..b`` plus one beam footprint, metres."""
    return math.hypot(px[b] - px[a], py[b] - py[a]) + 0.5 * (rr[a] + rr[b]) * spacing


@njit(cache=True, error_model="numpy")
def _fit_circle(px: np.ndarray, py: np.ndarray, rr: np.ndarray, a: int, b: int, ox: float, oy: float,
                spacing: float, r_min: float, r_max: float, out: np.ndarray) -> None:
    """``out = [x, y, r]``: the circle behind points ``a..b`` seen from ``(ox, oy)``."""
    n = b - a + 1
    mx, my = 0.0, 0.0
    for k in range(a, b + 1):
        mx += px[k]
        my += py[k]
    mx, my = mx / n, my / n
    suu = suv = svv = suuu = suvv = svvv = svuu = 0.0
    for k in range(a, b + 1):
        u, v = px[k] - mx, py[k] - my
        suu += u * u
        suv += u * v
        svv += v * v
        suuu += u * u * u
        suvv += u * v * v
        svvv += v * v * v
        svuu += v * u * u
    dist = math.hypot(mx - ox, my - oy)
    dx, dy = (mx - ox) / max(dist, 1e-9), (my - oy) / max(dist, 1e-9)
    half = 0.5 * _width(px, py, rr, a, b, spacing)
    radius = half / math.sqrt(max(1.0 - (half / max(dist, 1e-9)) ** 2, 0.25))
    det = suu * svv - suv * suv
    if n >= 3 and det > 1e-12:
        uc = 0.5 * ((suuu + suvv) * svv - (svvv + svuu) * suv) / det
        vc = 0.5 * ((svvv + svuu) * suu - (suuu + suvv) * suv) / det
        fit = math.sqrt(uc * uc + vc * vc + (suu + svv) / n)
        norm = math.hypot(uc, vc)
        if 0.5 * r_min <= fit <= 2.0 * r_max and norm > 1e-9 and uc * dx + vc * dy > 0.0:
            dx, dy = uc / norm, vc / norm
            radius = 0.5 * (radius + fit)
    radius = min(max(radius, r_min), r_max)
    phi = math.acos(min(radius / max(dist + 0.7 * radius, 1e-9), 1.0))
    depth = 1.0 if phi < 1e-6 else (math.sin(phi) * math.cos(phi) + phi) / (2.0 * math.sin(phi))
    out[0] = mx + dx * radius * depth
    out[1] = my + dy * radius * depth
    out[2] = radius


@njit(cache=True, error_model="numpy")
def _bump_depth(px: np.ndarray, py: np.ndarray, structure: np.ndarray, cs: int, ce: int, a: int, b: int,
                ox: float, oy: float) -> float:
    """Mean height of piece ``a..b`` above the structure line beside it, towards the robot, m.

    The line is a total-least-squares fit to the structure points among the twelve either side of
    the piece (within its cluster); a piece with fewer than two such points returns infinity
    (free-standing).
    """
    n, mx, my = 0, 0.0, 0.0
    for k in range(max(cs, a - 12), min(ce, b + 12) + 1):
        if (k < a or k > b) and structure[k]:
            n += 1
            mx += px[k]
            my += py[k]
    if n < 2:
        return np.inf
    mx, my = mx / n, my / n
    sxx = sxy = syy = 0.0
    for k in range(max(cs, a - 12), min(ce, b + 12) + 1):
        if (k < a or k > b) and structure[k]:
            sxx += (px[k] - mx) ** 2
            sxy += (px[k] - mx) * (py[k] - my)
            syy += (py[k] - my) ** 2
    angle = 0.5 * math.atan2(2.0 * sxy, sxx - syy)  # direction of largest spread
    nx, ny = -math.sin(angle), math.cos(angle)
    if nx * (ox - mx) + ny * (oy - my) < 0.0:
        nx, ny = -nx, -ny
    total = 0.0
    for k in range(a, b + 1):
        total += nx * (px[k] - mx) + ny * (py[k] - my)
    return total / (b - a + 1)


@njit(cache=True, inline="always", error_model="numpy")
def _cell(x: float, y: float, grid: np.ndarray, params: np.ndarray) -> tuple[int, int]:
    """Grid cell of world point ``(x, y)``, or (-1, -1) outside the grid (``params[12]`` = 1 / cell)."""
    return _cell_of(x, y, params[13], params[14], params[12], grid.shape[0], grid.shape[1])


@njit(cache=True, inline="always", error_model="numpy")
def _cell_of(x: float, y: float, x0: float, y0: float, inv: float, nx: int, ny: int) -> tuple[int, int]:
    """Cell ``(i, j)`` of ``(x, y)`` in an ``nx`` × ``ny`` grid from ``(x0, y0)``, or (-1, -1)."""
    fx = (x - x0) * inv  # truncation is floor here: negatives are outside
    fy = (y - y0) * inv
    if fx < 0.0 or fy < 0.0 or fx >= nx or fy >= ny:
        return -1, -1
    return int(fx), int(fy)


@njit(cache=True, error_model="numpy")
def _static_fraction(px: np.ndarray, py: np.ndarray, a: int, b: int, grid: np.ndarray, params: np.ndarray) -> float:
    """Share of points ``a..b`` in cells hit in at least ``static_hits`` scans so far."""
    static = 0
    for k in range(a, b + 1):
        i, j = _cell(px[k], py[k], grid, params)
        if i >= 0 and grid[i, j] >= params[15]:
            static += 1
    return static / (b - a + 1)


@njit(cache=True, error_model="numpy")
def _hollow(px: np.ndarray, py: np.ndarray, a: int, b: int, ox: float, oy: float) -> float:
    """Farthest any point of ``a..b`` lies behind the chord ``a``–``b`` (away from the robot), m.

    A pedestrian's arc bulges towards the robot; a piece hollow by more than the line tolerance
    is the inside of a corner.
    """
    ex, ey = px[b] - px[a], py[b] - py[a]
    length = math.sqrt(ex * ex + ey * ey)
    if length < 1e-9:
        return 0.0
    nx, ny = -ey / length, ex / length
    if nx * (ox - px[a]) + ny * (oy - py[a]) > 0.0:  # normal away from the robot
        nx, ny = -nx, -ny
    worst = 0.0
    for k in range(a + 1, b):
        worst = max(worst, nx * (px[k] - px[a]) + ny * (py[k] - py[a]))
    return worst


@njit(cache=True, error_model="numpy")
def _emit_run(px: np.ndarray, py: np.ndarray, rr: np.ndarray, a: int, b: int, cs: int, ce: int, ox: float,
              oy: float, spacing: float, params: np.ndarray, structure: np.ndarray, stack: np.ndarray,
              grid: np.ndarray, out: np.ndarray, count: int) -> int:
    """Split run ``a..b`` of cluster ``cs..ce`` into pedestrians and append their circles to ``out``.

    Returns the new count.
    """
    r_min, r_max, split_margin, max_width, min_points = params[4], params[5], params[6], params[7], params[8]
    notch_depth = params[9]
    stack[0, 0], stack[0, 1] = a, b
    top = 1
    while top > 0:
        top -= 1
        i, j = stack[top, 0], stack[top, 1]
        if j - i + 1 < min_points or rr[i:j + 1].min() > params[11]:
            continue
        width = _width(px, py, rr, i, j, spacing)
        wide = width > 2.0 * r_max + split_margin
        at, depth = _notch(rr, i, j) if width > 4.0 * r_min else (-1, 0.0)
        if wide or depth > notch_depth:
            if at >= 0 and top + 2 <= stack.shape[0]:
                stack[top, 0], stack[top, 1] = i, at
                stack[top + 1, 0], stack[top + 1, 1] = at + 1, j
                top += 2
                continue
            if wide and width > max_width:
                continue
        if (_static_fraction(px, py, i, j, grid, params) > 0.5 or _hollow(px, py, i, j, ox, oy) > params[2]
                or _bump_depth(px, py, structure, cs, ce, i, j, ox, oy) < params[10]):
            continue
        if count < out.shape[0]:
            _fit_circle(px, py, rr, i, j, ox, oy, spacing, r_min, r_max, out[count])
            count += 1
    return count


@njit(cache=True, error_model="numpy")
def detect_kernel(ranges: np.ndarray, cos_a: np.ndarray, sin_a: np.ndarray, ox: float, oy: float,
                  params: np.ndarray, grid: np.ndarray, out: np.ndarray) -> int:
    """Pedestrian circles in one scan.

    Args:
        ranges: (B,) ranges, metres, beam ``b`` along angle ``2πb/B`` in the world frame.
        cos_a, sin_a: (B,) beam direction cosines and sines.
        ox, oy: Robot (scan origin) position in the world, metres.
        params: ``[limit, range_jump, line_tolerance, line_min_length, r_min, r_max, split_margin,
            max_width, min_points, notch_depth, bump_depth, detect_range, 1 / cell, grid x0, grid y0,
            static_hits, range_jump_per_metre]`` (metres except the counts ``min_points`` and
            ``static_hits``); ``limit`` is the range at and above which a beam hit nothing;
            pieces whose nearest point lies beyond ``detect_range`` are segmented but not reported.
        grid: (G, G) uint8 hit counts per world cell, saturating at 255, updated in place (the robot's
            own static map; one byte per cell keeps the cells a scan touches in few cache lines).
        out: (D, 3) buffer for ``[x, y, r]`` rows, world metres.

    Returns:
        The number of rows written (at most D).
    """
    n = ranges.shape[0]
    spacing = 2.0 * math.pi / n
    limit, jump, tol, min_len = params[0], params[1], params[2], params[3]
    order, valid = _unroll(ranges, limit, jump, params[16])
    px, py, rr = np.empty(n), np.empty(n), np.empty(n)
    x0, y0, inv = params[13], params[14], params[12]
    for k in range(n):
        b = order[k]
        rr[k] = ranges[b]
        px[k] = ox + ranges[b] * cos_a[b]
        py[k] = oy + ranges[b] * sin_a[b]
        i, j = _cell_of(px[k], py[k], x0, y0, inv, grid.shape[0], grid.shape[1])
        if valid[k] and i >= 0 and grid[i, j] < 255:
            grid[i, j] += 1
    structure = np.zeros(n, np.bool_)
    stack = np.empty((2 * n + 4, 2), np.int64)
    count, k = 0, 0
    while k < n:
        if not valid[k]:
            k += 1
            continue
        end = k
        while end + 1 < n and valid[end + 1] and not _jumps(rr[end], rr[end + 1], jump, params[16]):
            end += 1
        _mark_lines(px, py, k, end, tol, min_len, structure, stack)
        run = k
        while run <= end:  # runs of non-structure points inside the cluster
            if structure[run]:
                run += 1
                continue
            stop = run
            while stop + 1 <= end and not structure[stop + 1]:
                stop += 1
            count = _emit_run(px, py, rr, run, stop, k, end, ox, oy, spacing, params, structure, stack, grid,
                              out, count)
            run = stop + 1
        k = end + 1
    return count
