"""The learned path as the machining run sees it: arc length, wall normals, and a test program.

The program's TCP path is the chain of straight moves (MoveL) through the targets. Along it the
wall normal ``n`` points from the wall's material towards the tool (into free space): the depth
of cut, the deflection and the wall error are all measured along ``n``. Built-in walls are
travelled with their material on the right, so by default ``n = up x t`` (left of travel).
"""

from __future__ import annotations

from typing import Literal

import numpy as np

from ..cell import Robot
from ..part import Workpiece
from ..postprocess import Targets, curvature_along, speeds_by_curvature
from ..transforms import arc_length_m, make_transform, quaternions_from_matrices
from .errors import StockError

WallSide = Literal["left", "right"]
# Speeds of ``targets_along_wall`` follow postprocess defaults: ~10 mm/s, slower at corners.
WALL_PROGRAM_SPEED_MEAN_M_S = 0.010
WALL_PROGRAM_SPEED_MIN_M_S = 0.003
WALL_PROGRAM_CURVATURE_REF_1_M = 1.0 / 0.010


def check_path(path_points_m: np.ndarray) -> np.ndarray:
    """(n, 3) finite float array of at least two distinct points, or ``StockError``."""
    p = np.asarray(path_points_m, dtype=float)
    if p.ndim != 2 or p.shape[1] != 3 or len(p) < 2:
        raise StockError(f"the path must be (n, 3) points with n >= 2, got shape {p.shape}")
    if not np.all(np.isfinite(p)):
        raise StockError("the path has non-finite points")
    if arc_length_m(p)[-1] <= 0.0:
        raise StockError("the path has zero length")
    return p


def path_tangents(path_points_m: np.ndarray) -> np.ndarray:
    """(n, 3) unit tangents by central differences (one-sided at the ends)."""
    p = np.asarray(path_points_m, dtype=float)
    t = np.gradient(p, axis=0)
    norm = np.linalg.norm(t, axis=1, keepdims=True)
    return t / np.where(norm > 0.0, norm, 1.0)


def wall_normals_from_path(
    path_points_m: np.ndarray,
    *,
    wall_side: WallSide = "right",
    up: tuple[float, float, float] = (0.0, 0.0, 1.0),
) -> np.ndarray:
    """(n, 3) unit wall normals, perpendicular to the path and to ``up``, pointing at the tool.

    ``wall_side`` is where the wall's material lies, seen along the direction of travel.
    """
    p = check_path(path_points_m)
    u = np.asarray(up, dtype=float)
    n = np.cross(u, path_tangents(p))
    if wall_side == "left":
        n = -n
    elif wall_side != "right":
        raise StockError(f"wall side must be 'left' or 'right', got {wall_side!r}")
    norm = np.linalg.norm(n, axis=1, keepdims=True)
    if np.any(norm < 1e-9):
        raise StockError("the path runs along the 'up' axis somewhere; give the wall normals")
    return n / norm


def wall_normals_for_workpiece(workpiece: Workpiece, path_points_m: np.ndarray) -> np.ndarray:
    """(n, 3) wall normals of a path along a built-in workpiece's known wall.

    The side is read from the geometry, not assumed: the normal is the one along which the
    path points move away from the true wall (the tool is on the free side).
    """
    wall = workpiece.wall
    if wall is None:
        raise StockError(f"workpiece {workpiece.name!r} has no known wall; give the normals")
    p = check_path(path_points_m)
    T = workpiece.T_base_wobj
    up = tuple(T[:3, 2])
    n = wall_normals_from_path(p, wall_side="right", up=up)

    def distance(points: np.ndarray) -> np.ndarray:
        return wall.distance(((points - T[:3, 3]) @ T[:3, :3])[:, :2])

    step = 0.2e-3
    away = distance(p + step * n) > distance(p)
    return n if np.mean(away) >= 0.5 else -n


def check_normals(wall_normals_m: np.ndarray, count: int) -> np.ndarray:
    """(count, 3) unit normals, or ``StockError``."""
    n = np.asarray(wall_normals_m, dtype=float)
    if n.shape != (count, 3) or not np.all(np.isfinite(n)):
        raise StockError(f"wall normals must be ({count}, 3) finite vectors, got shape {n.shape}")
    norm = np.linalg.norm(n, axis=1, keepdims=True)
    if np.any(norm < 1e-9):
        raise StockError("a wall normal has zero length")
    return n / norm


def targets_along_wall(
    robot: Robot,
    workpiece: Workpiece,
    *,
    tool_radius_m: float,
    spacing_m: float = 0.002,
    height_m: float | None = None,
) -> Targets:
    """A program that follows a built-in workpiece's true wall, tool pointing down.

    The TCP runs on the wall contour offset by the tool radius (the cutter touches the wall), at
    mid-height of the wall unless ``height_m`` (wobj z) is given; speeds slow at corners as the
    post-processor's do. Joints by IK, each seeded with the previous target's.
    Stands in for a learned program in unit tests and benchmarks.
    """
    if workpiece.wall is None:
        raise StockError(f"workpiece {workpiece.name!r} has no known wall to follow")
    xy = workpiece.wall.offset(tool_radius_m).sample(spacing_m)
    z = 0.5 * sum(workpiece.wall_z_m) if height_m is None else height_m
    T = workpiece.T_base_wobj
    p = np.column_stack([xy, np.full(len(xy), z)]) @ T[:3, :3].T + T[:3, 3]
    p = np.vstack([p, p[:1]])  # a closed loop ends where it starts
    R = T[:3, :3] @ np.diag([1.0, -1.0, -1.0])
    q = robot.ik(make_transform(R, p[0]))
    joints = []
    for point in p:
        q = robot.ik(make_transform(R, point), q)
        joints.append(q)
    curvature = curvature_along(p)
    speeds = speeds_by_curvature(
        curvature,
        speed_mean_m_s=WALL_PROGRAM_SPEED_MEAN_M_S,
        speed_min_m_s=WALL_PROGRAM_SPEED_MIN_M_S,
        curvature_ref_1_m=WALL_PROGRAM_CURVATURE_REF_1_M,
    )
    quats = quaternions_from_matrices(np.repeat(R[None], len(p), axis=0))
    return Targets(
        position_m=p,
        quaternion_wxyz=quats,
        joints_rad=np.array(joints),
        speed_m_s=speeds,
        curvature_1_m=curvature,
        sample_index=np.arange(len(p)),
    )


