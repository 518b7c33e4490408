"""Compiled (numba) kernels of the 4 ms control step: the arithmetic between pinocchio and coal.

PROBLEM   One control period does ~30 small vector operations besides pinocchio's FK/Jacobian and
          coal's collision query; as separate numpy calls they cost 1-12 us each, ten times the
          two library calls together.
STRATEGY  Fuse them into four numba kernels (arm-side pose, sensor reading, force compensation,
          reference pose + IK step). Each equals a documented numpy reference (tests check it).
SOLUTION  ``arm_side_pose``, ``sensor_reading``, ``contact_wrench_tcp_base``, ``path_reference``,
          ``ik_newton_step``; compiled on first use and cached on disk.

The deviation-height reduction of post-processing (``deviation_height_kept``) lives here too: the
same chord-by-chord scan as ``postprocess.reduce_deviation_height_reference``, with a certificate
that skips most of the per-end rescans (see its docstring).
"""

from __future__ import annotations

import math

import numba
import numpy as np

_jit = numba.njit(cache=True, fastmath=False, nogil=True)


@_jit
def cross(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    out = np.empty(3)
    out[0] = a[1] * b[2] - a[2] * b[1]
    out[1] = a[2] * b[0] - a[0] * b[2]
    out[2] = a[0] * b[1] - a[1] * b[0]
    return out


@_jit
def exp3(w: np.ndarray) -> np.ndarray:
    """Rotation matrix of a rotation vector (Rodrigues)."""
    theta = math.sqrt(w[0] * w[0] + w[1] * w[1] + w[2] * w[2])
    R = np.eye(3)
    if theta < 1e-12:
        R[0, 1], R[0, 2], R[1, 2] = -w[2], w[1], -w[0]
        R[1, 0], R[2, 0], R[2, 1] = w[2], -w[1], w[0]
        return R
    kx, ky, kz = w[0] / theta, w[1] / theta, w[2] / theta
    s, c = math.sin(theta), math.cos(theta)
    v = 1.0 - c
    R[0, 0] = c + kx * kx * v
    R[0, 1] = kx * ky * v - kz * s
    R[0, 2] = kx * kz * v + ky * s
    R[1, 0] = ky * kx * v + kz * s
    R[1, 1] = c + ky * ky * v
    R[1, 2] = ky * kz * v - kx * s
    R[2, 0] = kz * kx * v - ky * s
    R[2, 1] = kz * ky * v + kx * s
    R[2, 2] = c + kz * kz * v
    return R


@_jit
def log3(R: np.ndarray) -> np.ndarray:
    """Rotation vector of a rotation matrix (small and large angles)."""
    out = np.empty(3)
    cos_t = (R[0, 0] + R[1, 1] + R[2, 2] - 1.0) / 2.0
    cos_t = min(1.0, max(-1.0, cos_t))
    theta = math.acos(cos_t)
    vx, vy, vz = R[2, 1] - R[1, 2], R[0, 2] - R[2, 0], R[1, 0] - R[0, 1]
    if theta < 1e-6:
        out[0], out[1], out[2] = 0.5 * vx, 0.5 * vy, 0.5 * vz
        return out
    if math.pi - theta < 1e-2:
        # Near pi: axis from the symmetric part (1 - cos t) a a^T, sign from the skew part.
        best, col = -1.0, 0
        for i in range(3):
            if R[i, i] - cos_t > best:
                best, col = R[i, i] - cos_t, i
        ax = 0.5 * (R[0, col] + R[col, 0]) - (cos_t if col == 0 else 0.0)
        ay = 0.5 * (R[1, col] + R[col, 1]) - (cos_t if col == 1 else 0.0)
        az = 0.5 * (R[2, col] + R[col, 2]) - (cos_t if col == 2 else 0.0)
        n = math.sqrt(ax * ax + ay * ay + az * az)
        if ax * vx + ay * vy + az * vz < 0:
            n = -n
        out[0], out[1], out[2] = ax / n * theta, ay / n * theta, az / n * theta
        return out
    k = theta / (2.0 * math.sin(theta))
    out[0], out[1], out[2] = k * vx, k * vy, k * vz
    return out


@_jit
def arm_side_pose(
    T_motor: np.ndarray, J: np.ndarray, wrench: np.ndarray, compliance: np.ndarray
) -> tuple[np.ndarray, np.ndarray]:
    """Arm-side TCP pose under ``wrench``: dq = Kq^-1 J^T W, T_arm = T_motor moved by J dq.

    The rotation is updated to first order (R + [J dq]_x R); deflections are microradians.
    """
    dq = compliance * (J.T @ wrench)
    dx = J @ dq
    T = T_motor.copy()
    T[0, 3] += dx[0]
    T[1, 3] += dx[1]
    T[2, 3] += dx[2]
    wx, wy, wz = dx[3], dx[4], dx[5]
    for j in range(3):
        r0, r1, r2 = T_motor[0, j], T_motor[1, j], T_motor[2, j]
        T[0, j] = r0 + (-wz * r1 + wy * r2)
        T[1, j] = r1 + (wz * r0 - wx * r2)
        T[2, j] = r2 + (-wy * r0 + wx * r1)
    return T, dq


@_jit
def sensor_reading(
    R_flange: np.ndarray,
    wrench: np.ndarray,
    weight: np.ndarray,
    com: np.ndarray,
    tcp: np.ndarray,
    bias: np.ndarray,
    noise: np.ndarray,
) -> np.ndarray:
    """F/T reading in the sensor frame: contact wrench moved to the sensor + weight + bias + noise.

    f_s = R^T (F_c + m g);  tau_s = R^T tau_c + r_tcp x (R^T F_c) + r_com x (R^T m g).
    """
    Rt = R_flange.T
    f_c = Rt @ wrench[:3]
    f_g = Rt @ weight
    tau = Rt @ wrench[3:] + cross(tcp, f_c) + cross(com, f_g)
    out = np.empty(6)
    out[:3] = f_c + f_g
    out[3:] = tau
    return out + bias + noise


@_jit
def contact_wrench_tcp_base(
    reading: np.ndarray,
    R_flange: np.ndarray,
    weight: np.ndarray,
    com: np.ndarray,
    tcp: np.ndarray,
    bias: np.ndarray,
) -> np.ndarray:
    """The controller's compensation: remove bias and the tool's weight, move to the TCP.

    w_s = reading - bias - [R^T m g; r_com x R^T m g]; tau_tcp = tau_s - r_tcp x f_s; to base.
    """
    f_g = R_flange.T @ weight
    f_s = reading[:3] - bias[:3] - f_g
    tau_s = reading[3:] - bias[3:] - cross(com, f_g)
    tau_tcp = tau_s - cross(tcp, f_s)
    out = np.empty(6)
    out[:3] = R_flange @ f_s
    out[3:] = R_flange @ tau_tcp
    return out


@_jit
def ik_newton_step(
    q: np.ndarray,
    T: np.ndarray,
    J: np.ndarray,
    T_target: np.ndarray,
    lower: np.ndarray,
    upper: np.ndarray,
    damping: float,
) -> np.ndarray:
    """One Newton step of the 6-D pose error (damped least squares near singularities), clamped."""
    e = np.empty(6)
    e[0] = T_target[0, 3] - T[0, 3]
    e[1] = T_target[1, 3] - T[1, 3]
    e[2] = T_target[2, 3] - T[2, 3]
    e[3:] = log3(T_target[:3, :3] @ T[:3, :3].T)
    Jc = np.ascontiguousarray(J)
    dq = np.linalg.solve(Jc, e)
    if not np.isfinite(dq).all() or dq @ dq > 1e-4:
        A = Jc @ Jc.T
        for i in range(6):
            A[i, i] += damping * damping
        dq = Jc.T @ np.linalg.solve(A, e)
    out = q + dq
    for i in range(6):
        out[i] = min(max(out[i], lower[i]), upper[i])
    return out


@_jit
def _closest_on_triangle(p: np.ndarray, a: np.ndarray, b: np.ndarray, c: np.ndarray) -> np.ndarray:
    """Closest point of triangle abc to p (Ericson, Real-Time Collision Detection, 5.1.5)."""
    ab = b - a
    ac = c - a
    ap = p - a
    d1 = ab @ ap
    d2 = ac @ ap
    if d1 <= 0.0 and d2 <= 0.0:
        return a.copy()
    bp = p - b
    d3 = ab @ bp
    d4 = ac @ bp
    if d3 >= 0.0 and d4 <= d3:
        return b.copy()
    vc = d1 * d4 - d3 * d2
    if vc <= 0.0 and d1 >= 0.0 and d3 <= 0.0:
        return a + ab * (d1 / (d1 - d3))
    cp = p - c
    d5 = ab @ cp
    d6 = ac @ cp
    if d6 >= 0.0 and d5 <= d6:
        return c.copy()
    vb = d5 * d2 - d1 * d6
    if vb <= 0.0 and d2 >= 0.0 and d6 <= 0.0:
        return a + ac * (d2 / (d2 - d6))
    va = d3 * d6 - d5 * d4
    if va <= 0.0 and (d4 - d3) >= 0.0 and (d5 - d6) >= 0.0:
        return b + (c - b) * ((d4 - d3) / ((d4 - d3) + (d5 - d6)))
    denom = 1.0 / (va + vb + vc)
    return a + ab * (vb * denom) + ac * (vc * denom)


@_jit
def nearest_face(
    p: np.ndarray, triangles: np.ndarray, normals: np.ndarray, faces: np.ndarray
) -> tuple[float, np.ndarray, np.ndarray, bool]:
    """The nearest of ``faces`` (indices into ``triangles`` (F, 3, 3) and their outward
    ``normals`` (F, 3)) to the point ``p``: (distance, closest point, that face's normal,
    inside). Inside: ``p`` lies behind every nearest face (ties within 1e-12 m: several faces
    meet at the closest point, an edge or a corner; outside when any of them faces ``p``)."""
    best = np.inf
    closest = np.zeros(3)
    normal = np.zeros(3)
    inside = False
    for k in range(faces.shape[0]):
        f = faces[k]
        q = _closest_on_triangle(p, triangles[f, 0], triangles[f, 1], triangles[f, 2])
        d = p - q
        dist = math.sqrt(d @ d)
        behind = (d @ normals[f]) < 0.0
        if dist < best - 1e-12:
            best = dist
            closest = q
            normal = normals[f].copy()
            inside = behind
        elif dist <= best + 1e-12:
            inside = inside and behind
            if not behind:
                normal = normals[f].copy()
    return best, closest, normal, inside


@_jit
def winding_number(p: np.ndarray, triangles: np.ndarray) -> float:
    """Generalised winding number of the closed surface ``triangles`` (F, 3, 3) about ``p``:
    1 inside a closed outward-oriented mesh, 0 outside (the solid angles of the triangles seen
    from p over 4 pi; Van Oosterom and Strackee, IEEE Trans. Biomed. Eng. 30(2), 1983)."""
    total = 0.0
    for f in range(triangles.shape[0]):
        ax, ay, az = triangles[f, 0, 0] - p[0], triangles[f, 0, 1] - p[1], triangles[f, 0, 2] - p[2]
        bx, by, bz = triangles[f, 1, 0] - p[0], triangles[f, 1, 1] - p[1], triangles[f, 1, 2] - p[2]
        cx, cy, cz = triangles[f, 2, 0] - p[0], triangles[f, 2, 1] - p[1], triangles[f, 2, 2] - p[2]
        la = math.sqrt(ax * ax + ay * ay + az * az)
        lb = math.sqrt(bx * bx + by * by + bz * bz)
        lc = math.sqrt(cx * cx + cy * cy + cz * cz)
        det = ax * (by * cz - bz * cy) - ay * (bx * cz - bz * cx) + az * (bx * cy - by * cx)
        ab = ax * bx + ay * by + az * bz
        bc = bx * cx + by * cy + bz * cz
        ca = cx * ax + cy * ay + cz * az
        total += 2.0 * math.atan2(det, la * lb * lc + ab * lc + bc * la + ca * lb)
    return total / (4.0 * math.pi)


@_jit
def path_reference(
    Ra: np.ndarray,
    omega: np.ndarray,
    fraction: float,
    a: np.ndarray,
    xp: np.ndarray,
    side: float,
    s: float,
    y: float,
    h: float,
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Reference pose of path learning and its path frame.

    R = Ra exp(f omega) (slerp between the guide orientations), Yp = side * (Zp x Xp) normalised,
    Zp' = Xp x Yp; p = a + s Xp + y Yp + h Zp'. Returns (T_ref, Yp, Zp').
    """
    f = min(max(fraction, 0.0), 1.0)
    R = Ra @ exp3(omega * f)
    zt = R[:, 2].copy()
    yp = cross(zt, xp) * side
    yp /= math.sqrt(yp @ yp)
    zp = cross(xp, yp)
    T = np.eye(4)
    T[:3, :3] = R
    T[:3, 3] = a + s * xp + y * yp + h * zp
    return T, yp, zp


@_jit
def admittance_reference(
    T_ref: np.ndarray,
    R_frame: np.ndarray,
    velocity: np.ndarray,
    wrench_base: np.ndarray,
    mask: np.ndarray,
    mass: np.ndarray,
    damping: np.ndarray,
    deadband: np.ndarray,
    limit: np.ndarray,
    dt: float,
) -> tuple[np.ndarray, np.ndarray]:
    """One admittance period: M dv/dt + D v = W in the selection frame, integrated into T_ref.

    W (base axes) is rotated into the selection frame, shrunk by the deadband, and the damping is
    taken implicitly: v+ = (M v + dt W) / (M + D dt); stiff axes (mask 0) keep v = 0. The
    limits bound the speed and the rate as vectors (``limit[0]`` the norm of the linear part,
    ``limit[3]`` of the angular part), so a diagonal push is no faster than a straight one
    (clipping each axis let it reach sqrt(3) x the limit; issue 19, R11).
    Returns (new T_ref, new v).
    """
    Rt = R_frame.T
    w = np.empty(6)
    w[:3] = Rt @ wrench_base[:3]
    w[3:] = Rt @ wrench_base[3:]
    v = np.empty(6)
    for i in range(6):
        wi = w[i]
        mag = abs(wi) - deadband[i]
        wi = math.copysign(mag, wi) if mag > 0.0 else 0.0
        vi = (mass[i] * velocity[i] + dt * wi) / (mass[i] + damping[i] * dt)
        v[i] = vi * mask[i]
    for start in (0, 3):
        norm = math.sqrt(v[start] ** 2 + v[start + 1] ** 2 + v[start + 2] ** 2)
        if norm > limit[start]:
            scale = limit[start] / norm
            for i in range(start, start + 3):
                v[i] *= scale
    lin = R_frame @ v[:3]
    ang = R_frame @ v[3:]
    T = T_ref.copy()
    T[0, 3] += lin[0] * dt
    T[1, 3] += lin[1] * dt
    T[2, 3] += lin[2] * dt
    if ang[0] != 0.0 or ang[1] != 0.0 or ang[2] != 0.0:
        T[:3, :3] = exp3(ang * dt) @ T_ref[:3, :3]
    return T, v


# Relative safety margin of the certificate, so that a chord end it accepts also passes the exact
# test despite rounding (the exact test decides every case within this margin of the tolerance).
_CERTIFICATE_MARGIN = 1e-9
# Absolute safety on the direction bound [rad]: covers the rounding of unit vectors.
_DIRECTION_EPS = 1e-12


@_jit
def deviation_height_kept(points: np.ndarray, tolerance: float) -> np.ndarray:
    """Indices kept by the deviation-height method (chapter fig. 3) on (n, 3) points.

    Same decisions as the literal scan (``postprocess.reduce_deviation_height_reference``): from
    the segment's start ``a`` every end ``e = a+2, a+3, ...`` is tried in turn, the first end
    whose chord leaves some intermediate sample farther than ``tolerance`` fails, and ``e - 1``
    becomes the next start. The literal scan rescans all intermediates for every end (cost grows
    with the samples per chord squared); this one mostly checks a certificate in O(1):

    For a unit chord direction u and a reference direction u0 (an end fully checked before),
    a sample at r = p - a has  |r x u| <= |r x u0| + |r| |u - u0|  (triangle inequality), so a
    sample with height d0 about u0 stays within the tolerance while |u - u0| <= (tol - d0) / |r|.
    The minimum of these margins over the intermediates, delta*, certifies a new end when
    |u - u0| <= delta*. A sample that becomes an intermediate later is measured about the then
    current direction u1 and enters with margin (tol - d1) / |r| - |u1 - u0| (same inequality
    through u1). When the certificate does not hold, the end is checked exactly (exit at the
    first failing sample) and becomes the new reference. Near a segment's end the margin
    roughly halves at each exact check, so exact checks per segment grow like the log of its
    samples, and the cost stays near-linear in the samples.
    """
    n = points.shape[0]
    kept = np.empty(max(n, 1), dtype=np.int64)
    if n == 0:
        return kept[:0]
    kept[0] = 0
    m = 1
    start = 0
    while start < n - 1:
        end = _first_failing_end(points, start, tolerance)
        if end < 0:
            break
        start = end - 1
        kept[m] = start
        m += 1
    if kept[m - 1] != n - 1:
        kept[m] = n - 1
        m += 1
    return kept[:m].copy()


@_jit
def _first_failing_end(points: np.ndarray, start: int, tolerance: float) -> int:
    """Smallest end >= start + 2 whose chord from ``start`` fails the tolerance, or -1."""
    n = points.shape[0]
    tol_cert = tolerance * (1.0 - _CERTIFICATE_MARGIN)
    ax, ay, az = points[start, 0], points[start, 1], points[start, 2]
    # Reference direction and the certified radius around it (< 0: no certificate).
    u0x, u0y, u0z = 0.0, 0.0, 0.0
    delta_star = -1.0
    for end in range(start + 2, n):
        cx, cy, cz = points[end, 0] - ax, points[end, 1] - ay, points[end, 2] - az
        length = math.sqrt(cx * cx + cy * cy + cz * cz)
        if length < 1e-15:
            # Degenerate chord: heights are distances from the start (as deviation_heights).
            for i in range(start + 1, end):
                rx, ry, rz = points[i, 0] - ax, points[i, 1] - ay, points[i, 2] - az
                if math.sqrt(rx * rx + ry * ry + rz * rz) > tolerance:
                    return end
            delta_star = -1.0
            continue
        ux, uy, uz = cx / length, cy / length, cz / length
        if delta_star >= 0.0:
            dx, dy, dz = ux - u0x, uy - u0y, uz - u0z
            shift = math.sqrt(dx * dx + dy * dy + dz * dz)
            # The sample end - 1 has just become an intermediate: its margin through u.
            i = end - 1
            rx, ry, rz = points[i, 0] - ax, points[i, 1] - ay, points[i, 2] - az
            r = math.sqrt(rx * rx + ry * ry + rz * rz)
            if r > 0.0:
                along = rx * ux + ry * uy + rz * uz
                hx, hy, hz = rx - along * ux, ry - along * uy, rz - along * uz
                height = math.sqrt(hx * hx + hy * hy + hz * hz)
                margin = (tol_cert - height) / r - shift - _DIRECTION_EPS
                delta_star = min(delta_star, margin)
            if shift <= delta_star:
                continue
        # Exact check of this end; it becomes the reference.
        best = np.inf
        for i in range(start + 1, end):
            rx, ry, rz = points[i, 0] - ax, points[i, 1] - ay, points[i, 2] - az
            along = rx * ux + ry * uy + rz * uz
            hx, hy, hz = rx - along * ux, ry - along * uy, rz - along * uz
            height = math.sqrt(hx * hx + hy * hy + hz * hz)
            if height > tolerance:
                return end
            r = math.sqrt(rx * rx + ry * ry + rz * rz)
            if r > 0.0:
                best = min(best, (tol_cert - height) / r - _DIRECTION_EPS)
        u0x, u0y, u0z = ux, uy, uz
        delta_star = best
    return -1
