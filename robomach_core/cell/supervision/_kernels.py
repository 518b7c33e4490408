"""Compiled (numba) kernels of supervision: the per-period arithmetic between the limits.

PROBLEM   Every control period supervision evaluates ~25 margins (joint limits, three
          singularities, a capsule clearance per body and obstacle) before and after the
          proposed step; as numpy calls on 3-vectors that costs ~100 us, ten times the control
          step, and even as separate kernels the Python between them costs more than the step.
STRATEGY  The supervisor's model (kinematic chain, bodies, obstacles, thresholds) is one flat
          array (``pack_model``) that each kernel reads through views (``_unpack``), so a call
          passes a handful of arrays. ``chain_placements`` is a private copy of pinocchio's
          forward kinematics for a serial chain of revolute joints (a test checks the two
          agree); the rest is plain geometry. A body within an obstacle's slow zone gets its
          exact clearance by GJK over the obstacle's corners (``convex_clearance``: a test
          checks it against coal); only overlaps go back to Python for coal's depth.
SOLUTION  ``margins_at`` (the margins of one joint vector), ``decide`` (the speed scale and the
          verdict of one step) and ``supervise_increment``: a whole supervised period of a
          motion that moves the reference by a step and a turn, fused (equal to
          ``Supervisor.supervise`` with ``increment_proposal``: a test checks it).
"""

from __future__ import annotations

import math

import numba
import numpy as np

from ..._kernels import exp3, ik_newton_step, mul3, rotate_about

_jit = numba.njit(cache=True, fastmath=False, nogil=True)
# A margin shrinking by less than this (m or rad) in one period is not approaching its limit:
# the IK's rounding when sliding along a limit, 100 times below the slowest real approach.
APPROACH_TOLERANCE = 1e-8
# bodies, pairs, obstacles, couplings, elbow_to_axis4, table_z, min_scale, damping, vertices
_HEADER = 9
# GJK (``convex_clearance``) stops when the clearance it has is within this of the true one [m].
GJK_TOLERANCE_M = 1e-7  # coal agrees to about 1e-6 m; the slow zones are millimetres
GJK_MAX_ITERATIONS = 64


def pack_model(
    *,
    placements: np.ndarray,
    axes: np.ndarray,
    limits: np.ndarray,
    M_tcp: np.ndarray,
    step_bound: np.ndarray,
    tracking: np.ndarray,
    bodies: np.ndarray,
    pairs: np.ndarray,
    obstacles: np.ndarray,
    vertices: np.ndarray,
    couplings: np.ndarray,
    thresholds: np.ndarray,
    elbow_to_axis4: bool,
    table_z: float,
    min_scale: float,
    ik_damping: float,
) -> np.ndarray:
    """The supervisor's model as one flat array, read by the kernels through ``_unpack``.

    Args:
        placements: (6, 4, 4) joint placements in their parents. axes: (6, 3) joint axes in
            their own frames. limits: (2, 6) lower, upper. M_tcp: (4, 4) TCP in joint 6.
        step_bound: (6,) largest joint step of one period. tracking: (2,) largest reference
            error [m, rad]. bodies: (K, 9) per capsule: joint index (0-based), end a (3), end
            b (3) in the joint frame, radius, 1.0 for a flat-ended cylinder. pairs: (P, 3) body
            index, obstacle index (-1 the table), slow value. obstacles: (O, 8) bounding box
            lo (3), hi (3), then the first row and the number of rows of its corners in
            ``vertices``. vertices: (N, 3) the obstacles' corners (each obstacle the convex
            hull of its own), base frame [m]. couplings: (C, 8) coefficients (6), lower, upper
            [rad]. thresholds: (2, 9 + P + C) stop and slow values of every margin.
    """
    head: list[float] = [len(bodies), len(pairs), len(obstacles), len(couplings)]
    head += [float(elbow_to_axis4), table_z, min_scale, ik_damping, len(vertices)]
    parts = [placements, axes, limits, M_tcp, step_bound, tracking, bodies, pairs, obstacles]
    parts += [couplings, thresholds, vertices]
    return np.concatenate([np.asarray(head, dtype=float)] + [np.ravel(p) for p in parts])


