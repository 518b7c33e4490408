"""Homogeneous transforms and scalar-first quaternions (wxyz); SO(3) from SciPy and pinocchio.

Conventions (shared/DESIGN.md): ``T_a_b`` maps coordinates in frame b to frame a; quaternions
are ``[w, x, y, z]`` with ``w >= 0`` after normalisation so that output is deterministic.
Quaternions and their interpolation are ``scipy.spatial.transform.Rotation``'s; rotations to
and from rotation vectors are pinocchio's ``exp3`` and ``log3`` (the compiled loops' copies,
``_kernels.exp3`` and ``_kernels.log3``, are tested equal to them).
"""

from __future__ import annotations

import numpy as np
import pinocchio as pin
from scipy.spatial.transform import Rotation

from .errors import InvalidInputError

_AXES = {"x": (1.0, 0.0, 0.0), "y": (0.0, 1.0, 0.0), "z": (0.0, 0.0, 1.0)}


def arc_length_m(points_m: np.ndarray) -> np.ndarray:
    """(n,) cumulative length [m] along the polyline through ``points_m`` ((n, d)), from 0."""
    p = np.asarray(points_m, dtype=float)
    return np.concatenate([[0.0], np.cumsum(np.linalg.norm(np.diff(p, axis=0), axis=1))])


def unit_vector(v: np.ndarray | list[float], what: str = "a direction") -> np.ndarray:
    """(3,) ``v`` of any finite, non-zero length made unit. Outside 1e-150..1e150 it is scaled
    by its largest component first, so 1e285 does not overflow the norm (its unit came out
    zero) nor 1e-200 underflow it; inside, ``v / |v|`` as before, to the bit.

    Raises:
        InvalidInputError: not 3 finite numbers, or all zero (``what`` names it).
    """
    a = np.asarray(v, dtype=float)
    if a.shape != (3,) or not np.all(np.isfinite(a)):
        raise InvalidInputError(f"{what} must be 3 finite numbers")
    norm = float(np.linalg.norm(a))
    if 1e-150 < norm < 1e150:  # no overflow nor underflow in the squares
        return a / norm
    largest = float(np.max(np.abs(a)))
    if largest == 0.0:
        raise InvalidInputError(f"{what} must not be zero")
    a = a / largest
    return a / float(np.linalg.norm(a))


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
    """``q`` (4,) or (n, 4) with the sign that makes its first component larger than 1e-12 in
    size (w first) positive. SciPy's ``canonical=True`` keys on w's exact sign: a half turn's
    w of +-1e-17 from floating-point noise would flip the printed quaternion."""
    q = np.asarray(q, dtype=float)
    rows = np.atleast_2d(q)
    first = np.argmax(np.abs(rows) > 1e-12, axis=1)
    rows = rows * np.where(rows[np.arange(len(rows)), first] < 0.0, -1.0, 1.0)[:, None]
    return rows.reshape(q.shape)


def quaternion_from_matrix(R: np.ndarray) -> np.ndarray:
    """Unit quaternion ``[w, x, y, z]`` of a 3x3 rotation, canonical sign."""
    return quaternions_from_matrices(np.asarray(R, dtype=float)[None])[0]


def quaternions_from_matrices(Rs: np.ndarray) -> np.ndarray:
    """Unit quaternions (n, 4) ``[w, x, y, z]`` of (n, 3, 3) rotations, canonical sign."""
    Rs = np.asarray(Rs, dtype=float).reshape(-1, 3, 3)
    return canonical_quaternion(Rotation.from_matrix(Rs).as_quat(scalar_first=True))


def matrix_from_quaternion(q_wxyz: np.ndarray) -> np.ndarray:
    """3x3 rotation matrix of a quaternion ``[w, x, y, z]`` (normalised here)."""
    q = np.asarray(q_wxyz, dtype=float)
    n = np.linalg.norm(q)
    if not np.isfinite(n) or n < 1e-9:
        raise InvalidInputError(f"quaternion {q.tolist()} has no direction")
    return matrices_from_quaternions(q[None])[0]


def matrices_from_quaternions(qs_wxyz: np.ndarray) -> np.ndarray:
    """(n, 3, 3) rotation matrices of (n, 4) quaternions ``[w, x, y, z]`` (normalised here)."""
    q = np.asarray(qs_wxyz, dtype=float).reshape(-1, 4)
    return Rotation.from_quat(q, scalar_first=True).as_matrix()


def rotation_log(R: np.ndarray) -> np.ndarray:
    """Rotation vector (axis * angle, rad) of a 3x3 rotation matrix."""
    return pin.log3(np.asarray(R, dtype=float))


def slerp(q0_wxyz: np.ndarray, q1_wxyz: np.ndarray, fraction: float | np.ndarray) -> np.ndarray:
    """Spherical linear interpolation from ``q0`` to ``q1`` (4,) or (n, 4) at ``fraction`` in
    [0, 1] (scalar or (n,)), the shorter way round: q0 exp(f log(q0^-1 q1)), as SciPy's
    ``Slerp`` between two keys. Canonical sign."""
    q0 = np.asarray(q0_wxyz, dtype=float)
    r0 = Rotation.from_quat(np.atleast_2d(q0), scalar_first=True)
    r1 = Rotation.from_quat(np.atleast_2d(q1_wxyz), scalar_first=True)
    step = (r0.inv() * r1).as_rotvec() * np.reshape(fraction, (-1, 1))
    q = canonical_quaternion((r0 * Rotation.from_rotvec(step)).as_quat(scalar_first=True))
    return q[0] if q0.ndim == 1 and np.ndim(fraction) == 0 else q


def pose_error(T_current: np.ndarray, T_target: np.ndarray) -> np.ndarray:
    """6-vector error [dp (m), dtheta (rad)] from current to target, both in the base frame."""
    dp = T_target[:3, 3] - T_current[:3, 3]
    dtheta = rotation_log(T_target[:3, :3] @ T_current[:3, :3].T)
    return np.concatenate([dp, dtheta])
