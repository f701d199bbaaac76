"""Plain-Python ORCA (RVO2's half-planes and linear programs 1-3) to check the numba kernel against.

Written for readability, one agent at a time, with 2-vectors as numpy arrays; slow. Agents are
given as lists; obstacles in the :class:`mjnav.world.orca.OrcaObstacles` linked form.
"""

from __future__ import annotations

import math

import numpy as np

EPS = 1e-5


def det(a: np.ndarray, b: np.ndarray) -> float:
    """2-D cross product a x b."""
    return float(a[0] * b[1] - a[1] * b[0])


def unit(a: np.ndarray) -> np.ndarray:
    """a / |a|."""
    return a / math.hypot(a[0], a[1])


Line = tuple[np.ndarray, np.ndarray]  # (point, unit direction); admissible side: left of direction


def neighbours(i: int, pos: np.ndarray, extra: list[np.ndarray], dist: float, max_n: int) -> list[int]:
    """Indices (len(pos) + k for extra disc k) of the nearest ``max_n`` discs closer than ``dist``."""
    cands = [*pos, *extra]
    found = [(float(np.sum((c - pos[i]) ** 2)), j) for j, c in enumerate(cands) if j != i]
    found = sorted((d2, j) for d2, j in found if d2 < dist * dist)
    return [j for _, j in found[:max_n]]


def obstacle_neighbours(p: np.ndarray, reach: float, obs) -> list[int]:  # noqa: ANN001
    """Edges seen from their right side within ``reach`` of p, nearest first (stable)."""
    found = []
    for k in range(len(obs.point)):
        a, b = obs.point[k], obs.point[obs.next[k]]
        if det(b - a, p - a) >= 0.0:
            continue
        t = np.dot(p - a, b - a) / np.dot(b - a, b - a)
        nearest = a if t < 0.0 else b if t > 1.0 else a + t * (b - a)  # the vertex itself: ties stay exact
        d2 = float(np.sum((p - nearest) ** 2))
        if d2 < reach * reach:
            found.append((d2, k))
    return [k for _, k in sorted(found, key=lambda e: e[0])]


def agent_line(p, v, r, q, w, s, resp, tau, dt, tie) -> Line:  # noqa: ANN001
    """Half-plane against another disc (position q, velocity w, radius s)."""
    rel, rv, comb = q - p, v - w, r + s
    if rel @ rel > comb * comb:
        cut = rv - rel / tau
        if cut @ rel < 0.0 and (cut @ rel) ** 2 > comb * comb * (cut @ cut):
            n = unit(cut)
            direction, u = np.array([n[1], -n[0]]), (comb / tau - math.hypot(*cut)) * n
        else:
            leg = math.sqrt(rel @ rel - comb * comb)
            if det(rel, cut) > 0.0:
                direction = np.array([rel[0] * leg - rel[1] * comb, rel[0] * comb + rel[1] * leg]) / (rel @ rel)
            else:
                direction = -np.array([rel[0] * leg + rel[1] * comb, -rel[0] * comb + rel[1] * leg]) / (rel @ rel)
            u = (rv @ direction) * direction - rv
    else:
        cut = rv - rel / dt
        if math.hypot(*cut) > 1e-12:
            n = unit(cut)
        else:
            n = -unit(rel) if math.hypot(*rel) > 1e-12 else np.array([-tie, 0.0])
        direction, u = np.array([n[1], -n[0]]), (comb / dt - math.hypot(*cut)) * n
    return v + resp * u, direction


def tangents(rel: np.ndarray, r: float) -> tuple[np.ndarray, np.ndarray]:
    """Left and right unit tangent directions to a disc of radius r at ``rel``."""
    leg = math.sqrt(max(rel @ rel - r * r, 0.0))
    left = np.array([rel[0] * leg - rel[1] * r, rel[0] * r + rel[1] * leg]) / (rel @ rel)
    right = np.array([rel[0] * leg + rel[1] * r, -rel[0] * r + rel[1] * leg]) / (rel @ rel)
    return left, right


