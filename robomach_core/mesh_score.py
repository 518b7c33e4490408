"""Scoring a program against the workpiece mesh itself (any part: built-in or uploaded).

PROBLEM   ``scoring.score_path`` needs the true wall contour, which only the built-in parts have;
          an uploaded STL/OBJ/PLY got no quality figure at all, yet its mesh is the truth the
          user cares about.
STRATEGY  The cutter is a ball of radius r centred on the TCP; where it touches the wall without
          cutting into it, the TCP is exactly r from the surface. So the deviation of a program
          point p is | d(p, mesh) - r |, with d the unsigned distance to the nearest triangle
          (``trimesh.proximity``). The program is sampled along its moves (lines, and arcs
          through their via point) every ``MESH_SCORE_SPACING_M``, and at its targets.
SOLUTION  ``mesh_deviation(workpiece, tool_radius_m, points)`` and ``score_mesh(workpiece,
          tool_radius_m, positions, moves)`` returning a ``scoring.PathScore``. The one scoring
          path for meshes: the project's post-processing stage calls it for every part.
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np
import trimesh

from .arcs import Move, linear_moves, score_sampled_moves
from .errors import InvalidInputError
from .scoring import PathScore
from .workpiece import Workpiece

# 0.5 mm between scored points (~0.2 s for a metre of path on an 8k-triangle mesh; 0.1 mm cost
# 1 s, most of a workbench post-processing). Between targets the error is a smooth chord sagitta
# (mm-long chords), so the coarser sampling lowers the maximum by 2 um on the water pump.
MESH_SCORE_SPACING_M = 5e-4
MESH_QUERY_CHUNK = 2000  # points per trimesh query (its memory grows with the points asked)


def mesh_deviation(
    workpiece: Workpiece, tool_radius_m: float, points_base: np.ndarray
) -> np.ndarray:
    """| distance from the mesh - tool radius | [m] of base-frame TCP points, shape (k,)."""
    pts = np.asarray(points_base, dtype=float).reshape(-1, 3)
    # Distances do not change under the rigid work-object transform: query the part's own mesh
    # in its frame, whose triangle tree trimesh builds once and caches (a mesh moved into the
    # base frame would be a new mesh, its tree rebuilt on every call).
    T_wobj_base = np.linalg.inv(workpiece.T_base_wobj)
    pts_wobj = pts @ T_wobj_base[:3, :3].T + T_wobj_base[:3, 3]
    # trimesh's query holds every candidate triangle of every point at once: in chunks, its
    # memory stays bounded whatever the tolerance (30k targets at 0.01 mm took 1.1 GB at once).
    distance = np.empty(len(pts_wobj))
    for start in range(0, len(pts_wobj), MESH_QUERY_CHUNK):
        chunk = pts_wobj[start : start + MESH_QUERY_CHUNK]
        with np.errstate(divide="ignore", invalid="ignore"):  # degenerate facets in trimesh
            _, distance[start : start + len(chunk)], _ = trimesh.proximity.closest_point(
                workpiece.mesh, chunk
            )
    return np.abs(distance - tool_radius_m)


def score_mesh(
    workpiece: Workpiece,
    tool_radius_m: float,
    positions_m: np.ndarray,
    moves: Sequence[Move] | None = None,
    *,
    spacing_m: float = MESH_SCORE_SPACING_M,
) -> PathScore:
    """Deviation of the program (targets and the moves between them) from the mesh.

    Args:
        workpiece: The part; its mesh in the base frame is the truth.
        tool_radius_m: Ball cutter radius.
        positions_m: (m, 3) target positions, base frame.
        moves: The move sequence (``arcs.Move``); default a straight move to every target.
        spacing_m: Distance between scored points along the moves.
    """
    pts = np.asarray(positions_m, dtype=float)
    if len(pts) < 2:
        raise InvalidInputError("scoring needs at least 2 targets")
    moves = linear_moves(len(pts)) if moves is None else tuple(moves)
    return score_sampled_moves(
        lambda points: mesh_deviation(workpiece, tool_radius_m, points),
        pts,
        moves,
        spacing_m=spacing_m,
    )
