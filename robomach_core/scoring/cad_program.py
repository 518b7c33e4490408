"""What learning buys: the program a CAD/CAM tool would make from the mesh alone, scored against
the real wall beside the learned one.

PROBLEM   With the real part different from its CAD (``real_part``), the program planned from
          the mesh carries the fixture error and the casting's deviations, while the learned one
          (chapter section 3) follows the wall the robot met. Neither number means much alone:
          the user must see both against the same truth, signed (an overcut is not a small
          error) and placed (where the worst error sits).
STRATEGY  At the learned path's height above the floor (the section parallel to the floor
          under it, ``walls.floor_under``), the CAD's wall nearest to the learned targets
          (``walls.section_loops``) is offset by the tool radius towards the free side
          (shapely's exact round joins), over the same stretch as the learned path, sampled
          densely and reduced by the same deviation-height tolerance (chapter fig. 3), with the
          learned orientation at each target; it is placed with the nominal work object, as a
          CAD/CAM program is. Both programs are then sampled every ``SCORE_SPACING_M`` along
          their moves and measured against the real part's wall at that height (the casting
          without its burrs, ``Workpiece.scoring_mesh``): signed distance minus the radius,
          negative inside the material (overcut), positive in the air.
SOLUTION  ``compare_with_cad(workpiece, positions, quaternions, tool_radius_m, tolerance_m,
          closed) -> CadComparison | None`` (None when the learned path follows no wall of the
          mesh), with a ``WallScore`` per program; ``comparison_summary`` for summary.json and
          the API.
"""

from __future__ import annotations

import math
import threading
import weakref
from dataclasses import dataclass, replace

import numpy as np
import shapely

from ..learning.walls import WallLoop, floor_under, section_loops
from ..part import Workpiece
from ..part.mesh_query import transformed
from ..postprocess import reduce_deviation_height
from ..transforms import arc_length_m

# Every 0.1 mm along the moves: between targets the error is a smooth chord sagitta, whose
# maximum a 0.1 mm sampling misses by well under a micrometre on millimetre-long chords.
SCORE_SPACING_M = 1e-4
NEAREST_LOOP_POINTS = 200  # the learned targets that decide which wall they follow
DENSE_M = 5e-5  # the CAD path is sampled this densely before the reduction
MAX_WALL_DISTANCE_M = 0.005  # a learned path farther than this from every wall follows none


@dataclass(frozen=True)
class WallScore:
    """Signed deviation of a program from a wall (metres; + air, - overcut).

    Attributes:
        max_m: Largest |deviation| along the program.
        rms_m: RMS deviation along the program.
        overcut_m: Deepest cut into the material (>= 0).
        air_m: Largest gap off the wall (>= 0).
        worst_wobj_m: (3,) where |deviation| is largest, work-object frame.
        worst_fraction: How far along the program that is, 0-1.
        along_m: (k,) arc length of the scored points along the program.
        deviation_m: (k,) signed deviation at each.
        points_m: (k, 3) the scored points, base frame (for drawing).
    """

    max_m: float
    rms_m: float
    overcut_m: float
    air_m: float
    worst_wobj_m: np.ndarray
    worst_fraction: float
    along_m: np.ndarray
    deviation_m: np.ndarray
    points_m: np.ndarray

    def summary(self) -> dict:
        """The figures in mm, for summary.json and the API."""
        return {
            "max_deviation_mm": round(self.max_m * 1e3, 4),
            "rms_deviation_mm": round(self.rms_m * 1e3, 4),
            "overcut_mm": round(self.overcut_m * 1e3, 4),
            "air_mm": round(self.air_m * 1e3, 4),
            "worst_at_wobj_mm": [round(float(v) * 1e3, 2) for v in self.worst_wobj_m],
            "worst_at_fraction": round(self.worst_fraction, 4),
        }