def obstacle_line(p, v, r, k, tau, obs, lines: list[Line]) -> Line | None:  # noqa: ANN001, C901, PLR0911, PLR0912
    """Half-plane of edge k, or None when it is covered or ignored."""
    inv = 1.0 / tau
    o1, o2 = k, int(obs.next[k])
    rel1, rel2 = obs.point[o1] - p, obs.point[o2] - p
    if any(det(inv * rel1 - pt, d) - inv * r >= -EPS and det(inv * rel2 - pt, d) - inv * r >= -EPS for pt, d in lines):
        return None
    edge = obs.point[o2] - obs.point[o1]
    s = float(-rel1 @ edge / (edge @ edge))
    dline = float(np.sum((-rel1 - s * edge) ** 2))
    if s < 0.0 and rel1 @ rel1 <= r * r:
        return (np.zeros(2), unit(np.array([-rel1[1], rel1[0]]))) if obs.convex[o1] else None
    if s > 1.0 and rel2 @ rel2 <= r * r:
        if obs.convex[o2] and det(rel2, obs.direction[o2]) >= 0.0:
            return np.zeros(2), unit(np.array([-rel2[1], rel2[0]]))
        return None
    if 0.0 <= s < 1.0 and dline <= r * r:
        return np.zeros(2), -obs.direction[o1]
    if s < 0.0 and dline <= r * r:
        if not obs.convex[o1]:
            return None
        o2 = o1
        left, right = tangents(rel1, r)
    elif s > 1.0 and dline <= r * r:
        if not obs.convex[o2]:
            return None
        o1 = o2
        left, right = tangents(rel2, r)
    else:
        left = tangents(rel1, r)[0] if obs.convex[o1] else -obs.direction[o1]
        right = tangents(rel2, r)[1] if obs.convex[o2] else obs.direction[o1]
    prev_dir = obs.direction[obs.prev[o1]]
    left_foreign = bool(obs.convex[o1] and det(left, -prev_dir) >= 0.0)
    if left_foreign:
        left = -prev_dir
    right_foreign = bool(obs.convex[o2] and det(right, obs.direction[o2]) <= 0.0)
    if right_foreign:
        right = obs.direction[o2]
    lc, rc = inv * (obs.point[o1] - p), inv * (obs.point[o2] - p)
    cv = rc - lc
    same = o1 == o2
    t = 0.5 if same else float((v - lc) @ cv / (cv @ cv))
    tl, tr = float((v - lc) @ left), float((v - rc) @ right)
    if (t < 0.0 and tl < 0.0) or (same and tl < 0.0 and tr < 0.0):
        n = unit(v - lc)
        return lc + r * inv * n, np.array([n[1], -n[0]])
    if t > 1.0 and tr < 0.0:
        n = unit(v - rc)
        return rc + r * inv * n, np.array([n[1], -n[0]])
    d_cut = math.inf if (t < 0.0 or t > 1.0 or same) else float(np.sum((v - lc - t * cv) ** 2))
    d_left = math.inf if tl < 0.0 else float(np.sum((v - lc - tl * left) ** 2))
    d_right = math.inf if tr < 0.0 else float(np.sum((v - rc - tr * right) ** 2))
    normal = lambda d: np.array([-d[1], d[0]])  # noqa: E731
    if d_cut <= d_left and d_cut <= d_right:
        d = -obs.direction[o1]
        return lc + r * inv * normal(d), d
    if d_left <= d_right:
        return None if left_foreign else (lc + r * inv * normal(left), left)
    return None if right_foreign else (rc + r * inv * normal(-right), -right)


