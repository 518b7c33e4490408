"""Compiled (numba) kernels of supervision: the per-period arithmetic between the limits.

Every control period supervision evaluates ~25 margins (joint limits, three singularities, a
capsule clearance per body and obstacle) twice; as numpy calls on 3-vectors that costs ~100 us,
ten times the control step. These kernels fuse it; ``chain_placements`` is a private copy of
pinocchio's forward kinematics for a serial chain of revolute joints (a test checks the two
agree), the rest is plain geometry.
"""

from __future__ import annotations

import math

import numba
import numpy as np

from .._kernels import cross

_jit = numba.njit(cache=True, fastmath=False, nogil=True)
# A margin shrinking by less than this (m or rad) in one period is not approaching its limit:
# the IK's rounding when sliding along a limit, 100 times below the slowest real approach.
APPROACH_TOLERANCE = 1e-8


@_jit
def chain_placements(q: np.ndarray, placements: np.ndarray, axes: np.ndarray) -> np.ndarray:
    """Forward kinematics of a serial chain of revolute joints: (6, 4, 4) joint placements.

    oMi_j = oMi_{j-1} jointPlacement_j Rot(axis_j, q_j) (pinocchio's ``forwardKinematics``
    for a chain whose joint j's parent is j - 1; a test checks that the two agree).
    """
    Ts = np.empty((6, 4, 4))
    parent = np.eye(4)
    for j in range(6):
        kx, ky, kz = axes[j, 0], axes[j, 1], axes[j, 2]
        s, c = math.sin(q[j]), math.cos(q[j])
        v = 1.0 - c
        rot = np.eye(4)
        rot[0, 0] = c + kx * kx * v
        rot[0, 1] = kx * ky * v - kz * s
        rot[0, 2] = kx * kz * v + ky * s
        rot[1, 0] = ky * kx * v + kz * s
        rot[1, 1] = c + ky * ky * v
        rot[1, 2] = ky * kz * v - kx * s
        rot[2, 0] = kz * kx * v - ky * s
        rot[2, 1] = kz * ky * v + kx * s
        rot[2, 2] = c + kz * kz * v
        parent = parent @ placements[j] @ rot
        Ts[j] = parent
    return Ts


@_jit
def geometry_margins(
    q: np.ndarray,
    placements: np.ndarray,
    axes: np.ndarray,
    limits: np.ndarray,
    bodies: np.ndarray,
    pairs: np.ndarray,
    obstacles: np.ndarray,
    elbow_to_axis4: bool,
    table_z: float,
) -> tuple[np.ndarray, np.ndarray, int]:
    """The margins at joints ``q`` (see the ``supervisor`` module) and the joint placements.

    Args:
        q: (6,) joints. placements: (6, 4, 4) joint placements in their parents. axes: (6, 3)
        joint axes in their own frames. limits: (2, 6) lower, upper. bodies: (K, 9) per
        capsule: joint index (0-based), end a (3), end b (3) in the joint frame, radius,
        1.0 for a flat-ended cylinder. pairs: (P, 3) body index, obstacle index (-1 the
        table), slow value. obstacles: (O, 6) bounding box lo (3), hi (3) of each obstacle.

    Returns:
        margins (9 + P,): joint limits (6), wrist, elbow, shoulder, one clearance per pair
        (NaN where an obstacle's bounding box is nearer than the slow value, so coal must
        measure it); the joint placements (6, 4, 4); and how many margins are NaN.
    """
    Ts = chain_placements(q, placements, axes)
    n_pairs = pairs.shape[0]
    margins = np.empty(9 + n_pairs)
    z = np.empty((6, 3))
    o = np.empty((6, 3))
    for j in range(6):
        margins[j] = min(q[j] - limits[0, j], limits[1, j] - q[j])
        for r in range(3):
            z[j, r] = Ts[j, r, 0] * axes[j, 0] + Ts[j, r, 1] * axes[j, 1] + Ts[j, r, 2] * axes[j, 2]
            o[j, r] = Ts[j, r, 3]
    # Wrist: angle between axes 4 and 6, folded to [0, 90] deg (0 when axis 5 is at 0).
    c = cross(z[3], z[5])
    margins[6] = math.atan2(math.sqrt(c @ c), abs(z[3] @ z[5]))
    # Wrist centre: the point of axis 6 closest to axis 5.
    w = o[5] - o[4]
    b = z[4] @ z[5]
    denom = 1.0 - b * b
    wrist_centre = o[5].copy()
    if denom > 1e-9:
        wrist_centre = o[5] + (b * (z[4] @ w) - (z[5] @ w)) / denom * z[5]
    # Elbow: angle between upper arm and forearm in the plane normal to axis 2.
    n = z[1]
    x_point = o[3] if elbow_to_axis4 else wrist_centre
    u = o[2] - o[1]
    v = x_point - o[2]
    u = u - (u @ n) * n
    v = v - (v @ n) * n
    c = cross(u, v)
    margins[7] = math.atan2(math.sqrt(c @ c), u @ v)
    # Shoulder: the wrist centre's distance from the axis-1 line, in the arm plane.
    across = cross(z[0], z[1])
    norm = math.sqrt(across @ across)
    margins[8] = abs((wrist_centre - o[0]) @ across) / norm if norm > 1e-9 else np.inf
    # Collisions: the table plane exactly; boxes and hull by their bounding box, from below.
    a = np.empty(3)
    e = np.empty(3)
    reach = np.empty(3)
    n_near = 0
    for i in range(n_pairs):
        k = int(pairs[i, 0])
        obstacle = int(pairs[i, 1])
        j = int(bodies[k, 0])
        for r in range(3):
            a[r] = Ts[j, r, 3]
            e[r] = Ts[j, r, 3]
            for col in range(3):
                a[r] += Ts[j, r, col] * bodies[k, 1 + col]
                e[r] += Ts[j, r, col] * bodies[k, 4 + col]
        # How far the body reaches beyond its end points along each base axis: r for a
        # capsule; r sqrt(1 - u_k^2) for a flat-ended cylinder of unit axis u (its rim).
        radius = bodies[k, 7]
        length2 = 0.0
        for r in range(3):
            length2 += (e[r] - a[r]) * (e[r] - a[r])
        for r in range(3):
            reach[r] = radius
            if bodies[k, 8] > 0.5:
                u2 = (e[r] - a[r]) * (e[r] - a[r]) / max(length2, 1e-300)
                reach[r] = radius * math.sqrt(max(0.0, 1.0 - u2))
        if obstacle < 0:
            margins[9 + i] = min(a[2], e[2]) - reach[2] - table_z
            continue
        gap2 = 0.0
        for d in range(3):
            g = max(
                0.0,
                obstacles[obstacle, d] - (max(a[d], e[d]) + reach[d]),
                (min(a[d], e[d]) - reach[d]) - obstacles[obstacle, 3 + d],
            )
            gap2 += g * g
        bound = math.sqrt(gap2)
        if bound >= pairs[i, 2]:
            margins[9 + i] = bound
        else:
            margins[9 + i] = np.nan
            n_near += 1
    return margins, Ts, n_near


