"""Compiled (numba) kernels of the 4 ms control step: the arithmetic between pinocchio and coal.

PROBLEM   One control period does ~30 small vector operations besides pinocchio's FK/Jacobian and
          coal's collision query; as separate numpy calls they cost 1-12 us each, ten times the
          two library calls together, and even inside a kernel a BLAS or LAPACK call on a 3x3
          or 6x6 matrix costs more than the arithmetic it does.
STRATEGY  Fuse them into numba kernels over plain loops (no BLAS calls: ``mul3``, ``rotate``,
          ``solve``). Each is the private copy of a public function (pinocchio's ``exp3`` and
          ``log3``, ``Robot.ik_step``'s Newton step, the sensor model of ``sensor``) or follows a
          documented formula, and a test checks that it agrees with its reference.
SOLUTION  ``exp3``, ``log3``, ``ik_newton_step``, ``arm_side_pose``, ``sensor_reading``,
          ``contact_wrench_tcp_base``, ``ball_contact``, ``admittance_reference``; compiled on
          first use and cached on disk.

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
def mul3(
    A: np.ndarray, B: np.ndarray, transpose_a: bool = False, transpose_b: bool = False
) -> np.ndarray:
    """(3, 3) product of the upper-left 3x3 blocks of ``A`` and ``B``, each transposed when
    asked."""
    out = np.empty((3, 3))
    for i in range(3):
        for j in range(3):
            s = 0.0
            for k in range(3):
                s += (A[k, i] if transpose_a else A[i, k]) * (B[j, k] if transpose_b else B[k, j])
            out[i, j] = s
    return out


@_jit
def rotate(R: np.ndarray, v: np.ndarray, offset: int = 0, transpose: bool = False) -> np.ndarray:
    """(3,) R v[offset : offset + 3] (R^T v when ``transpose``), R the upper-left 3x3 block."""
    out = np.empty(3)
    for i in range(3):
        s = 0.0
        for k in range(3):
            s += (R[k, i] if transpose else R[i, k]) * v[offset + k]
        out[i] = s
    return out


@_jit
def solve(A: np.ndarray, b: np.ndarray) -> np.ndarray:
    """x with A x = b for a small square A (Gaussian elimination, partial pivoting); all NaN
    when A is singular."""
    n = b.shape[0]
    M = np.empty((n, n + 1))
    for i in range(n):
        for j in range(n):
            M[i, j] = A[i, j]
        M[i, n] = b[i]
    for col in range(n):
        pivot = col
        for r in range(col + 1, n):
            if abs(M[r, col]) > abs(M[pivot, col]):
                pivot = r
        if M[pivot, col] == 0.0:
            return np.full(n, np.nan)
        if pivot != col:
            for j in range(col, n + 1):
                M[col, j], M[pivot, j] = M[pivot, j], M[col, j]
        for r in range(col + 1, n):
            f = M[r, col] / M[col, col]
            for j in range(col + 1, n + 1):
                M[r, j] -= f * M[col, j]
    x = np.empty(n)
    for i in range(n - 1, -1, -1):
        s = M[i, n]
        for j in range(i + 1, n):
            s -= M[i, j] * x[j]
        x[i] = s / M[i, i]
    return x


@_jit
def clamp(q: np.ndarray, lower: np.ndarray, upper: np.ndarray) -> np.ndarray:
    """``q`` moved into [lower, upper], element by element (a new array)."""
    out = np.empty(q.shape[0])
    for i in range(q.shape[0]):
        out[i] = min(max(q[i], lower[i]), upper[i])
    return out


@_jit
def exp3(w: np.ndarray) -> np.ndarray:
    """Rotation matrix of a rotation vector (Rodrigues): ``pin.exp3``'s private copy."""
    theta = math.sqrt(w[0] * w[0] + w[1] * w[1] + w[2] * w[2])
    R = np.eye(3)
    if theta < 1e-12:
        R[0, 1], R[0, 2], R[1, 2] = -w[2], w[1], -w[0]
        R[1, 0], R[2, 0], R[2, 1] = w[2], -w[1], w[0]
        return R
    rotate_about(R, w[0] / theta, w[1] / theta, w[2] / theta, math.sin(theta), math.cos(theta))
    return R


@_jit
def rotate_about(R: np.ndarray, kx: float, ky: float, kz: float, s: float, c: float) -> None:
    """Writes into ``R[:3, :3]`` the rotation about the unit axis k by the angle whose sine is
    ``s`` and cosine ``c``: R = c I + s [k]x + (1 - c) k k^T (Rodrigues)."""
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


