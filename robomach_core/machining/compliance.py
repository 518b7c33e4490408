"""The arm's compliance along the path as the cut sees it: n^T C u at any arc length.

PROBLEM   The cut needs, at every station of the path, how far the tool moves along the wall
          normal n per newton of process force along u = (n - rho t) / |n - rho t| (chapter
          eq. 19: C = J Kq^-1 J^T, its translational block). Evaluated at the program's targets
          and interpolated, it depended on where the targets sit: a corrected program (a target
          every millimetre or so) and its nominal program (one every few millimetres) saw
          different tangents at the targets (central differences across a corner), so the same
          correction cut the wall differently depending on how it was written down.
STRATEGY  Split what depends on the arm's pose from what depends on the path: the 3x3 block
          C_vv = J_v Kq^-1 J_v^T at each target (smooth in the joints, interpolated linearly
          between targets, as the joints are along a MoveL), and n, t from the stock's path at
          the station (t the direction of the path's segment there: a MoveL runs straight).
SOLUTION  ``compliance_blocks``, ``path_directions`` and ``normal_compliance_along``; the
          blocks of a program are kept (``compliance_blocks`` is cached), so the stocks of a
          sweep and the rehearsals of a compensation share them.
"""

from __future__ import annotations

import hashlib

import numpy as np

from ..cell import JointCompliance, Robot
from ..transforms import arc_length_m

# Blocks of the programs cut lately in this process, by arm, tool, joints and stiffness.
_BLOCKS: dict[tuple, np.ndarray] = {}
_BLOCKS_KEPT = 64


def compliance_blocks(robot: Robot, joints_rad: np.ndarray, model: JointCompliance) -> np.ndarray:
    """(m, 3, 3) C_vv = J_v Kq^-1 J_v^T at each joint vector (chapter eq. 19); read-only."""
    q = np.ascontiguousarray(joints_rad, dtype=float)
    key = (
        robot.name,
        np.ascontiguousarray(robot.T_flange_tcp, dtype=float).tobytes(),
        hashlib.blake2b(q.tobytes(), digest_size=16).digest(),
        tuple(float(k) for k in model.stiffness_Nm_rad),
    )
    out = _BLOCKS.get(key)
    if out is None:
        c = model.compliance_rad_Nm
        out = np.empty((len(q), 3, 3))
        for i, qi in enumerate(q):
            _, J = robot.fk_and_jacobian(qi)
            Jv = J[:3]
            out[i] = (Jv * c) @ Jv.T
        out.setflags(write=False)
        if len(_BLOCKS) >= _BLOCKS_KEPT:
            _BLOCKS.pop(next(iter(_BLOCKS)))
        _BLOCKS[key] = out
    return out


def segment_tangents(path_points_m: np.ndarray, s_m: np.ndarray) -> np.ndarray:
    """(k, 3) unit direction of the path's segment at arc lengths ``s_m`` (a vertex takes the
    segment that leaves it)."""
    p = np.asarray(path_points_m, dtype=float)
    d = np.diff(p, axis=0)
    length = np.linalg.norm(d, axis=1)
    s_path = np.concatenate([[0.0], np.cumsum(length)])
    seg = np.clip(np.searchsorted(s_path, s_m, side="right") - 1, 0, len(d) - 1)
    # A zero-length segment takes its neighbour's direction.
    good = length > 0.0
    index = np.where(good, np.arange(len(d)), -1)
    index = np.maximum.accumulate(index)
    index = np.where(index < 0, np.argmax(good), index)
    seg = index[seg]
    return d[seg] / length[seg, None]


def path_directions(
    path_points_m: np.ndarray,
    path_normals_m: np.ndarray,
    s_m: np.ndarray,
    feed_force_ratio: float,
) -> tuple[np.ndarray, np.ndarray]:
    """(n (k, 3), u (k, 3)) at arc lengths ``s_m`` of the path: the wall normal interpolated
    between the path points and the process force's direction u = (n - rho t) / |n - rho t|."""
    s_path = arc_length_m(path_points_m)
    n = np.stack([np.interp(s_m, s_path, path_normals_m[:, i]) for i in range(3)], axis=1)
    n /= np.linalg.norm(n, axis=1, keepdims=True)
    u = n - feed_force_ratio * segment_tangents(path_points_m, s_m)
    u /= np.linalg.norm(u, axis=1, keepdims=True)
    return n, u


def normal_compliance_along(
    s_targets_m: np.ndarray,
    blocks: np.ndarray,
    s_m: np.ndarray,
    normals_m: np.ndarray,
    directions_m: np.ndarray,
) -> np.ndarray:
    """(k,) n^T C_vv u [m/N] at arc lengths ``s_m``: the blocks (at the targets' arc lengths
    ``s_targets_m``) interpolated linearly, n and u given there."""
    out = np.zeros(len(s_m))
    for a in range(3):
        for b in range(3):
            c_ab = np.interp(s_m, s_targets_m, blocks[:, a, b])
            out += normals_m[:, a] * c_ab * directions_m[:, b]
    return out