@_jit
def decide(
    m0: np.ndarray,
    m1: np.ndarray,
    thresholds: np.ndarray,
    min_scale: float,
    q0: np.ndarray,
    q1: np.ndarray,
    step_bound: np.ndarray,
    T_ref: np.ndarray,
    T_tcp: np.ndarray,
    tracking: np.ndarray,
) -> tuple[float, int, int, float]:
    """The speed scale of a step and its verdict, from the margins before (m0) and after (m1).

    scale = min over approached limits (m1 < m0 - APPROACH_TOLERANCE) of
    clip((m0 - stop) / (slow - stop), min_scale, 1), and 0.95 / max_i(|dq_i| / bound_i) when a
    joint would move too far.
    Verdict (code, index, value): 0 allowed; 1 joint ``index`` steps ``value`` rad, over its
    bound; 2 margin ``index`` ends at ``value``, past its stop while shrinking (the worst);
    3 the TCP misses the reference by ``value`` (index 0: metres, 1: radians).

    Args:
        thresholds: (2, K) stop and slow values of the K margins.
        tracking: (2,) largest reference error in metres and radians.
    """
    scale = 1.0
    worst_i, worst = -1, np.inf
    for i in range(m0.shape[0]):
        if m1[i] < m0[i] - APPROACH_TOLERANCE:
            stop, slow = thresholds[0, i], thresholds[1, i]
            scale = min(scale, max(min_scale, (m0[i] - stop) / (slow - stop)))
            if m1[i] < stop:
                badness = (m1[i] - stop) / (slow - stop)
                if badness < worst:
                    worst_i, worst = i, badness
    worst_j, worst_ratio = -1, 1.0 + 1e-9
    for j in range(q0.shape[0]):
        ratio = abs(q1[j] - q0[j]) / step_bound[j]
        if ratio > worst_ratio:
            worst_j, worst_ratio = j, ratio
    if worst_j >= 0:
        return min(scale, 0.95 / worst_ratio), 1, worst_j, abs(q1[worst_j] - q0[worst_j])
    if worst_i >= 0:
        return scale, 2, worst_i, m1[worst_i]
    dx = T_ref[0, 3] - T_tcp[0, 3]
    dy = T_ref[1, 3] - T_tcp[1, 3]
    dz = T_ref[2, 3] - T_tcp[2, 3]
    error_m = math.sqrt(dx * dx + dy * dy + dz * dz)
    if error_m > tracking[0]:
        return scale, 3, 0, error_m
    trace = 0.0
    for r in range(3):
        for c in range(3):
            trace += T_ref[r, c] * T_tcp[r, c]
    error_rad = math.acos(min(1.0, max(-1.0, (trace - 1.0) / 2.0)))
    if error_rad > tracking[1]:
        return scale, 3, 1, error_rad
    return scale, 0, -1, 0.0