@dataclass(frozen=True)
class CadComparison:
    """The learned program and the CAD-only program against the real wall.

    Attributes:
        cad_positions_m: (m, 3) targets of the CAD-only program, base frame.
        cad_quaternions_wxyz: (m, 4) their orientations (the learned program's).
        learned: Score of the learned program.
        cad_only: Score of the CAD-only program.
        z_m: Height of the comparison (the learned path's), work-object frame.
        closed: The programs are closed contours.
        part_deviates: The real part differs from its CAD (``real_part``).
        deviation_note: How it differs, for people.
        cad_only_unregistered: Score of the same CAD-only program written in the work object
            as it was before the calibration (``registration``; what a calibration buys),
            None when the work object was not calibrated.
    """

    cad_positions_m: np.ndarray
    cad_quaternions_wxyz: np.ndarray
    learned: WallScore
    cad_only: WallScore
    z_m: float
    closed: bool
    part_deviates: bool
    deviation_note: str
    cad_only_unregistered: WallScore | None = None

    def summary(self) -> dict:
        """summary.json's ``cad_comparison``: the scores and the CAD-only program's size
        (``cad_only_uncalibrated``: the CAD-only program in the work object as placed before
        the calibration, null without one)."""
        unregistered = self.cad_only_unregistered
        return {
            "part_deviates_from_cad": self.part_deviates,
            "deviation": self.deviation_note,
            "height_wobj_mm": round(self.z_m * 1e3, 3),
            "cad_only_targets": len(self.cad_positions_m),
            "learned": self.learned.summary(),
            "cad_only": self.cad_only.summary(),
            "cad_only_uncalibrated": None if unregistered is None else unregistered.summary(),
        }


def _to_wobj(T_base_wobj: np.ndarray, points_base: np.ndarray) -> np.ndarray:
    return (np.asarray(points_base, dtype=float) - T_base_wobj[:3, 3]) @ T_base_wobj[:3, :3]


def _to_base(T_base_wobj: np.ndarray, points_wobj: np.ndarray) -> np.ndarray:
    return np.asarray(points_wobj, dtype=float) @ T_base_wobj[:3, :3].T + T_base_wobj[:3, 3]