def obstacle_corner_counts(model: np.ndarray) -> np.ndarray:
    """(O,) each obstacle's number of corners in the packed ``model``, as a view into it. Set
    to 0, the kernels leave that obstacle's near clearances to coal: the reference that the
    GJK test and ``bench_path_learning.py`` compare with."""
    return _unpack.py_func(model)[8][:, 7]


@_jit
def _unpack(model: np.ndarray):  # noqa: ANN202 - a tuple of views, in ``pack_model``'s order
    K, P, O, C = int(model[0]), int(model[1]), int(model[2]), int(model[3])
    i = _HEADER
    placements = model[i : i + 96].reshape((6, 4, 4))
    axes = model[i + 96 : i + 114].reshape((6, 3))
    limits = model[i + 114 : i + 126].reshape((2, 6))
    M_tcp = model[i + 126 : i + 142].reshape((4, 4))
    step_bound = model[i + 142 : i + 148]
    tracking = model[i + 148 : i + 150]
    i += 150
    bodies = model[i : i + 9 * K].reshape((K, 9))
    i += 9 * K
    pairs = model[i : i + 3 * P].reshape((P, 3))
    i += 3 * P
    obstacles = model[i : i + 8 * O].reshape((O, 8))
    i += 8 * O
    couplings = model[i : i + 8 * C].reshape((C, 8))
    i += 8 * C
    n = 9 + P + C
    thresholds = model[i : i + 2 * n].reshape((2, n))
    i += 2 * n
    N = int(model[8])
    vertices = model[i : i + 3 * N].reshape((N, 3))
    return (
        placements, axes, limits, M_tcp, step_bound, tracking, bodies, pairs, obstacles,
        couplings, thresholds, vertices,
    )  # fmt: skip


@_jit
def chain_placements(q: np.ndarray, placements: np.ndarray, axes: np.ndarray) -> np.ndarray:
    """Forward kinematics of a serial chain of revolute joints: (6, 4, 4) joint placements.

    oMi_j = oMi_{j-1} jointPlacement_j Rot(axis_j, q_j) (pinocchio's ``forwardKinematics``
    for a chain whose joint j's parent is j - 1; a test checks that the two agree).
    """
    Ts = np.empty((6, 4, 4))
    P = np.eye(4)
    rot = np.empty((3, 3))
    RM = np.empty((3, 3))
    for j in range(6):
        rotate_about(rot, axes[j, 0], axes[j, 1], axes[j, 2], math.sin(q[j]), math.cos(q[j]))
        M = placements[j]
        T = Ts[j]
        # P M Rot: rotation R_P R_M R, translation R_P t_M + t_P.
        for r in range(3):
            for c in range(3):
                RM[r, c] = P[r, 0] * M[0, c] + P[r, 1] * M[1, c] + P[r, 2] * M[2, c]
            T[r, 3] = P[r, 0] * M[0, 3] + P[r, 1] * M[1, 3] + P[r, 2] * M[2, 3] + P[r, 3]
        for r in range(3):
            for c in range(3):
                T[r, c] = RM[r, 0] * rot[0, c] + RM[r, 1] * rot[1, c] + RM[r, 2] * rot[2, c]
            T[3, r] = 0.0
        T[3, 3] = 1.0
        P = T
    return Ts


@_jit
def _row(a: np.ndarray, i: int) -> tuple[float, float, float]:
    return a[i, 0], a[i, 1], a[i, 2]


@_jit
def _dot(a: tuple, b: tuple) -> float:
    return a[0] * b[0] + a[1] * b[1] + a[2] * b[2]


@_jit
def _cross(a: tuple, b: tuple) -> tuple[float, float, float]:
    return a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2], a[0] * b[1] - a[1] * b[0]