def lp1(lines: list[Line], no: int, radius: float, opt: np.ndarray, direction: bool) -> np.ndarray | None:
    """Optimum on line ``no`` under the lines before it and the disc; None if infeasible."""
    pt, d = lines[no]
    dot = float(pt @ d)
    disc = dot * dot + radius * radius - float(pt @ pt)
    if disc < 0.0:
        return None
    lo, hi = -dot - math.sqrt(disc), -dot + math.sqrt(disc)
    for pt_m, d_m in lines[:no]:
        den, num = det(d, d_m), det(d_m, pt - pt_m)
        if abs(den) <= EPS:
            if num < 0.0:
                return None
            continue
        if den >= 0.0:
            hi = min(hi, num / den)
        else:
            lo = max(lo, num / den)
        if lo > hi:
            return None
    if direction:
        return pt + (hi if opt @ d > 0.0 else lo) * d
    return pt + min(max(float(d @ (opt - pt)), lo), hi) * d


def lp2(lines: list[Line], radius: float, opt: np.ndarray, direction: bool) -> tuple[int, np.ndarray]:
    """Incremental 2-D LP; returns (index of the first infeasible line or len(lines), result)."""
    if direction:
        result = opt * radius
    elif opt @ opt > radius * radius:
        result = unit(opt) * radius
    else:
        result = opt.copy()
    for m, (pt, d) in enumerate(lines):
        if det(d, pt - result) > 0.0:
            new = lp1(lines, m, radius, opt, direction)
            if new is None:
                return m, result
            result = new
    return len(lines), result


def lp3(lines: list[Line], n_obst: int, begin: int, radius: float, result: np.ndarray) -> np.ndarray:
    """Least largest penetration of the agent lines, obstacle lines kept hard."""
    distance = 0.0
    for i in range(begin, len(lines)):
        pt_i, d_i = lines[i]
        if det(d_i, pt_i - result) <= distance:
            continue
        proj = list(lines[:n_obst])
        for pt_j, d_j in lines[n_obst:i]:
            den = det(d_i, d_j)
            if abs(den) <= EPS:
                if d_i @ d_j > 0.0:
                    continue
                point = 0.5 * (pt_i + pt_j)
            else:
                point = pt_i + det(d_j, pt_i - pt_j) / den * d_i
            proj.append((point, unit(d_j - d_i)))
        fail, new = lp2(proj, radius, np.array([-d_i[1], d_i[0]]), True)
        if fail >= len(proj):
            result = new
        distance = det(d_i, pt_i - result)
    return result


def agent_lines(i, pos, vel, radii, vmax, obs, neighbor_dist, max_n, tau, tau_obst, dt,  # noqa: ANN001, ANN201
                robot=None, robot_resp=0.5):  # fmt: skip
    """Half-planes of agent i, obstacle ones first, and how many of them are obstacle ones."""
    n = len(pos)
    p, v, r = pos[i], vel[i], radii[i]
    lines: list[Line] = []
    for k in obstacle_neighbours(p, tau_obst * vmax[i] + r, obs):
        line = obstacle_line(p, v, r, k, tau_obst, obs, lines)
        if line is not None:
            lines.append(line)
    n_obst = len(lines)
    for j in neighbours(i, pos, [] if robot is None else [robot[0]], neighbor_dist, max_n):
        q, w, s, resp = (robot[0], robot[1], robot[2], robot_resp) if j == n else (pos[j], vel[j], radii[j], 0.5)
        lines.append(agent_line(p, v, r, q, w, s, resp, tau, dt, 1.0 if i < j else -1.0))
    return lines, n_obst


def orca(pos, vel, radii, pref, vmax, obs, neighbor_dist, max_n, tau, tau_obst, dt,  # noqa: ANN001, ANN201
         robot=None, robot_resp=0.5):  # fmt: skip
    """New velocities (N, 2) of all agents; ``robot`` = (position, velocity, radius) or None."""
    out = np.empty((len(pos), 2))
    for i in range(len(pos)):
        lines, n_obst = agent_lines(i, pos, vel, radii, vmax, obs, neighbor_dist, max_n, tau, tau_obst, dt, robot,
                                    robot_resp)  # fmt: skip
        fail, result = lp2(lines, vmax[i], pref[i], False)
        if fail < len(lines):
            result = lp3(lines, n_obst, fail, vmax[i], result)
        out[i] = result
    return out
