"""Homogeneous transforms and scalar-first quaternions (wxyz); SO(3) from pinocchio.

Conventions (shared/DESIGN.md): ``T_a_b`` maps coordinates in frame b to frame a; quaternions
are ``[w, x, y, z]`` with ``w >= 0`` after normalisation so that output is deterministic.
Rotations to and from rotation vectors are pinocchio's ``exp3`` and ``log3`` (the compiled
loops' copies, ``_kernels.exp3`` and ``_kernels.log3``, are tested equal to them).
"""

from __future__ import annotations

import numpy as np
import pinocchio as pin

from .errors import InvalidInputError

_AXES = {"x": (1.0, 0.0, 0.0), "y": (0.0, 1.0, 0.0), "z": (0.0, 0.0, 1.0)}


def make_transform(rotation: np.ndarray, translation: np.ndarray) -> np.ndarray:
    """Build a 4x4 transform from a 3x3 rotation and a (3,) translation."""
    T = np.eye(4)
    T[:3, :3] = rotation
    T[:3, 3] = translation
    return T


def inverse_transform(T: np.ndarray) -> np.ndarray:
    """Inverse of a rigid 4x4 transform."""
    R = T[:3, :3]
    return make_transform(R.T, -R.T @ T[:3, 3])


def rotation_about(axis: str | np.ndarray, angle_rad: float) -> np.ndarray:
    """3x3 rotation by ``angle_rad`` about ``"x"``, ``"y"``, ``"z"`` or a (3,) axis."""
    a = np.asarray(_AXES[axis] if isinstance(axis, str) else axis, dtype=float)
    return pin.exp3(a / np.linalg.norm(a) * float(angle_rad))


def canonical_quaternion(q: np.ndarray) -> np.ndarray:
    """The sign of ``q`` with the first non-zero component (w first) positive."""
    for c in q:
        if abs(c) > 1e-12:
            return q if c > 0 else -q
    return q


def quaternion_from_matrix(R: np.ndarray) -> np.ndarray:
    """Unit quaternion ``[w, x, y, z]`` of a 3x3 rotation (Shepperd's method), canonical sign."""
    m = np.asarray(R, dtype=float)
    tr = m[0, 0] + m[1, 1] + m[2, 2]
    if tr > 0:
        s = 2.0 * np.sqrt(tr + 1.0)
        q = np.array(
            [0.25 * s, (m[2, 1] - m[1, 2]) / s, (m[0, 2] - m[2, 0]) / s, (m[1, 0] - m[0, 1]) / s]
        )
    elif m[0, 0] > m[1, 1] and m[0, 0] > m[2, 2]:
        s = 2.0 * np.sqrt(1.0 + m[0, 0] - m[1, 1] - m[2, 2])
        q = np.array(
            [(m[2, 1] - m[1, 2]) / s, 0.25 * s, (m[0, 1] + m[1, 0]) / s, (m[0, 2] + m[2, 0]) / s]
        )
    elif m[1, 1] > m[2, 2]:
        s = 2.0 * np.sqrt(1.0 + m[1, 1] - m[0, 0] - m[2, 2])
        q = np.array(
            [(m[0, 2] - m[2, 0]) / s, (m[0, 1] + m[1, 0]) / s, 0.25 * s, (m[1, 2] + m[2, 1]) / s]
        )
    else:
        s = 2.0 * np.sqrt(1.0 + m[2, 2] - m[0, 0] - m[1, 1])
        q = np.array(
            [(m[1, 0] - m[0, 1]) / s, (m[0, 2] + m[2, 0]) / s, (m[1, 2] + m[2, 1]) / s, 0.25 * s]
        )
    q /= np.linalg.norm(q)
    return canonical_quaternion(q)


def matrix_from_quaternion(q_wxyz: np.ndarray) -> np.ndarray:
    """3x3 rotation matrix of a quaternion ``[w, x, y, z]`` (normalised here)."""
    q = np.asarray(q_wxyz, dtype=float)
    n = np.linalg.norm(q)
    if not np.isfinite(n) or n < 1e-9:
        raise InvalidInputError(f"quaternion {q.tolist()} has no direction")
    return matrices_from_quaternions((q / n)[None])[0]