@_jit
def _axpy(k: float, x: tuple, y: tuple) -> tuple[float, float, float]:
    """k x + y."""
    return k * x[0] + y[0], k * x[1] + y[1], k * x[2] + y[2]


@_jit
def _end(T: np.ndarray, body: np.ndarray, at: int) -> tuple[float, float, float]:
    """The point ``body[at : at + 3]`` (in the joint frame ``T``) in the base frame."""
    x, y, z = body[at], body[at + 1], body[at + 2]
    return (
        T[0, 3] + T[0, 0] * x + T[0, 1] * y + T[0, 2] * z,
        T[1, 3] + T[1, 0] * x + T[1, 1] * y + T[1, 2] * z,
        T[2, 3] + T[2, 0] * x + T[2, 1] * y + T[2, 2] * z,
    )


@_jit
def margins_at(
    q: np.ndarray, model: np.ndarray, parts: tuple | None = None
) -> tuple[np.ndarray, np.ndarray, np.ndarray, int]:
    """The margins at joints ``q`` (see the ``supervisor`` module), the TCP pose and Jacobian.

    Args:
        parts: ``_unpack(model)`` when the caller has it.

    Returns:
        margins (9 + P + C,): joint limits (6), wrist, elbow, shoulder, one clearance per pair
        (where an obstacle's bounding box is nearer than the slow value, the exact clearance
        by GJK, ``convex_clearance``; NaN where that finds none, overlapping or not converged,
        so coal must measure it), the combined joint limits; the 4x4 TCP pose; its (6, 6) Jacobian
        (``tcp_jacobian``); how many margins are NaN.
    """
    parts = _unpack(model) if parts is None else parts
    placements, axes, limits, M_tcp, _, _, bodies, pairs, obstacles, couplings, _, vertices = parts
    elbow_to_axis4 = model[4] > 0.5
    table_z = model[5]
    Ts = chain_placements(q, placements, axes)
    n_pairs = pairs.shape[0]
    margins = np.empty(9 + n_pairs + couplings.shape[0])
    z = np.empty((6, 3))  # joint axes and origins in the base frame
    o = np.empty((6, 3))
    for j in range(6):
        margins[j] = min(q[j] - limits[0, j], limits[1, j] - q[j])
        for r in range(3):
            z[j, r] = Ts[j, r, 0] * axes[j, 0] + Ts[j, r, 1] * axes[j, 1] + Ts[j, r, 2] * axes[j, 2]
            o[j, r] = Ts[j, r, 3]
    z1, z2, z4, z5, z6 = _row(z, 0), _row(z, 1), _row(z, 3), _row(z, 4), _row(z, 5)
    o1, o2, o3, o5, o6 = _row(o, 0), _row(o, 1), _row(o, 2), _row(o, 4), _row(o, 5)
    # Wrist: angle between axes 4 and 6, folded to [0, 90] deg (0 when axis 5 is at 0).
    c = _cross(z4, z6)
    margins[6] = math.atan2(math.sqrt(_dot(c, c)), abs(_dot(z4, z6)))
    # Wrist centre: the point of axis 6 closest to axis 5.
    w = _axpy(-1.0, o5, o6)
    b = _dot(z5, z6)
    denom = 1.0 - b * b
    centre = o6
    if denom > 1e-9:
        centre = _axpy((b * _dot(z5, w) - _dot(z6, w)) / denom, z6, o6)
    # Elbow: angle between upper arm and forearm in the plane normal to axis 2.
    u = _axpy(-1.0, o2, o3)
    v = _axpy(-1.0, o3, _row(o, 3) if elbow_to_axis4 else centre)
    u = _axpy(-_dot(u, z2), z2, u)
    v = _axpy(-_dot(v, z2), z2, v)
    c = _cross(u, v)
    margins[7] = math.atan2(math.sqrt(_dot(c, c)), _dot(u, v))
    # Shoulder: the wrist centre's distance from the axis-1 line, in the arm plane.
    across = _cross(z1, z2)
    norm = math.sqrt(_dot(across, across))
    margins[8] = abs(_dot(_axpy(-1.0, o1, centre), across)) / norm if norm > 1e-9 else np.inf
    # Collisions: the table plane exactly; boxes and hull by their bounding box, from below.
    n_near = 0
    for i in range(n_pairs):
        k = int(pairs[i, 0])
        obstacle = int(pairs[i, 1])
        T = Ts[int(bodies[k, 0])]
        a = _end(T, bodies[k], 1)
        e = _end(T, bodies[k], 4)
        # How far the body reaches beyond its end points along each base axis: r for a
        # capsule; r sqrt(1 - u_k^2) for a flat-ended cylinder of unit axis u (its rim).
        radius = bodies[k, 7]
        d = _axpy(-1.0, a, e)
        length2 = max(_dot(d, d), 1e-300)
        gap2 = 0.0
        for r in range(3):
            reach = radius
            if bodies[k, 8] > 0.5:
                reach = radius * math.sqrt(max(0.0, 1.0 - d[r] * d[r] / length2))
            if obstacle < 0:
                if r == 2:
                    margins[9 + i] = min(a[2], e[2]) - reach - table_z
                continue
            g = max(
                0.0,
                obstacles[obstacle, r] - (max(a[r], e[r]) + reach),
                (min(a[r], e[r]) - reach) - obstacles[obstacle, 3 + r],
            )
            gap2 += g * g
        if obstacle < 0:
            continue
        bound = math.sqrt(gap2)
        if bound >= pairs[i, 2]:
            margins[9 + i] = bound
            continue
        first, count = int(obstacles[obstacle, 6]), int(obstacles[obstacle, 7])
        exact = np.nan
        if count > 0:
            corners = vertices[first : first + count]
            exact = convex_clearance(corners, a, e, radius, bodies[k, 8] > 0.5)
        margins[9 + i] = exact
        if math.isnan(exact):
            n_near += 1
    # Combined joint limits: lower <= coefficients . q <= upper.
    for k in range(couplings.shape[0]):
        value = 0.0
        for j in range(6):
            value += couplings[k, j] * q[j]
        margins[9 + n_pairs + k] = min(value - couplings[k, 6], couplings[k, 7] - value)
    T_tcp = _compose(Ts[5], M_tcp)
    return margins, T_tcp, tcp_jacobian(z, o, T_tcp), n_near


