"""Touching the real part to calibrate its work object: where to touch, and the touches.

PROBLEM   A work object is measured on the real part (``registration``), which may stand
          several millimetres and a degree or two off its CAD. A touch planned on the CAD must
          still meet the face it aims at, and only that face: from a start in free space, far
          enough off the face for the error, on a stretch flat for the error around the aim.
STRATEGY  Three-two-one, as a fixture is located, each face touched once more than it needs:
          four touches down on the part's top face, three across on its largest outer side,
          two across on an outer side facing another way (nine touches for six unknowns: the
          residual says how well the CAD fits, and every touch is checked by the others: with
          three on the top, a chip under one of them tilted the CAD 1.6-7.8 mm off with no
          residual over 0.34 mm, in 65 of 67 chips of 0.5-3 mm).
          Candidates are sampled on the CAD's planes (faces grouped by normal and offset, in
          the base frame: the tool comes from above) and kept when rays from the start over a
          square of +- the expected error meet the same plane at the same distance, and, for
          a side, nothing stands beyond the start (an outer side, not a groove's wall) nor
          above it (the tool comes down there). The kept ones farthest apart are taken.
SOLUTION  ``plan_touches(cad, tool_radius_m, robot=) -> TouchPlan`` (the scripted operator's,
          and the features a GUI shows to touch); ``touch_at(cad, point_wobj_m, tool_radius_m)``
          the touch of a face a person picked; ``scripted_touches(lt, state, plan, force_N)``
          the operator's guarded touches, each backed off to its start.
"""

from __future__ import annotations

import itertools
import math
from collections.abc import Callable
from dataclasses import dataclass

import numpy as np
import shapely

from ..cell import TOOL_DOWN, LeadThrough, LeadThroughState
from ..errors import InvalidInputError, NoContactError, RobomachError
from ..limits import TOUCH_OFF_FORCE_N
from ..part import PartDeviation, Workpiece, mesh_query
from .motion import go_to_point, move_by
from .registration import CalibrationError, Touch

EXPECTED_ERROR_M = 0.01  # the part may stand this far off its CAD at a touch (a few mm and 2 deg)
# ... as a shift and a turn about the work object's z: the realistic preset's largest fixture
# error (``PartDeviation``), which ``edge_margin_m`` spreads over a face
_PRESET = PartDeviation()
EXPECTED_SHIFT_M = _PRESET.fixture_shift_mm * 1e-3
EXPECTED_TURN_RAD = math.radians(_PRESET.fixture_rotation_deg)
TOP_STANDOFF_M = 0.008  # a touch down starts this far above the face
SIDE_STANDOFF_M = EXPECTED_ERROR_M + 0.003  # a touch across starts this far off the face
TOUCH_DEPTH_M = 0.008  # a side is touched this far below its top edge (the spindle stays above)
TABLE_CLEARANCE_M = 0.002  # ... and at least this far above the part's lowest point
SAFE_ABOVE_M = 0.03  # the tool travels between touches this far above the part
TOUCH_FORCE_N = TOUCH_OFF_FORCE_N.default_value()  # the chapter's lightest contact force
TOP_TOUCHES = 4  # the largest triangle on the top face, and a fourth point to check its plane
MIN_TOP_TOUCHES = 3  # ... the triangle alone where the arm reaches no fourth
SIDE_TOUCHES = 3
OTHER_SIDE_TOUCHES = 2
UP_COS = math.cos(math.radians(5.0))  # a face whose normal is this near +z faces up
SIDE_SIN = math.sin(math.radians(5.0))  # ... this near horizontal, sideways
ACROSS_COS = 0.5  # a second side faces at least 60 deg away from the first
PLANE_MATCH_M = 2e-5  # a ray meets the aimed plane when its hit lies this near it
CANDIDATES = 600


