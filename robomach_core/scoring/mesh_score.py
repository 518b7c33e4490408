"""Scoring a program against the workpiece mesh itself (any part: built-in or uploaded).

PROBLEM   ``scoring.score_path`` needs the true wall contour, which only the built-in parts have;
          on an uploaded part the mesh is the only truth. Measured as the unsigned distance to
          the nearest surface minus the cutter radius, a path learned on the wrong wall, rolling
          on the groove's floor or held inside the material scored 0.20 mm like a good one.
STRATEGY  The cutter is a ball of radius r centred on the TCP. The deviation of a program point
          p is signed and measured against the part's walls (faces across the tool axis, not the
          floor or the top):
              dev(p) = d_wall(p) - r   when p is outside the material (> 0: air, < 0: the
                                       cutter cuts into the wall),
              dev(p) = -(d(p) + r)     when p is inside it (an overcut, never a small number),
          inside from the nearest face's outward normal, or from the winding number where the
          nearest point is on an edge (``_inside``). Whether the program follows the wall the
          guide points were taught on is the learning model's check
          (``learning.checks.taught_wall_check``), not a score.
SOLUTION  ``mesh_deviation``, ``score_mesh`` (a ``scoring.PathScore`` with the overcut and the
          air). The project's post-processing stage calls them for every part.
"""

from __future__ import annotations

from collections.abc import Sequence

import igl
import numpy as np
import trimesh

from ..errors import InvalidInputError
from ..part import Workpiece, mesh_query
from ..postprocess import Move, linear_moves
from .true_wall import PathScore, score_sampled_moves

# 0.5 mm between scored points (~0.2 s for a metre of path on an 8k-triangle mesh; 0.1 mm cost
# 1 s, most of a workbench post-processing). Between targets the error is a smooth chord sagitta
# (mm-long chords), so the coarser sampling lowers the maximum by 2 um on the water pump.
MESH_SCORE_SPACING_M = 5e-4
MESH_QUERY_CHUNK = 2000  # points per trimesh query (its memory grows with the points asked)


def _inside(
    mesh: trimesh.Trimesh,
    pts: np.ndarray,
    closest: np.ndarray,
    distance: np.ndarray,
    tri: np.ndarray,
) -> np.ndarray:
    """(k,) True for points inside the part. Where the nearest point lies inside a face, that
    face's outward normal tells; where it lies on an edge or a corner (the direction to it off
    the face's normal), the generalised winding number does (libigl's, exact: the solid
    angles of every face over 4 pi): ray tests (``trimesh.contains``) gave different answers
    for the same points in two frames."""
    rel = pts - closest
    along = np.einsum("ij,ij->i", rel, mesh.face_normals[tri])
    inside = along < 0.0
    unsure = np.abs(along) < 0.999 * distance
    if unsure.any():
        vertices = np.asarray(mesh.vertices, dtype=np.float64)
        faces = np.asarray(mesh.faces, dtype=np.int64)
        inside[unsure] = igl.winding_number(vertices, faces, pts[unsure]) > 0.5
    return inside


def mesh_deviation(
    workpiece: Workpiece,
    tool_radius_m: float,
    points_base: np.ndarray,
    *,
    axis_base: np.ndarray | None = None,
) -> np.ndarray:
    """Signed deviation [m] of base-frame TCP points from the part's walls (module docstring):
    > 0 air, < 0 into the material. ``axis_base``: the tool axis (default the work object's z).
    Shape (k,)."""
    pts = np.asarray(points_base, dtype=float).reshape(-1, 3)
    T = workpiece.T_base_wobj
    R, t = T[:3, :3], T[:3, 3]
    # Distances do not change under the rigid work-object transform: query the part's own mesh
    # in its frame, whose triangle tree trimesh builds once and caches. trimesh's query holds
    # every candidate triangle of every point at once: in chunks, its memory stays bounded
    # whatever the tolerance (30k targets at 0.01 mm took 1.1 GB at once; issue 19, R3).
    pts_w = (pts - t) @ R
    axis_w = np.array([0.0, 0.0, 1.0]) if axis_base is None else R.T @ np.asarray(axis_base)
    mesh = workpiece.mesh
    walls = mesh_query.wall_faces(mesh, axis_w)
    out = np.empty(len(pts_w))
    for start in range(0, len(pts_w), MESH_QUERY_CHUNK):
        chunk = pts_w[start : start + MESH_QUERY_CHUNK]
        with np.errstate(divide="ignore", invalid="ignore"):  # degenerate facets in trimesh
            closest, distance, tri = mesh_query.closest_point(mesh, chunk)
            distance = np.asarray(distance, dtype=float)
            behind = _inside(mesh, chunk, closest, distance, tri)
            if walls is None:
                wall_distance = distance
            else:
                _, wall_distance, _ = mesh_query.closest_point(walls, chunk)
        out[start : start + len(chunk)] = np.where(
            behind,
            -(distance + tool_radius_m),
            np.asarray(wall_distance, dtype=float) - tool_radius_m,
        )
    return out


def score_mesh(
    workpiece: Workpiece,
    tool_radius_m: float,
    positions_m: np.ndarray,
    moves: Sequence[Move] | None = None,
    *,
    spacing_m: float = MESH_SCORE_SPACING_M,
    axis_base: np.ndarray | None = None,
) -> PathScore:
    """Signed deviation of the program (targets and the moves between them) from the part's
    walls: max and RMS of its size, the overcut and the air.

    Args:
        workpiece: The part; its mesh in the base frame is the truth.
        tool_radius_m: Ball cutter radius.
        positions_m: (m, 3) target positions, base frame.
        moves: The move sequence (``arcs.Move``); default a straight move to every target.
        spacing_m: Distance between scored points along the moves.
        axis_base: The tool axis, which tells walls from floors (default the work object's z).
    """
    pts = np.asarray(positions_m, dtype=float)
    if len(pts) < 2:
        raise InvalidInputError("scoring needs at least 2 targets")
    moves = linear_moves(len(pts)) if moves is None else tuple(moves)
    return score_sampled_moves(
        lambda points: mesh_deviation(workpiece, tool_radius_m, points, axis_base=axis_base),
        pts,
        moves,
        spacing_m=spacing_m,
    )