@_jit
def convex_clearance(corners: np.ndarray, a: tuple, e: tuple, radius: float, flat: bool) -> float:
    """The clearance between the convex hull of ``corners`` (N, 3) and a body (the capsule, or
    the flat-ended cylinder, of radius ``radius`` around the segment a-e), by GJK (Gilbert,
    Johnson and Keerthi 1988): the distance of the origin from their Minkowski difference,
    whose support point in a direction d is the hull's in d minus the body's in -d. Each
    iteration adds the support point in -v to the simplex and moves v, the simplex's point
    nearest the origin (``_nearest_on_simplex``), until |v|^2 - v.w <= tol |v| (then |v| is
    within tol of the clearance). NaN when the two overlap or it does not converge: the caller
    asks coal."""
    simplex = np.empty((4, 3))
    work = np.empty((4, 3))
    d = (1.0, 0.0, 0.0)
    w = _difference_support(corners, a, e, radius, flat, d)
    simplex[0, 0], simplex[0, 1], simplex[0, 2] = w[0], w[1], w[2]
    n = 1
    v = w
    for _ in range(GJK_MAX_ITERATIONS):
        vv = _dot(v, v)
        if vv < 1e-24:
            return np.nan  # touching or overlapping
        w = _difference_support(corners, a, e, radius, flat, (-v[0], -v[1], -v[2]))
        if vv - _dot(v, w) <= GJK_TOLERANCE_M * math.sqrt(vv):
            return math.sqrt(vv)
        if n == 4:
            return np.nan  # degenerate: no progress possible
        simplex[n, 0], simplex[n, 1], simplex[n, 2] = w[0], w[1], w[2]
        n += 1
        v, n = _nearest_on_simplex(simplex, n, work)
    return np.nan