@dataclass(frozen=True)
class PlannedTouch:
    """One touch to make (base frame, SI).

    Attributes:
        feature: What it touches, for people ("top", "side facing -y (work object)").
        start_m: Where the ball's centre starts, in free space.
        direction: Unit direction of the guarded move (into the face).
        travel_m: How far the move searches.
        aim_m: The point of the CAD's face it aims at.
    """

    feature: str
    start_m: np.ndarray
    direction: np.ndarray
    travel_m: float
    aim_m: np.ndarray

    def document(self, T_base_wobj: np.ndarray) -> dict:
        """The touch at the boundary (mm; base and work-object frames)."""
        R, t = T_base_wobj[:3, :3], T_base_wobj[:3, 3]
        return {
            "feature": self.feature,
            "start_mm": [round(float(v) * 1e3, 3) for v in self.start_m],
            "start_wobj_mm": [round(float(v) * 1e3, 3) for v in (self.start_m - t) @ R],
            "direction": [round(float(v), 6) for v in self.direction],
            "direction_wobj": [round(float(v), 6) for v in self.direction @ R],
            "travel_mm": round(self.travel_m * 1e3, 3),
            "aim_mm": [round(float(v) * 1e3, 3) for v in self.aim_m],
        }


@dataclass(frozen=True)
class TouchPlan:
    """The touches of a calibration and the height the tool travels at between them."""

    touches: tuple[PlannedTouch, ...]
    safe_z_m: float


@dataclass(frozen=True)
class _Plane:
    normal: np.ndarray  # base frame, unit
    offset_m: float  # normal . p on the plane
    faces: np.ndarray
    area_m2: float


def _planes(mesh) -> list[_Plane]:
    """The mesh's faces grouped by plane (normal to 1e-3, offset to 0.05 mm)."""
    normals = np.asarray(mesh.face_normals)
    centres = np.asarray(mesh.triangles_center)
    areas = np.asarray(mesh.area_faces)
    offsets = np.einsum("ij,ij->i", normals, centres)
    keys = np.column_stack([np.round(normals, 3), np.round(offsets / 5e-5)])
    _, inverse = np.unique(keys, axis=0, return_inverse=True)
    out = []
    for g in range(int(inverse.max()) + 1):
        faces = np.flatnonzero(inverse.ravel() == g)
        area = float(areas[faces].sum())
        n = normals[faces].T @ areas[faces]
        n /= np.linalg.norm(n)
        out.append(_Plane(n, float(offsets[faces] @ areas[faces] / area), faces, area))
    return out


def _samples(mesh, plane: _Plane, rng: np.random.Generator, count: int) -> np.ndarray:
    """(count, 3) points on the plane's faces, spread by area."""
    tri = np.asarray(mesh.triangles)[plane.faces]
    area = np.asarray(mesh.area_faces)[plane.faces]
    pick = rng.choice(len(tri), count, p=area / area.sum())
    u, v = rng.uniform(size=(2, count))
    flip = u + v > 1
    u[flip], v[flip] = 1 - u[flip], 1 - v[flip]
    t = tri[pick]
    return t[:, 0] + u[:, None] * (t[:, 1] - t[:, 0]) + v[:, None] * (t[:, 2] - t[:, 0])


def _first_hits(mesh, origins: np.ndarray, direction: np.ndarray) -> np.ndarray:
    """(k,) distance to the first hit of each ray (inf: none)."""
    dirs = np.repeat(direction[None], len(origins), axis=0)
    locations, rays, _ = mesh_query.ray_hits(mesh, origins, dirs)
    out = np.full(len(origins), np.inf)
    if len(rays):
        along = np.einsum("ij,j->i", locations - origins[rays], direction)
        np.minimum.at(out, rays, along)
    return out