def _nearest_loop(loops: list[WallLoop], xy: np.ndarray) -> tuple[WallLoop, float] | None:
    points = shapely.points(xy[:: max(1, len(xy) // NEAREST_LOOP_POINTS)])
    best = None
    for loop in loops:
        chain = np.vstack([loop.points_m, loop.points_m[:1]]) if loop.closed else loop.points_m
        d = float(np.median(shapely.distance(points, shapely.LineString(chain))))
        if best is None or d < best[1]:
            best = (loop, d)
    return best


def _polyline(points: np.ndarray, closed: bool, spacing_m: float) -> tuple[np.ndarray, np.ndarray]:
    """Points every ``spacing_m`` along the straight moves through ``points`` (and back to the
    first when ``closed``), and their arc lengths."""
    chain = np.vstack([points, points[:1]]) if closed else np.asarray(points)
    out, along, s0 = [], [], 0.0
    for a, b in zip(chain[:-1], chain[1:], strict=True):
        length = float(np.linalg.norm(b - a))
        n = max(2, int(math.ceil(length / spacing_m)) + 1)
        f = np.linspace(0.0, 1.0, n)[:-1]
        out.append(a + (b - a) * f[:, None])
        along.append(s0 + f * length)
        s0 += length
    out.append(chain[-1:])
    along.append(np.array([s0]))
    return np.vstack(out), np.concatenate(along)


def score_against_wall(
    positions_base_m: np.ndarray,
    wall: WallLoop,
    T_base_wobj: np.ndarray,
    tool_radius_m: float,
    *,
    closed: bool = False,
) -> WallScore:
    """Signed deviation of the straight moves through ``positions_base_m`` from ``wall``
    (work-object frame): the ball's centre distance from the wall minus its radius."""
    points, along = _polyline(np.asarray(positions_base_m, dtype=float), closed, SCORE_SPACING_M)
    wobj = _to_wobj(T_base_wobj, points)
    deviation = wall.signed_distance(wobj[:, :2]) - tool_radius_m
    k = int(np.argmax(np.abs(deviation)))
    return WallScore(
        max_m=float(np.abs(deviation).max()),
        rms_m=float(np.sqrt(np.mean(deviation**2))),
        overcut_m=float(max(0.0, -deviation.min())),
        air_m=float(max(0.0, deviation.max())),
        worst_wobj_m=wobj[k].copy(),
        worst_fraction=float(along[k] / along[-1]) if along[-1] > 0 else 0.0,
        along_m=along,
        deviation_m=deviation,
        points_m=points,
    )


def _offset_path(loop: WallLoop, radius_m: float, closed: bool) -> np.ndarray | None:
    """(n, 2) the wall offset by ``radius_m`` to its free side (left of travel), in the wall's
    direction; None when the offset vanishes."""
    if closed:
        ring = shapely.Polygon(loop.points_m)
        ccw = shapely.LinearRing(loop.points_m).is_ccw
        # Material on the right: a counter-clockwise wall has the free side inside.
        grown = ring.buffer(-radius_m if ccw else radius_m, quad_segs=32)
        if grown.is_empty:
            return None
        if grown.geom_type == "MultiPolygon":
            grown = max(grown.geoms, key=lambda g: g.area)
        coords = np.asarray(grown.exterior.coords)[:-1]
        if shapely.LinearRing(coords).is_ccw != ccw:
            coords = coords[::-1]
        return coords
    line = shapely.LineString(loop.points_m).offset_curve(radius_m, quad_segs=32)
    if line.is_empty:
        return None
    if line.geom_type == "MultiLineString":
        line = max(line.geoms, key=lambda g: g.length)
    return np.asarray(line.coords)


def _resample(path: np.ndarray, closed: bool, spacing_m: float) -> np.ndarray:
    chain = np.vstack([path, path[:1]]) if closed else path
    s = arc_length_m(chain)
    n = max(2, int(math.ceil(s[-1] / spacing_m)) + 1)
    t = np.linspace(0.0, s[-1], n)
    if closed:
        t = t[:-1]
    return np.column_stack([np.interp(t, s, chain[:, 0]), np.interp(t, s, chain[:, 1])])


def cad_only_program(
    cad: Workpiece,
    wall: WallLoop,
    tool_radius_m: float,
    tolerance_m: float,
    *,
    closed: bool,
    start_xy: np.ndarray,
    end_xy: np.ndarray | None = None,
    forward: bool = True,
    T_base_frame: np.ndarray | None = None,
) -> np.ndarray | None:
    """(m, 3) base-frame targets of the CAD-only program: ``wall`` (the CAD's, in the
    work-object frame or ``T_base_frame``, the floor's, where it was cut) offset by the tool
    radius to its free side, travelled along the wall (against it when not ``forward``), from
    the point nearest ``start_xy`` (to the one nearest ``end_xy`` when open), reduced with
    ``tolerance_m``."""
    path = _offset_path(wall, tool_radius_m, closed)
    if path is None or len(path) < 2:
        return None
    dense = _resample(path, closed, DENSE_M)
    if not forward:
        dense = dense[::-1]
    i0 = int(np.argmin(np.linalg.norm(dense - start_xy, axis=1)))
    if closed:
        dense = np.vstack([np.roll(dense, -i0, axis=0), dense[i0 : i0 + 1]])
    else:
        i1 = (
            len(dense) - 1
            if end_xy is None
            else int(np.argmin(np.linalg.norm(dense - end_xy, axis=1)))
        )
        dense = dense[min(i0, i1) : max(i0, i1) + 1]
        if i1 < i0:
            dense = dense[::-1]
    if len(dense) < 2:
        return None
    points = np.column_stack([dense, np.full(len(dense), wall.z_m)])
    kept = reduce_deviation_height(points, tolerance_m)
    targets = points[kept]
    if closed:
        targets = targets[:-1]  # the program closes the loop itself (as the learned one ends)
    return _to_base(cad.T_base_wobj if T_base_frame is None else T_base_frame, targets)


def compare_with_cad(
    workpiece: Workpiece,
    positions_m: np.ndarray,
    quaternions_wxyz: np.ndarray,
    tool_radius_m: float,
    tolerance_m: float,
    *,
    closed: bool,
) -> CadComparison | None:
    """The learned targets (base frame) and the CAD-only program against the real wall
    (module docstring); None when the learned path follows no wall of the mesh."""
    positions = np.asarray(positions_m, dtype=float)
    if len(positions) < 2:
        return None
    cad = workpiece.cad()
    # The walls are cut parallel to the floor under the path (``walls.floor_under``; the work
    # object's x-y on a level part): a part tilted in its mesh has no horizontal wall.
    T_floor = floor_under(cad.mesh, _to_wobj(cad.T_base_wobj, positions[:1])[0])
    T = cad.T_base_wobj @ T_floor
    wobj = _to_wobj(T, positions)  # in the floor's frame
    z = float(np.median(wobj[:, 2]))
    inverse = np.linalg.inv(T_floor)
    cad_loops = _sections(transformed(cad.mesh, inverse), z)
    # The real part's mesh is in its own work object (the placement's); the CAD's may have
    # been moved onto it by a calibration: both are cut in the CAD's floor frame.
    real_in_cad = np.linalg.inv(cad.T_base_wobj) @ workpiece.T_base_wobj
    real_loops = _sections(transformed(workpiece.scoring_mesh(), inverse @ real_in_cad), z)
    found_cad = _nearest_loop(cad_loops, wobj[:, :2])
    found_real = _nearest_loop(real_loops, wobj[:, :2])
    if found_cad is None or found_real is None:
        return None
    cad_wall, d_cad = found_cad
    real_wall, d_real = found_real
    if min(d_cad, d_real) > MAX_WALL_DISTANCE_M + tool_radius_m:
        return None
    s = cad_wall.project(wobj[:, :2])
    steps = np.diff(s)
    if cad_wall.closed:
        steps = (steps + 0.5 * cad_wall.length_m) % cad_wall.length_m - 0.5 * cad_wall.length_m
    forward = float(np.sum(steps)) >= 0.0
    closed_program = closed and cad_wall.closed
    cad_targets = cad_only_program(
        cad,
        cad_wall,
        tool_radius_m,
        tolerance_m,
        closed=closed_program,
        start_xy=wobj[0, :2],
        end_xy=None if closed_program else wobj[-1, :2],
        forward=forward,
        T_base_frame=T,
    )
    if cad_targets is None or len(cad_targets) < 2:
        return None
    nearest = np.argmin(
        np.linalg.norm(cad_targets[:, None, :] - positions[None, :, :], axis=2), axis=1
    )
    quats = np.asarray(quaternions_wxyz, dtype=float)[nearest]
    learned, cad_only = (
        replace(score, worst_wobj_m=T_floor[:3, :3] @ score.worst_wobj_m)
        for score in (
            score_against_wall(positions, real_wall, T, tool_radius_m),
            score_against_wall(cad_targets, real_wall, T, tool_radius_m, closed=closed_program),
        )
    )
    unregistered = None
    if workpiece.unregistered is not None:  # the same program in the work object as it was
        M = workpiece.unregistered.T_base_wobj @ np.linalg.inv(cad.T_base_wobj)
        before = cad_targets @ M[:3, :3].T + M[:3, 3]
        score = score_against_wall(before, real_wall, T, tool_radius_m, closed=closed_program)
        unregistered = replace(score, worst_wobj_m=T_floor[:3, :3] @ score.worst_wobj_m)
    return CadComparison(
        cad_targets,
        quats,
        learned,
        cad_only,
        z,
        closed_program,
        workpiece.nominal is not None,
        workpiece.deviation_note,
        unregistered,
    )


_SECTIONS: list[tuple[weakref.ref, float, list[WallLoop]]] = []
_SECTIONS_KEPT = 8
_SECTIONS_LOCK = threading.Lock()


def _sections(mesh, z: float) -> list[WallLoop]:
    """``section_loops`` of a mesh at ``z``, remembered for the last few (mesh, z) while the
    mesh lives: a post-processing run again with other settings compares at the same height.
    The mesh is held weakly (it held the last eight parts, uploads of 500k triangles too)."""
    z = round(float(z), 5)  # 10 um: the walls are the same a few micrometres up or down
    with _SECTIONS_LOCK:
        for m, zz, loops in _SECTIONS:
            if m() is mesh and zz == z:
                return loops
    loops = section_loops(mesh, z)
    with _SECTIONS_LOCK:
        _SECTIONS[:] = [entry for entry in _SECTIONS if entry[0]() is not None]
        _SECTIONS.append((weakref.ref(mesh), z, loops))
        del _SECTIONS[:-_SECTIONS_KEPT]
    return loops