@_jit
def _difference_support(
    corners: np.ndarray, a: tuple, e: tuple, radius: float, flat: bool, d: tuple
) -> tuple:
    """The support point in ``d`` of (hull of ``corners``) minus (the body)."""
    best, k = -np.inf, 0
    for i in range(corners.shape[0]):
        value = corners[i, 0] * d[0] + corners[i, 1] * d[1] + corners[i, 2] * d[2]
        if value > best:
            best, k = value, i
    # The body's support point in -d: its end furthest along -d, then its rim (cylinder) or
    # its sphere (capsule) towards -d.
    m = (-d[0], -d[1], -d[2])
    end = a if _dot(a, m) >= _dot(e, m) else e
    axis = _axpy(-1.0, a, e)
    length2 = _dot(axis, axis)
    full = math.sqrt(_dot(m, m))
    if flat and length2 > 0.0:
        along = _dot(m, axis) / length2
        m = (m[0] - along * axis[0], m[1] - along * axis[1], m[2] - along * axis[2])
    size = math.sqrt(_dot(m, m))
    # Along the axis (to rounding) the whole end disc is nearest: its centre serves.
    k_r = radius / size if size > 1e-9 * full else 0.0
    return (
        corners[k, 0] - (end[0] + k_r * m[0]),
        corners[k, 1] - (end[1] + k_r * m[1]),
        corners[k, 2] - (end[2] + k_r * m[2]),
    )


@_jit
def _nearest_on_simplex(simplex: np.ndarray, n: int, work: np.ndarray) -> tuple:
    """The point of the simplex's first ``n`` rows (1-4 points) nearest the origin, and the
    simplex reduced to the points whose face holds it (rows moved to the front): of every
    face whose nearest point on its plane has barycentric weights all >= 0, the nearest.
    ``work``: (4, 3) scratch."""
    best_v = (0.0, 0.0, 0.0)
    best, best_mask = np.inf, 0
    for mask in range(1, 1 << n):
        k = 0
        first = -1
        for i in range(n):
            if mask & (1 << i):
                if first < 0:
                    first = i
                else:  # the edges from the first point: D's columns
                    work[k, 0] = simplex[i, 0] - simplex[first, 0]
                    work[k, 1] = simplex[i, 1] - simplex[first, 1]
                    work[k, 2] = simplex[i, 2] - simplex[first, 2]
                    k += 1
        p0 = (simplex[first, 0], simplex[first, 1], simplex[first, 2])
        x = p0
        if k > 0:
            # x = p0 + D mu with (D^T D) mu = -D^T p0, by Cramer's rule (k <= 3).
            d0 = (work[0, 0], work[0, 1], work[0, 2])
            d1 = (work[1, 0], work[1, 1], work[1, 2]) if k > 1 else d0
            d2 = (work[2, 0], work[2, 1], work[2, 2]) if k > 2 else d0
            g00, g01, g02 = _dot(d0, d0), _dot(d0, d1), _dot(d0, d2)
            g11, g12, g22 = _dot(d1, d1), _dot(d1, d2), _dot(d2, d2)
            r0, r1, r2 = -_dot(d0, p0), -_dot(d1, p0), -_dot(d2, p0)
            mu0 = mu1 = mu2 = 0.0
            if k == 1:
                if g00 < 1e-30:
                    continue
                mu0 = r0 / g00
            elif k == 2:
                det = g00 * g11 - g01 * g01
                if abs(det) < 1e-30:
                    continue
                mu0 = (r0 * g11 - g01 * r1) / det
                mu1 = (g00 * r1 - g01 * r0) / det
            else:
                c00 = g11 * g22 - g12 * g12
                c01 = g02 * g12 - g01 * g22
                c02 = g01 * g12 - g02 * g11
                det = g00 * c00 + g01 * c01 + g02 * c02
                if abs(det) < 1e-36:
                    continue
                c11 = g00 * g22 - g02 * g02
                c12 = g01 * g02 - g00 * g12
                c22 = g00 * g11 - g01 * g01
                mu0 = (c00 * r0 + c01 * r1 + c02 * r2) / det
                mu1 = (c01 * r0 + c11 * r1 + c12 * r2) / det
                mu2 = (c02 * r0 + c12 * r1 + c22 * r2) / det
            if min(mu0, mu1, mu2) < -1e-12 or mu0 + mu1 + mu2 > 1.0 + 1e-12:
                continue
            x = _axpy(mu0, d0, x)
            if k > 1:
                x = _axpy(mu1, d1, x)
            if k > 2:
                x = _axpy(mu2, d2, x)
        norm2 = _dot(x, x)
        if norm2 < best:
            best, best_v, best_mask = norm2, x, mask
    k = 0
    for i in range(n):  # keep the face's points, in order, at the front
        if best_mask & (1 << i):
            work[k, 0], work[k, 1], work[k, 2] = simplex[i, 0], simplex[i, 1], simplex[i, 2]
            k += 1
    simplex[:k] = work[:k]
    return best_v, k


