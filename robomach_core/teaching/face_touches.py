"""Touching a face the person picked, at the points the three-two-one of a calibration asks.

PROBLEM   A work object is fixed by six touches, three-two-one (``registration``): three on
          a top face (its height and tilt), two on a side (its turn), one on a side across
          (the last shift). A person picks faces, not points: one click on a face should touch
          it where the frame needs it, spread far enough apart to fix its tilt or turn, on the
          same flat face, and not so near its edge that a part standing a few millimetres off
          its CAD is missed there.
STRATEGY  The face at the pick is the plane of the mesh's face there (normal and offset).
          Candidates are drawn over that plane's faces (on a side at the pick's height, along
          it, so the spindle stays above the side's top edge); one (the pick too) is
          kept when the mesh's closest point to it, and to each point ``edge_margin_m`` around
          it, lies on the same plane (flat over the error the part may have). The kept point
          nearest the pick comes first (the pick itself unless it is near the face's edge),
          then the kept candidate farthest from it, a third farthest from the line through
          those two (the tilt across a long face), a fourth farthest from the lines through
          two of those three (so the others check each), and more farthest from the points
          chosen.
          How many: what the example operator's plan takes from a face of that kind (four on
          the top, three and two on two sides: three-two-one and a touch to spare on each
          face, ``touches_for_face``).
SOLUTION  ``touches_for_face(up, directions)`` and ``face_touch_points(cad, point, count)``
          -> (k, 3) points of the face (work-object frame) to touch with
          ``Calibration.touch(at_wobj_m=...)``.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Sequence

import numpy as np

from ..errors import InvalidInputError
from ..part import Workpiece, mesh_query
from .calibration import (
    EXPECTED_ERROR_M,
    OTHER_SIDE_TOUCHES,
    SIDE_TOUCHES,
    TOP_TOUCHES,
    edge_margin_m,
    off_lines_m,
)

CANDIDATES = 400  # points drawn on the face to choose its touches from
# ... each on the face over ``calibration.edge_margin_m`` around it: at least the error the
# example operator's plan keeps off an edge (``EXPECTED_ERROR_M``; also the least spacing of
# two touches), more where the part's turn about its work object's z carries the face's end
# further (a 400 mm block's end). At a fixed 6 mm, one click-touch in 14 on a realistic part
# (2-4 mm and 1-2 deg off: 10 mm at the end of a 300 mm plate) ran past the face's end and met
# its corner, and the fit put the CAD 11-17 mm off (seed 1885297732 of test_workbench_cell's
# three-click calibration).
FLAT_MARGIN_M = EXPECTED_ERROR_M
PLANE_COS = math.cos(math.radians(3.0))  # a face of the same plane: normal within 3 deg ...
PLANE_M = 5e-5  # ... and within 0.05 mm of the plane
ON_FACE_M = 5e-4  # a candidate this near the mesh lies on it
UP_COS = math.cos(math.radians(30.0))  # a face (or a touch down) this near vertical is a top
PICK_DISTANCE_M = 0.002  # a pick farther than this from the mesh is not on the part


def touches_for_face(up: bool, directions: Sequence[Sequence[float]], up_axis=(0, 0, 1)) -> int:
    """How many touches a face should take given the touches made so far (their unit
    ``directions``; ``up_axis`` the part's up, same frame): as the example operator's plan
    (``calibration.plan_touches``), three-two-one with a touch to spare on each face, so that
    the others check each touch: a top
    face (``up``) up to ``TOP_TOUCHES``, the first side ``SIDE_TOUCHES``, another side
    ``OTHER_SIDE_TOUCHES``, and one at least."""
    u = np.asarray(up_axis, dtype=float)
    d = np.asarray(directions, dtype=float).reshape(-1, 3)
    down = d @ -u > UP_COS
    if up:
        return max(1, TOP_TOUCHES - int(np.count_nonzero(down)))
    sides = int(np.count_nonzero(~down))
    return SIDE_TOUCHES if sides == 0 else max(1, OTHER_SIDE_TOUCHES - max(0, sides - SIDE_TOUCHES))


def face_touch_points(
    cad: Workpiece,
    point_wobj_m: np.ndarray,
    count: int,
    *,
    reachable: Callable[[np.ndarray], bool] | None = None,
) -> np.ndarray:
    """(k, 3) points of the face at ``point_wobj_m`` (work-object frame) to touch, k <= count:
    the flat point nearest the pick first, then points of the same flat face far from those
    chosen (module docstring); ``reachable(point)`` (work-object frame) drops points the arm
    cannot touch. Fewer than ``count`` when the face is too small for more.

    Raises:
        InvalidInputError: the point is not on the part, or count is below 1.
    """
    if count < 1:
        raise InvalidInputError("a face is touched at one point at least")
    mesh = cad.mesh
    p = np.asarray(point_wobj_m, dtype=float).reshape(3)
    closest, distance, tri = mesh_query.closest_point(mesh, p[None])
    if float(distance[0]) > PICK_DISTANCE_M:
        raise InvalidInputError(
            f"the point is {float(distance[0]) * 1e3:.1f} mm from the part: pick a face of it"
        )
    pick = np.asarray(closest[0], dtype=float)
    n = np.asarray(mesh.face_normals[int(tri[0])], dtype=float)
    offset = float(n @ pick)
    up = abs(float(n[2])) > UP_COS
    tangents = _tangents(n, up)
    candidates = np.vstack([pick[None], _candidates(mesh, pick, n, offset, up)])
    flat = _on_plane(mesh, candidates, n, offset, tangents)
    if reachable is not None:
        flat &= np.array([bool(reachable(c)) for c in candidates])
    kept = candidates[flat]
    if len(kept) == 0:  # a face too small to be flat around any point: the pick, as it is
        return pick[None]
    # The first touch nearest the pick (the pick itself when its face is flat around it).
    chosen = [kept[int(np.argmin(np.linalg.norm(kept - pick, axis=1)))]]
    while len(chosen) < count:
        gaps = _spread_from(kept, np.asarray(chosen), across=up)
        k = int(np.argmax(gaps))
        if gaps[k] < FLAT_MARGIN_M:
            break
        chosen.append(kept[k])
    return np.asarray(chosen)


def _spread_from(points: np.ndarray, chosen: np.ndarray, *, across: bool) -> np.ndarray:
    """(k,) how far each point stands from those chosen: from the one point, then (on a face
    spread ``across``, a top) from the line through the first two (a third touch of a long
    face off that line fixes its tilt across it: farthest from both ends picked one at the
    end of a bar) and from the lines through two of the three (``off_lines_m``: the fourth),
    then from the nearest chosen point."""
    if across and len(chosen) in (2, 3):
        return off_lines_m(points, chosen)
    return np.min(np.linalg.norm(points[:, None] - chosen[None], axis=2), axis=1)


def _tangents(n: np.ndarray, up: bool) -> list[np.ndarray]:
    """The directions a face's touches spread along: both tangents of a top face, the
    horizontal one of a side (its touches stay at the pick's height, below its top edge)."""
    z = np.array([0.0, 0.0, 1.0])
    helper = np.array([1.0, 0.0, 0.0]) if up else z
    a = np.cross(helper, n)
    a /= np.linalg.norm(a)
    return [a, np.cross(n, a)] if up else [a]


def _candidates(mesh, pick: np.ndarray, n: np.ndarray, offset: float, up: bool) -> np.ndarray:
    """Points on the plane's faces, spread by area (a side's at the pick's height)."""
    normals = np.asarray(mesh.face_normals)
    centres = np.asarray(mesh.triangles_center)
    faces = np.flatnonzero(
        (normals @ n > PLANE_COS) & (np.abs(centres @ n - offset) < PLANE_M + 1e-3)
    )
    tri = np.asarray(mesh.triangles)[faces]
    area = np.asarray(mesh.area_faces)[faces]
    if len(faces) == 0 or area.sum() <= 0:
        return np.zeros((0, 3))
    rng = np.random.default_rng(0)  # the same points for the same pick
    pick_tri = rng.choice(len(tri), CANDIDATES, p=area / area.sum())
    u, v = rng.uniform(size=(2, CANDIDATES))
    flip = u + v > 1
    u[flip], v[flip] = 1 - u[flip], 1 - v[flip]
    t = tri[pick_tri]
    points = t[:, 0] + u[:, None] * (t[:, 1] - t[:, 0]) + v[:, None] * (t[:, 2] - t[:, 0])
    if not up:  # a side: at the pick's height, below the face's top edge
        points[:, 2] = pick[2]
    return points


def _on_plane(
    mesh, points: np.ndarray, n: np.ndarray, offset: float, tangents: list[np.ndarray]
) -> np.ndarray:
    """(k,) True where each point, and every point ``edge_margin_m`` around it along the
    tangents, lies on the plane (n, offset) of the mesh."""
    margin = edge_margin_m(points)[:, None]
    shifts = [np.zeros(3)] + [s * margin * t for t in tangents for s in (1.0, -1.0)]
    ok = np.ones(len(points), dtype=bool)
    for shift in shifts:
        closest, distance, tri = mesh_query.closest_point(mesh, points + shift)
        normals = np.asarray(mesh.face_normals)[np.asarray(tri, dtype=int)]
        ok &= np.asarray(distance) < ON_FACE_M
        ok &= normals @ n > PLANE_COS
        ok &= np.abs(np.asarray(closest) @ n - offset) < PLANE_M
    return ok