def _project_onto_every_segment(
    p: np.ndarray, ref: np.ndarray, normals_m: np.ndarray, *, window_m: float
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """``project_onto_path`` measured against every segment of the reference ((k, n-1)
    arrays): its reference (tests compare the two) and its answer where no segment lies in a
    point's window."""
    s_ref = arc_length_m(ref)
    length = float(s_ref[-1])
    s_own = arc_length_m(p)
    expected = s_own * (length / s_own[-1]) if s_own[-1] > 0.0 else np.zeros(len(p))
    a, b = ref[:-1], ref[1:]
    d = b - a
    seg_len2 = np.maximum(np.einsum("ij,ij->i", d, d), 1e-30)
    t = np.einsum("kij,ij->ki", p[:, None, :] - a[None], d) / seg_len2
    t = np.clip(t, 0.0, 1.0)
    foot = a[None] + t[..., None] * d[None]
    dist = np.linalg.norm(p[:, None, :] - foot, axis=2)
    s_foot = s_ref[:-1][None] + t * np.sqrt(seg_len2)[None]
    far = np.abs(s_foot - expected[:, None]) > window_m + np.sqrt(seg_len2)[None]
    dist = np.where(far, np.inf, dist)
    best = np.argmin(dist, axis=1)
    rows = np.arange(len(p))
    return _offsets_at(p, s_foot[rows, best], foot[rows, best], s_ref, normals_m)


def project_onto_path(
    points_m: np.ndarray,
    path_points_m: np.ndarray,
    normals_m: np.ndarray,
    *,
    window_m: float = 0.005,
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Where a program's points lie relative to a reference path (the stock's).

    Each point is projected onto the nearest segment of the reference polyline among those
    within ``window_m`` of its expected arc length (its own arc length scaled to the reference
    length), so a closed loop's last point lands at the end, not the start.

    Returns:
        (s_m (k,) arc length along the reference, non-decreasing; offset_m (k,) distance along
        the reference's normal (interpolated at s); lateral_m (k,) the rest of the distance).
    """
    p = np.asarray(points_m, dtype=float)
    ref = np.asarray(path_points_m, dtype=float)
    s_ref = arc_length_m(ref)
    length = float(s_ref[-1])
    s_own = arc_length_m(p)
    expected = s_own * (length / s_own[-1]) if s_own[-1] > 0.0 else np.zeros(len(p))
    a, d = ref[:-1], ref[1:] - ref[:-1]
    seg_len2 = np.maximum(np.einsum("ij,ij->i", d, d), 1e-30)
    seg_len = np.sqrt(seg_len2)
    # Only the segments near each point's expected arc length can be within the window (a
    # foot lies on its segment): (k, w) candidates instead of every segment, the same numbers.
    reach = window_m + 2.0 * float(seg_len.max()) + 1e-9
    first = np.searchsorted(s_ref[1:], expected - reach, side="left")
    count = np.searchsorted(s_ref[:-1], expected + reach, side="right") - first
    seg = first[:, None] + np.arange(max(int(count.max(initial=0)), 1))[None]
    outside = seg >= (first + count)[:, None]
    seg = np.minimum(seg, len(a) - 1)
    # (k, w): parameter of the foot on each candidate segment, clipped to the segment.
    t = np.einsum("kwj,kwj->kw", p[:, None, :] - a[seg], d[seg]) / seg_len2[seg]
    t = np.clip(t, 0.0, 1.0)
    foot = a[seg] + t[..., None] * d[seg]
    dist = np.linalg.norm(p[:, None, :] - foot, axis=2)
    s_foot = s_ref[:-1][seg] + t * seg_len[seg]
    far = outside | (np.abs(s_foot - expected[:, None]) > window_m + seg_len[seg])
    if far.all(axis=1).any():  # a point no segment's window holds: every segment, as before
        return _project_onto_every_segment(p, ref, normals_m, window_m=window_m)
    dist = np.where(far, np.inf, dist)
    best = np.argmin(dist, axis=1)
    rows = np.arange(len(p))
    return _offsets_at(p, s_foot[rows, best], foot[rows, best], s_ref, normals_m)


def _offsets_at(
    p: np.ndarray, s_foot: np.ndarray, foot: np.ndarray, s_ref: np.ndarray, normals_m: np.ndarray
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(s, offset, lateral) of ``project_onto_path`` from each point's nearest foot."""
    s = np.maximum.accumulate(s_foot)
    n = np.stack([np.interp(s, s_ref, normals_m[:, i]) for i in range(3)], axis=1)
    n /= np.linalg.norm(n, axis=1, keepdims=True)
    delta = p - foot
    offset = np.einsum("ij,ij->i", delta, n)
    lateral = np.sqrt(np.maximum(np.einsum("ij,ij->i", delta, delta) - offset**2, 0.0))
    return s, offset, lateral