@_jit
def tcp_jacobian(z: np.ndarray, o: np.ndarray, T_tcp: np.ndarray) -> np.ndarray:
    """(6, 6) Jacobian [v; omega] of the TCP point in base-aligned axes (pinocchio's
    ``LOCAL_WORLD_ALIGNED``) from the joints' axes ``z`` and origins ``o`` (6, 3), base frame:
    column j = [z_j x (p_tcp - o_j); z_j] (revolute joints)."""
    J = np.empty((6, 6))
    for j in range(6):
        dx, dy, dz = T_tcp[0, 3] - o[j, 0], T_tcp[1, 3] - o[j, 1], T_tcp[2, 3] - o[j, 2]
        J[0, j] = z[j, 1] * dz - z[j, 2] * dy
        J[1, j] = z[j, 2] * dx - z[j, 0] * dz
        J[2, j] = z[j, 0] * dy - z[j, 1] * dx
        J[3, j], J[4, j], J[5, j] = z[j, 0], z[j, 1], z[j, 2]
    return J


@_jit
def _compose(A: np.ndarray, B: np.ndarray) -> np.ndarray:
    """A B of two rigid 4x4 transforms."""
    out = np.zeros((4, 4))
    out[:3, :3] = mul3(A, B)
    for r in range(3):
        out[r, 3] = A[r, 0] * B[0, 3] + A[r, 1] * B[1, 3] + A[r, 2] * B[2, 3] + A[r, 3]
    out[3, 3] = 1.0
    return out


@_jit
def decide(
    m0: np.ndarray,
    m1: np.ndarray,
    q0: np.ndarray,
    q1: np.ndarray,
    T_ref: np.ndarray,
    T_tcp: np.ndarray,
    track: bool,
    model: np.ndarray,
    parts: tuple | None = None,
) -> tuple[float, int, int, float]:
    """The speed scale of a step and its verdict, from the margins before (m0) and after (m1).

    scale = min over approached limits (m1 < m0 - APPROACH_TOLERANCE) of
    clip((m0 - stop) / (slow - stop), min_scale, 1), and 0.95 / max_i(|dq_i| / bound_i) when a
    joint would move too far.
    Verdict (code, index, value): 0 allowed; 1 joint ``index`` steps ``value`` rad, over its
    bound; 2 margin ``index`` ends at ``value``, past its stop while shrinking (the worst);
    3 the TCP misses the reference ``T_ref`` by ``value`` (index 0: metres, 1: radians; only
    when ``track``).
    """
    parts = _unpack(model) if parts is None else parts
    _, _, _, _, step_bound, tracking, _, _, _, _, thresholds, _ = parts
    min_scale = model[6]
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
    if not track:
        return scale, 0, -1, 0.0
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