@_jit
def log3(R: np.ndarray) -> np.ndarray:
    """Rotation vector of a rotation matrix (small and large angles): ``pin.log3``'s private
    copy."""
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
    T_motor: np.ndarray,
    J: np.ndarray,
    wrench: np.ndarray,
    compliance: np.ndarray,
    p_before: np.ndarray,
    dt: float,
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Arm-side TCP pose under ``wrench`` by the linear joint-stiffness model, the cell's copy
    of ``stiffness.model.loaded_equilibrium(..., mode="linear")``: dq = Kq^-1 J^T W, the TCP
    moved by the twist J dq (p + dp, exp(dtheta) R); and the TCP's velocity from ``p_before``
    ``dt`` earlier. Returns (T_arm, dq, velocity).
    """
    dq = np.empty(6)
    for j in range(6):
        s = 0.0
        for i in range(6):
            s += J[i, j] * wrench[i]
        dq[j] = compliance[j] * s
    dx = np.zeros(6)
    for i in range(6):
        for j in range(6):
            dx[i] += J[i, j] * dq[j]
    T = T_motor.copy()
    velocity = np.empty(3)
    for i in range(3):
        T[i, 3] += dx[i]
        velocity[i] = (T[i, 3] - p_before[i]) / dt
    T[:3, :3] = mul3(exp3(dx[3:]), T_motor)
    return T, dq, velocity


@_jit
def sensor_reading(
    R_flange: np.ndarray, wrench: np.ndarray, load: np.ndarray, noise: np.ndarray, row: int
) -> np.ndarray:
    """F/T reading in the sensor frame: contact wrench moved to the sensor + weight + bias + the
    ``row`` of ``noise`` (``sensor.contact_reading`` + ``sensor.gravity_reading``).

    f_s = R^T (F_c + m g);  tau_s = R^T tau_c + r_tcp x (R^T F_c) + r_com x (R^T m g).

    Args:
        load: (15,) weight m g (3), centre of mass (3), TCP (3) in the sensor frame, bias (6).
    """
    f_c = rotate(R_flange, wrench, 0, True)
    f_g = rotate(R_flange, load, 0, True)
    tau = rotate(R_flange, wrench, 3, True) + cross(load[6:9], f_c) + cross(load[3:6], f_g)
    out = np.empty(6)
    for i in range(3):
        out[i] = f_c[i] + f_g[i] + load[9 + i] + noise[row, i]
        out[3 + i] = tau[i] + load[12 + i] + noise[row, 3 + i]
    return out


@_jit
def contact_wrench_tcp_base(
    reading: np.ndarray,
    R_flange: np.ndarray,
    weight: np.ndarray,
    com: np.ndarray,
    tcp: np.ndarray,
    bias: np.ndarray,
) -> np.ndarray:
    """The controller's compensation: remove bias and the tool's weight, move to the TCP
    (``sensor.wrench_at_tcp_in_base`` of ``sensor.compensate_gravity``).

    w_s = reading - bias - [R^T m g; r_com x R^T m g]; tau_tcp = tau_s - r_tcp x f_s; to base.
    """
    f_g = rotate(R_flange, weight, 0, True)
    f_s = reading[:3] - bias[:3] - f_g
    tau_s = reading[3:] - bias[3:] - cross(com, f_g)
    tau_tcp = tau_s - cross(tcp, f_s)
    out = np.empty(6)
    out[:3] = rotate(R_flange, f_s)
    out[3:] = rotate(R_flange, tau_tcp)
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
    """One Newton step of the 6-D pose error (``transforms.pose_error``), clamped to the limits:
    dq = J^-1 e, or where that step is large (near a singularity) damped least squares,
    dq = J^T (J J^T + damping^2 I)^-1 e (``Robot.ik_step``)."""
    e = np.empty(6)
    e[0] = T_target[0, 3] - T[0, 3]
    e[1] = T_target[1, 3] - T[1, 3]
    e[2] = T_target[2, 3] - T[2, 3]
    e[3:] = log3(mul3(T_target, T, False, True))
    dq = solve(J, e)
    size = 0.0
    for i in range(6):
        size += dq[i] * dq[i]
    if not math.isfinite(size) or size > 1e-4:
        A = np.empty((6, 6))
        for i in range(6):
            for j in range(6):
                s = 0.0
                for k in range(6):
                    s += J[i, k] * J[j, k]
                A[i, j] = s
            A[i, i] += damping * damping
        x = solve(A, e)
        for j in range(6):
            s = 0.0
            for i in range(6):
                s += J[i, j] * x[i]
            dq[j] = s
    out = np.empty(6)
    for i in range(6):
        out[i] = min(max(q[i] + dq[i], lower[i]), upper[i])
    return out


@_jit
def _closest_on_triangle(
    px: float, py: float, pz: float, tri: np.ndarray
) -> tuple[float, float, float]:
    """Closest point of the triangle ``tri`` (3, 3) to p (Ericson, Real-Time Collision
    Detection, 5.1.5), in scalars: no array is allocated (it runs for every candidate face of
    every control period)."""
    ax, ay, az = tri[0, 0], tri[0, 1], tri[0, 2]
    bx, by, bz = tri[1, 0], tri[1, 1], tri[1, 2]
    cx, cy, cz = tri[2, 0], tri[2, 1], tri[2, 2]
    abx, aby, abz = bx - ax, by - ay, bz - az
    acx, acy, acz = cx - ax, cy - ay, cz - az
    apx, apy, apz = px - ax, py - ay, pz - az
    d1 = abx * apx + aby * apy + abz * apz
    d2 = acx * apx + acy * apy + acz * apz
    if d1 <= 0.0 and d2 <= 0.0:
        return ax, ay, az
    bpx, bpy, bpz = px - bx, py - by, pz - bz
    d3 = abx * bpx + aby * bpy + abz * bpz
    d4 = acx * bpx + acy * bpy + acz * bpz
    if d3 >= 0.0 and d4 <= d3:
        return bx, by, bz
    vc = d1 * d4 - d3 * d2
    if vc <= 0.0 and d1 >= 0.0 and d3 <= 0.0:
        t = d1 / (d1 - d3)
        return ax + abx * t, ay + aby * t, az + abz * t
    cpx, cpy, cpz = px - cx, py - cy, pz - cz
    d5 = abx * cpx + aby * cpy + abz * cpz
    d6 = acx * cpx + acy * cpy + acz * cpz
    if d6 >= 0.0 and d5 <= d6:
        return cx, cy, cz
    vb = d5 * d2 - d1 * d6
    if vb <= 0.0 and d2 >= 0.0 and d6 <= 0.0:
        t = d2 / (d2 - d6)
        return ax + acx * t, ay + acy * t, az + acz * t
    va = d3 * d6 - d5 * d4
    if va <= 0.0 and (d4 - d3) >= 0.0 and (d5 - d6) >= 0.0:
        t = (d4 - d3) / ((d4 - d3) + (d5 - d6))
        return bx + (cx - bx) * t, by + (cy - by) * t, bz + (cz - bz) * t
    denom = 1.0 / (va + vb + vc)
    v, w = vb * denom, vc * denom
    return ax + abx * v + acx * w, ay + aby * v + acy * w, az + abz * v + acz * w


@_jit
def ball_contact(
    center: np.ndarray,
    skin_center: np.ndarray,
    skin_m: float,
    candidates: np.ndarray,
    triangles: np.ndarray,
    normals: np.ndarray,
    p_tcp: np.ndarray,
    velocity: np.ndarray,
    previous_depth: float,
    dt: float,
    params: np.ndarray,
) -> tuple[int, float, float, np.ndarray]:
    """Penalty contact of a ball cutter (``contact`` module) against the faces it overlaps.

    The faces are those of ``candidates`` (indices into ``triangles`` (F, 3, 3) and their
    outward ``normals`` (F, 3)) within the ball's radius of ``center``: the candidates hold
    every face within radius + ``skin_m`` of ``skin_center`` (coal's query), so they serve
    while the centre stays within ``skin_m`` of it. The nearest of them gives the depth and
    the side: outside, depth = r - d along the direction from the surface to the centre;
    behind every nearest face (ties within 1e-12 m: an edge or a corner), depth = r + d along
    its normal. F_n = k depth + c d(depth)/dt (>= 0); friction F_t = -mu F_n tanh(|v_t| / v0)
    v_t / |v_t|; the wrench at the TCP, base-aligned axes.

    Args:
        params: radius, contact stiffness k [N/m], damping c [N s/m], friction mu, v0 [m/s].

    Returns:
        (status, distance [m], depth [m], (9,) normal (3) and wrench (6)); status -1: the
        centre left the skin (query coal again), 0: no contact, 1: contact.
    """
    out = np.zeros(9)
    px, py, pz = center[0], center[1], center[2]
    sx, sy, sz = px - skin_center[0], py - skin_center[1], pz - skin_center[2]
    if sx * sx + sy * sy + sz * sz > skin_m * skin_m:
        return -1, np.inf, 0.0, out
    radius = params[0]
    best = np.inf
    qx, qy, qz = 0.0, 0.0, 0.0
    nx, ny, nz = 0.0, 0.0, 0.0
    inside = False
    for k in range(candidates.shape[0]):
        f = candidates[k]
        cx, cy, cz = _closest_on_triangle(px, py, pz, triangles[f])
        dx, dy, dz = px - cx, py - cy, pz - cz
        dist = math.sqrt(dx * dx + dy * dy + dz * dz)
        if dist > radius:
            continue  # the ball does not overlap this face
        behind = (dx * normals[f, 0] + dy * normals[f, 1] + dz * normals[f, 2]) < 0.0
        if dist < best - 1e-12:
            best = dist
            qx, qy, qz = cx, cy, cz
            nx, ny, nz = normals[f, 0], normals[f, 1], normals[f, 2]
            inside = behind
        elif dist <= best + 1e-12:
            inside = inside and behind
            if not behind:
                nx, ny, nz = normals[f, 0], normals[f, 1], normals[f, 2]
    if inside:
        depth = radius + best
    else:
        depth = radius - best
        if depth <= 0.0:
            return 0, np.inf, 0.0, out
        if best > 1e-9:
            nx, ny, nz = (px - qx) / best, (py - qy) / best, (pz - qz) / best
    _penalty_wrench(out, depth, nx, ny, nz, qx, qy, qz, p_tcp, velocity, previous_depth, dt, params)
    return 1, -depth, depth, out


@_jit
def penalty_wrench(
    depth: float,
    normal: np.ndarray,
    point: np.ndarray,
    p_tcp: np.ndarray,
    velocity: np.ndarray,
    previous_depth: float,
    dt: float,
    params: np.ndarray,
) -> np.ndarray:
    """(9,) normal and wrench of a contact ``depth`` deep along the unit ``normal`` (from the
    part to the cutter) at ``point``: ``ball_contact``'s force law, for the other cutters."""
    out = np.zeros(9)
    _penalty_wrench(
        out, depth, normal[0], normal[1], normal[2], point[0], point[1], point[2],
        p_tcp, velocity, previous_depth, dt, params,
    )  # fmt: skip
    return out


@_jit
def _penalty_wrench(
    out: np.ndarray,
    depth: float,
    nx: float,
    ny: float,
    nz: float,
    qx: float,
    qy: float,
    qz: float,
    p_tcp: np.ndarray,
    velocity: np.ndarray,
    previous_depth: float,
    dt: float,
    params: np.ndarray,
) -> None:
    depth_rate = (depth - previous_depth) / dt
    f_n = max(0.0, params[1] * depth + params[2] * depth_rate)
    vx, vy, vz = velocity[0], velocity[1], velocity[2]
    vn = vx * nx + vy * ny + vz * nz
    tx, ty, tz = vx - vn * nx, vy - vn * ny, vz - vn * nz
    speed_t = math.sqrt(tx * tx + ty * ty + tz * tz)
    fx, fy, fz = f_n * nx, f_n * ny, f_n * nz
    if speed_t > 1e-12 and params[3] > 0.0:
        k = params[3] * f_n * math.tanh(speed_t / params[4]) / speed_t
        fx, fy, fz = fx - k * tx, fy - k * ty, fz - k * tz
    rx, ry, rz = qx - p_tcp[0], qy - p_tcp[1], qz - p_tcp[2]
    out[0], out[1], out[2] = nx, ny, nz
    out[3], out[4], out[5] = fx, fy, fz
    out[6], out[7], out[8] = ry * fz - rz * fy, rz * fx - rx * fz, rx * fy - ry * fx


@_jit
def boxes_overlapping(
    lo: np.ndarray, hi: np.ndarray, box_lo: np.ndarray, box_hi: np.ndarray
) -> np.ndarray:
    """Indices of the boxes [lo_i, hi_i] ((F, 3) each) that overlap [box_lo, box_hi] (the
    mesh's faces a grid cell of ``contact`` holds)."""
    out = np.empty(lo.shape[0], dtype=np.int64)
    n = 0
    for i in range(lo.shape[0]):
        if (
            hi[i, 0] >= box_lo[0]
            and hi[i, 1] >= box_lo[1]
            and hi[i, 2] >= box_lo[2]
            and lo[i, 0] <= box_hi[0]
            and lo[i, 1] <= box_hi[1]
            and lo[i, 2] <= box_hi[2]
        ):
            out[n] = i
            n += 1
    return out[:n].copy()


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
        # A contiguous copy: numba warns (on the user's terminal) of "@" on a slice, and copies.
        T[:3, :3] = exp3(ang * dt) @ T_ref[:3, :3].copy()
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