def _tangents(n: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    helper = np.array([0.0, 0.0, 1.0]) if abs(n[2]) < 0.9 else np.array([1.0, 0.0, 0.0])
    a = np.cross(helper, n)
    a /= np.linalg.norm(a)
    return a, np.cross(n, a)


def _flat(mesh, plane: _Plane, starts: np.ndarray, reach: float, spans: list) -> np.ndarray:
    """(k,) True where rays from every start shifted by each of ``spans`` (vectors) along
    -normal meet ``plane`` first, at ``reach`` (the aimed face, flat over the span)."""
    ok = np.ones(len(starts), dtype=bool)
    for s in spans:
        d = _first_hits(mesh, starts + s, -plane.normal)
        ok &= np.abs(d - reach) < PLANE_MATCH_M
    return ok


def _within_face(
    mesh, plane: _Plane, points: np.ndarray, axes: tuple[np.ndarray, np.ndarray],
    radii: tuple[float, float],
) -> np.ndarray:  # fmt: skip
    """(k,) True where the ellipse of ``radii`` along the two in-plane ``axes`` round each
    point lies on the plane's faces: their union in the plane, scaled by the radii and shrunk
    by 1 (shapely), holds the point. The rays of ``_flat`` sample it at a few places only; a
    groove between them passed, and a ball touching down over its edge read the top 0.17 mm
    low (the fit then tilted the part by 0.05 deg: 0.32 mm at its far end)."""
    a, b = axes[0] / radii[0], axes[1] / radii[1]
    tri = np.asarray(mesh.triangles)[plane.faces]
    uv = np.stack([tri @ a, tri @ b], axis=-1)  # (n, 3, 2)
    inner = shapely.union_all(shapely.polygons(uv)).buffer(-1.0)
    if inner.is_empty:
        return np.zeros(len(points), dtype=bool)
    return shapely.contains_xy(inner, points @ a, points @ b)


def _spread(points: np.ndarray, count: int) -> list[int]:
    """Indices of ``count`` points far apart (farthest-point order from the outermost)."""
    if len(points) == 0 or count <= 0:
        return []
    centre = points.mean(axis=0)
    chosen = [int(np.argmax(np.linalg.norm(points - centre, axis=1)))]
    nearest = np.linalg.norm(points - points[chosen[0]], axis=1)
    while len(chosen) < min(count, len(points)):
        k = int(np.argmax(nearest))
        if nearest[k] <= 1e-6:
            break
        chosen.append(k)
        nearest = np.minimum(nearest, np.linalg.norm(points - points[k], axis=1))
    return chosen


def _reachable(robot, start: np.ndarray) -> bool:
    """The arm reaches ``start`` with the tool pointing down (always, without an arm)."""
    if robot is None:
        return True
    T = np.eye(4)
    T[:3, :3], T[:3, 3] = TOOL_DOWN, start
    try:
        robot.ik(T, robot.home_rad)
    except RobomachError:
        return False
    return True


def _pick_top(points: np.ndarray, starts: np.ndarray, robot) -> list[int]:
    """Four candidates the arm reaches: three spanning the largest triangle (in x-y), the
    outermost, the farthest from it, the farthest from the line through both (three points
    far apart but in a row fix no turn about that row); then the farthest from the lines
    through two of those three (``off_lines_m``), which checks the plane they fix."""

    def first_reached(order: np.ndarray) -> int | None:
        return next((int(k) for k in order if _reachable(robot, starts[k])), None)

    xy = points[:, :2]
    a = first_reached(np.argsort(-np.linalg.norm(xy - xy.mean(axis=0), axis=1)))
    if a is None:
        return []
    b = first_reached(np.argsort(-np.linalg.norm(xy - xy[a], axis=1)))
    if b is None or b == a:
        return [a]
    c = first_reached(np.argsort(-off_lines_m(xy, xy[[a, b]])))
    if c is None or c in (a, b):
        return [a, b]
    d = first_reached(np.argsort(-off_lines_m(xy, xy[[a, b, c]])))
    return [a, b, c] if d is None or d in (a, b, c) else [a, b, c, d]


def off_lines_m(points: np.ndarray, chosen: np.ndarray) -> np.ndarray:
    """(k,) each point's distance from the nearest line through two of ``chosen`` (2 or 3
    points, any dimension): a third touch far off the line through two fixes the tilt across
    it, and a fourth far from every line through two of three leaves any three of the four
    off a row, so the others check each touch of a face's plane (farthest from the points
    alone picked the middle of a long top, in a row with two of them)."""
    out = np.full(len(points), np.inf)
    for i, j in itertools.combinations(range(len(chosen)), 2):
        axis = chosen[j] - chosen[i]
        axis = axis / max(float(np.linalg.norm(axis)), 1e-12)
        rel = points - chosen[i]
        out = np.minimum(out, np.linalg.norm(rel - np.outer(rel @ axis, axis), axis=1))
    return out


def _pick(keys: np.ndarray, starts: np.ndarray, count: int, robot) -> list[int]:
    """``count`` candidates far apart (``_spread`` over ``keys``) that the arm reaches."""
    order = _spread(keys, min(len(keys), 8 * count))
    picked = [k for k in order if _reachable(robot, starts[k])][:count]
    if len(picked) < count:
        return picked
    return [picked[i] for i in _spread(keys[picked], count)]


def _axis_words(normal_base: np.ndarray, T_base_wobj: np.ndarray) -> str:
    n = T_base_wobj[:3, :3].T @ normal_base
    i = int(np.argmax(np.abs(n)))
    if abs(n[i]) > math.cos(math.radians(10.0)):
        return f"{'+' if n[i] > 0 else '-'}{'xyz'[i]}"
    return "({:+.2f}, {:+.2f}, {:+.2f})".format(*n)


def edge_margin_m(points_wobj: np.ndarray) -> np.ndarray:
    """(k,) how far from a face's edge a touch at each point (work-object frame) must stay to
    meet that face on a part standing off its CAD by ``EXPECTED_SHIFT_M`` and turned
    ``EXPECTED_TURN_RAD`` about the work object's z: the edge moves by up to the shift plus the
    turn times its distance from the z axis (the point's and the margin's, hence the
    1 / (1 - turn)); ``EXPECTED_ERROR_M`` at least."""
    rho = np.linalg.norm(np.asarray(points_wobj, dtype=float).reshape(-1, 3)[:, :2], axis=1)
    moved = (EXPECTED_SHIFT_M + EXPECTED_TURN_RAD * rho) / (1.0 - EXPECTED_TURN_RAD)
    return np.maximum(moved, EXPECTED_ERROR_M)


def plan_touches(
    cad: Workpiece,
    tool_radius_m: float,
    *,
    robot=None,
    expected_error_m: float = EXPECTED_ERROR_M,
) -> TouchPlan:
    """Where the scripted operator touches the part (module docstring): four down on its top
    face, three across its largest outer side, two across an outer side facing another way.

    Raises:
        CalibrationError: the part has no top face or no two outer sides that a touch can
            reach with the tool pointing down (touch it by hand: ``touch_at``).
    """
    mesh = mesh_query.transformed(cad.mesh, cad.T_base_wobj)
    rng = np.random.default_rng(0)
    r = float(tool_radius_m)
    margin = expected_error_m + r
    planes = [p for p in _planes(mesh) if p.area_m2 > 1e-6]
    z_low, z_high = float(mesh.bounds[0, 2]), float(mesh.bounds[1, 2])
    safe_z = z_high + SAFE_ABOVE_M
    touches: list[PlannedTouch] = []

    ups = [p for p in planes if p.normal[2] > UP_COS and p.area_m2 > (2 * margin) ** 2]
    ups.sort(key=lambda p: (-round(p.offset_m / 1e-3), -p.area_m2))  # highest, then largest
    top = None
    flat_anywhere = False
    for plane in ups:
        pts = _samples(mesh, plane, rng, CANDIDATES)
        a, b = _tangents(plane.normal)
        reach = TOP_STANDOFF_M + r
        starts = pts + plane.normal * reach
        spans = [np.zeros(3)] + [m * margin for m in (a, -a, b, -b, a + b, a - b, b - a, -a - b)]
        ok = _flat(mesh, plane, starts, reach, spans)
        ok &= _within_face(mesh, plane, pts, (a, b), (margin, margin))
        flat_anywhere = flat_anywhere or ok.sum() >= MIN_TOP_TOUCHES
        picked = _pick_top(pts[ok], starts[ok], robot)
        if len(picked) >= MIN_TOP_TOUCHES:  # three where no fourth is reached: still a frame
            top = (plane, pts[ok][picked], starts[ok][picked])
            break
    if top is None and flat_anywhere:
        raise CalibrationError(
            f"{cad.name}: the {robot.name if robot is not None else 'arm'} reaches no three "
            "places of the part's top face with the tool pointing down: place the part nearer "
            "the arm"
        )
    if top is None:
        raise CalibrationError(
            f"{cad.name}: no top face of the part is flat over +-{margin * 1e3:.0f} mm where "
            "the tool can touch it from above: touch four points of a top face by hand (three "
            "at least)"
        )
    plane, pts, starts = top
    for k in range(len(pts)):
        touches.append(PlannedTouch(
            "top", starts[k], -plane.normal, TOP_STANDOFF_M + expected_error_m, pts[k]
        ))  # fmt: skip

    sides = []
    for plane in planes:
        if abs(plane.normal[2]) > SIDE_SIN or plane.area_m2 < 2 * margin * TOUCH_DEPTH_M:
            continue
        pts = _samples(mesh, plane, rng, CANDIDATES)
        tri = np.asarray(mesh.triangles)[plane.faces]
        top_z = float(tri[:, :, 2].max())
        depth = min(TOUCH_DEPTH_M, 0.5 * (top_z - z_low))
        z = max(top_z - depth, z_low + r + TABLE_CLEARANCE_M)
        pts = pts[np.abs(pts[:, 2] - z) < 0.5 * depth]  # the band at the touch height
        if len(pts) == 0:
            continue
        pts[:, 2] = z
        reach = SIDE_STANDOFF_M + r
        starts = pts + plane.normal * reach
        along = np.cross(np.array([0.0, 0.0, 1.0]), plane.normal)
        along /= np.linalg.norm(along)
        up = np.array([0.0, 0.0, 1.0])
        vertical = min(margin, 0.5 * depth)
        spans = [np.zeros(3), along * margin, -along * margin, up * vertical, -up * vertical]
        ok = _flat(mesh, plane, starts, reach, spans)
        ok &= _within_face(mesh, plane, pts, (along, up), (margin, vertical))
        ok &= np.isinf(_first_hits(mesh, starts, plane.normal))  # an outer side
        ok &= np.isinf(_first_hits(mesh, starts, up))  # the tool comes down there
        if ok.sum() >= 2:
            s = pts[ok] @ along
            sides.append((float(s.max() - s.min()), plane, pts[ok], starts[ok], along))
    sides.sort(key=lambda item: -item[0])
    if not sides:
        raise CalibrationError(
            f"{cad.name}: no outer side of the part can be touched from beside it with the tool "
            "pointing down: touch two sides by hand"
        )
    chosen: list[tuple] = []
    for _, plane, pts, starts, along in sides:
        if chosen and abs(plane.normal @ chosen[0][0].normal) >= ACROSS_COS:
            continue  # the second side faces across the first
        count = SIDE_TOUCHES if not chosen else OTHER_SIDE_TOUCHES
        picked = _pick((pts @ along)[:, None], starts, count, robot)
        if len(picked) == count:
            chosen.append((plane, pts[picked], starts[picked]))
        if len(chosen) == 2:
            break
    if len(chosen) < 2:
        raise CalibrationError(
            f"{cad.name}: {'no outer side' if not chosen else 'only sides facing one way'} of "
            "the part can be touched from beside it with the tool pointing down; a frame needs "
            "two sides facing across each other: touch them by hand"
        )
    for plane, pts, starts in chosen:
        name = f"side facing {_axis_words(plane.normal, cad.T_base_wobj)} (work object)"
        for p, start in zip(pts, starts, strict=True):
            touches.append(PlannedTouch(
                name, start, -plane.normal, SIDE_STANDOFF_M + expected_error_m, p
            ))  # fmt: skip
    return TouchPlan(tuple(touches), safe_z)


def touch_at(
    cad: Workpiece,
    point_wobj_m: np.ndarray,
    tool_radius_m: float,
    *,
    expected_error_m: float = EXPECTED_ERROR_M,
) -> PlannedTouch:
    """The touch of the face at a point a person picked on the CAD (work-object frame): it
    starts off the face along its normal (farther for a side, which may stand off by the
    error) and moves back along it.

    Raises:
        InvalidInputError: the point is not on the part (farther than 2 mm from its mesh).
    """
    p = np.asarray(point_wobj_m, dtype=float).reshape(3)
    closest, distance, tri = mesh_query.closest_point(cad.mesh, p[None])
    if float(distance[0]) > 0.002:
        raise InvalidInputError(
            f"the point is {float(distance[0]) * 1e3:.1f} mm from the part: pick a face of it"
        )
    R, t = cad.T_base_wobj[:3, :3], cad.T_base_wobj[:3, 3]
    n = R @ np.asarray(cad.mesh.face_normals)[int(tri[0])]
    on = R @ closest[0] + t
    side = abs(float(n[2])) < UP_COS
    standoff = SIDE_STANDOFF_M if side else TOP_STANDOFF_M
    name = "top" if not side else f"side facing {_axis_words(n, cad.T_base_wobj)} (work object)"
    return PlannedTouch(
        name, on + n * (standoff + tool_radius_m), -n, standoff + expected_error_m, on
    )


def scripted_touches(
    lt: LeadThrough,
    state: LeadThroughState,
    plan: TouchPlan,
    *,
    force_N: float = TOUCH_FORCE_N,
    progress: Callable[[float], None] | None = None,
) -> tuple[LeadThroughState, list[Touch]]:
    """The operator touches each planned feature: over its start at the safe height, tool
    pointing down, down to the start, a guarded move at ``force_N`` until the part pushes
    back, recorded, and back to the start.

    Raises:
        CalibrationError: a touch met nothing within its travel, or the part stood in the way
            of its start (the part is farther off its CAD than the plan allows).
    """
    touches: list[Touch] = []
    for k, planned in enumerate(plan.touches):
        state, touch = touch_once(lt, state, planned, force_N=force_N, safe_z_m=plan.safe_z_m,
                                  number=k + 1)  # fmt: skip
        touches.append(touch)
        if progress is not None:
            progress((k + 1) / len(plan.touches))
    return state, touches


def touch_once(
    lt: LeadThrough,
    state: LeadThroughState,
    planned: PlannedTouch,
    *,
    force_N: float,
    safe_z_m: float,
    number: int = 1,
) -> tuple[LeadThroughState, Touch]:
    """One planned touch (``scripted_touches``); the robot ends back at its start."""
    T = np.eye(4)
    T[:3, :3], T[:3, 3] = TOOL_DOWN, planned.start_m
    state, arrival = go_to_point(lt, state, T, safe_z_m=safe_z_m)
    if not arrival.reached:
        raise CalibrationError(
            f"touch {number} ({planned.feature}): the part stands where the touch starts "
            f"({arrival.describe()}): it is farther off its CAD than "
            f"{EXPECTED_ERROR_M * 1e3:.0f} mm there; touch it by hand"
        )
    try:
        state = lt.touch_off_along(state, planned.direction, force_N, planned.travel_m)
    except NoContactError as exc:
        raise CalibrationError(
            f"touch {number} ({planned.feature}) met nothing within "
            f"{planned.travel_m * 1e3:.0f} mm: the part is not where its CAD says, by more "
            "than the plan allows; touch it by hand"
        ) from exc
    c = state.cell
    force = -float(lt.measured_wrench(c)[:3] @ planned.direction)
    touch = Touch(
        tuple(c.T_base_tcp[:3, 3]), tuple(planned.direction), max(force, 0.0),
        lt.cell.tool.radius_m, planned.feature,
    )  # fmt: skip
    back = planned.start_m - c.T_base_tcp[:3, 3]
    state = move_by(lt, state, back, 0.02)
    return state, touch