def matrices_from_quaternions(qs_wxyz: np.ndarray) -> np.ndarray:
    """Vectorised ``matrix_from_quaternion`` for (n, 4) quaternions -> (n, 3, 3)."""
    q = np.asarray(qs_wxyz, dtype=float)
    q = q / np.linalg.norm(q, axis=1, keepdims=True)
    w, x, y, z = q.T
    R = np.empty((len(q), 3, 3))
    R[:, 0, 0] = 1 - 2 * (y * y + z * z)
    R[:, 0, 1] = 2 * (x * y - w * z)
    R[:, 0, 2] = 2 * (x * z + w * y)
    R[:, 1, 0] = 2 * (x * y + w * z)
    R[:, 1, 1] = 1 - 2 * (x * x + z * z)
    R[:, 1, 2] = 2 * (y * z - w * x)
    R[:, 2, 0] = 2 * (x * z - w * y)
    R[:, 2, 1] = 2 * (y * z + w * x)
    R[:, 2, 2] = 1 - 2 * (x * x + y * y)
    return R


def rotation_log(R: np.ndarray) -> np.ndarray:
    """Rotation vector (axis * angle, rad) of a 3x3 rotation matrix."""
    return pin.log3(np.asarray(R, dtype=float))


def slerp(q0_wxyz: np.ndarray, q1_wxyz: np.ndarray, fraction: float) -> np.ndarray:
    """Spherical linear interpolation between two unit quaternions, ``fraction`` in [0, 1]."""
    q0 = np.asarray(q0_wxyz, dtype=float)
    q1 = np.asarray(q1_wxyz, dtype=float)
    dot = float(q0 @ q1)
    if dot < 0:
        q1, dot = -q1, -dot
    if dot > 0.9995:
        q = q0 + fraction * (q1 - q0)
    else:
        theta = np.arccos(dot)
        q = (np.sin((1 - fraction) * theta) * q0 + np.sin(fraction * theta) * q1) / np.sin(theta)
    q /= np.linalg.norm(q)
    return canonical_quaternion(q)


def pose_error(T_current: np.ndarray, T_target: np.ndarray) -> np.ndarray:
    """6-vector error [dp (m), dtheta (rad)] from current to target, both in the base frame."""
    dp = T_target[:3, 3] - T_current[:3, 3]
    dtheta = rotation_log(T_target[:3, :3] @ T_current[:3, :3].T)
    return np.concatenate([dp, dtheta])


def quaternions_from_matrices(Rs: np.ndarray) -> np.ndarray:
    """Vectorised ``quaternion_from_matrix`` for a stack of rotations (n, 3, 3) -> (n, 4)."""
    Rs = np.asarray(Rs, dtype=float)
    m00, m11, m22 = Rs[:, 0, 0], Rs[:, 1, 1], Rs[:, 2, 2]
    # |q| components from the diagonal, signs from the off-diagonal terms (w >= 0).
    w = 0.5 * np.sqrt(np.maximum(0.0, 1.0 + m00 + m11 + m22))
    x = 0.5 * np.sqrt(np.maximum(0.0, 1.0 + m00 - m11 - m22))
    y = 0.5 * np.sqrt(np.maximum(0.0, 1.0 - m00 + m11 - m22))
    z = 0.5 * np.sqrt(np.maximum(0.0, 1.0 - m00 - m11 + m22))
    q = np.stack([w, x, y, z], axis=1)
    # Fix the signs relative to the largest component, which is well conditioned.
    big = np.argmax(q, axis=1)
    s_x = Rs[:, 2, 1] - Rs[:, 1, 2]
    s_y = Rs[:, 0, 2] - Rs[:, 2, 0]
    s_z = Rs[:, 1, 0] - Rs[:, 0, 1]
    p_xy = Rs[:, 0, 1] + Rs[:, 1, 0]
    p_xz = Rs[:, 0, 2] + Rs[:, 2, 0]
    p_yz = Rs[:, 1, 2] + Rs[:, 2, 1]
    signs = np.ones_like(q)
    # Relative signs: (w,x)~s_x, (w,y)~s_y, (w,z)~s_z, (x,y)~p_xy, (x,z)~p_xz, (y,z)~p_yz.
    rel = {
        0: (np.ones_like(w), np.sign(s_x), np.sign(s_y), np.sign(s_z)),
        1: (np.sign(s_x), np.ones_like(w), np.sign(p_xy), np.sign(p_xz)),
        2: (np.sign(s_y), np.sign(p_xy), np.ones_like(w), np.sign(p_yz)),
        3: (np.sign(s_z), np.sign(p_xz), np.sign(p_yz), np.ones_like(w)),
    }
    for k, comps in rel.items():
        sel = big == k
        for j in range(4):
            signs[sel, j] = comps[j][sel]
    signs[signs == 0] = 1.0
    q = q * signs
    q = q / np.linalg.norm(q, axis=1, keepdims=True)
    # Canonical sign: the first component that is not ~0 is positive.
    first = np.argmax(np.abs(q) > 1e-12, axis=1)
    q *= np.where(q[np.arange(len(q)), first] < 0, -1.0, 1.0)[:, None]
    return q