@_jit
def increment_proposal(
    q0: np.ndarray,
    T0: np.ndarray,
    J0: np.ndarray,
    T_ref: np.ndarray,
    step: np.ndarray,
    turn: np.ndarray,
    scale: float,
    model: np.ndarray,
    parts: tuple | None = None,
) -> tuple[np.ndarray, np.ndarray]:
    """The reference ``T_ref`` moved by ``scale`` x (``step``, ``turn``) and one IK step to it.

    T = (p_ref + s step, R_ref exp(s turn)) (``turn`` in the reference's own axes);
    q = ``_kernels.ik_newton_step`` from ``q0`` at the pose ``T0`` with Jacobian ``J0``.
    """
    limits = (_unpack(model) if parts is None else parts)[2]
    T = np.eye(4)
    T[:3, :3] = mul3(T_ref, exp3(turn * scale))
    for i in range(3):
        T[i, 3] = T_ref[i, 3] + step[i] * scale
    return T, ik_newton_step(q0, T0, J0, T, limits[0], limits[1], model[7])


# ``supervise_increment``'s memory: joints (6), TCP pose (16), Jacobian (36), then margins.
MEMORY_MARGINS = 58


@_jit
def supervise_increment(
    q0: np.ndarray,
    T_ref: np.ndarray,
    step: np.ndarray,
    turn: np.ndarray,
    model: np.ndarray,
    memory: np.ndarray,
) -> tuple[int, float, int, int, float, np.ndarray, np.ndarray]:
    """One supervised period of ``increment_proposal`` (``Supervisor.supervise``'s logic):
    propose at scale 1, judge against the margins at ``q0``; if slowed, propose at the scale
    and judge again for the verdict. The pose and Jacobian at ``q0`` are the chain's
    (``chain_placements``, ``tcp_jacobian``).

    Args:
        memory: (MEMORY_MARGINS + margins,) the last step decided here: its joints (NaN:
            none), TCP pose, Jacobian and margins, which serve when ``q0`` is those joints;
            updated to this step's.

    Returns:
        (status, scale, code, index, value, T_ref, q_next); status 0: decided; -1: not
        decided here (a proposal is not finite, or an obstacle is within a slow zone and needs
        coal's exact clearance): run ``Supervisor.supervise``.
    """
    parts = _unpack(model)
    scale = 1.0
    remembered_T = memory[6:22].reshape((4, 4))
    remembered_J = memory[22:58].reshape((6, 6))
    m0, T0, J0 = memory[MEMORY_MARGINS:], remembered_T, remembered_J
    for i in range(6):
        if memory[i] != q0[i]:
            m0, T0, J0, n_near = margins_at(q0, model, parts)
            if n_near > 0:
                return -1, scale, 0, -1, 0.0, T_ref, q0
            break
    for attempt in range(2):
        T, q1 = increment_proposal(q0, T0, J0, T_ref, step, turn, scale, model, parts)
        size = 0.0
        for i in range(6):
            size += q1[i] * q1[i]
        if not math.isfinite(size):
            break
        m1, T_tcp, J1, n_near = margins_at(q1, model, parts)
        if n_near > 0:
            break
        s, code, index, value = decide(m0, m1, q0, q1, T, T_tcp, True, model, parts)
        if attempt == 0:
            scale = s
        if attempt == 1 or s >= 1.0:
            memory[:6] = q1
            remembered_T[:, :] = T_tcp
            remembered_J[:, :] = J1
            memory[MEMORY_MARGINS:] = m1
            return 0, scale, code, index, value, T, q1
    return -1, scale, 0, -1, 0.0, T_ref, q0
