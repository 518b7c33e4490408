"""The route path learning runs, planned once from the guide points and the part as the user
sees it: the legs, the wall side, the height, and a walk along the mesh's wall before any motion.

PROBLEM   The guide points give the route, the orientation and the height; the wall gives the
          position by force (chapter section 3.1). Before the robot moves, four things must be
          settled once, and used by the run, the checks and the scores alike: which side of
          the route the wall is on (never a guess), what height to hold between the points on
          any floor (level, tilted, stepped, or none), how far the wall may lead the tool off a
          leg, and whether the route is one the wall can give at all (a slot taught as a loop
          would come back along the slot's other wall).
STRATEGY  - The side: the setting when it is "left" or "right" (it wins); on "auto", clear
            pushes at the points (at least ``WALL_FORCE_CLEAR_N`` across the leg), else the
            part's mesh (the points nearer one wall); evidence that disagrees, or none, is
            refused naming the points (``resolve_wall_side``).
          - The height (``HeightReference``): along the mean tool axis, the route holds
            h = surface(p) + offset, the offset interpolated along each leg between its two
            points. The surface is the floor under the tool in the mesh (measured every
            ``REFERENCE_SPACING_M`` of travel, under the cutter's centre and a radius either
            side along the travel) when every point has one below it, else the guide points'
            own plane. A point resting on the floor is lifted to ``floor_clearance_m`` above it.
          - The walk (``walk_route``): the ideal run on the mesh, a ball rolled along the wall
            on the chosen side at the route's heights, leg by leg with the run's own leg ends
            (``LegEnd``). Each leg's walk says how far its wall runs from the leg (the run's
            protection lets the tool that far off, + ``WANDER_MARGIN_M``), and a leg that comes
            back along the other wall of the free space it went along, where no point was
            taught, is refused: the wall is open.
SOLUTION  ``plan_route(guides, settings, *, workpiece, tool_radius_m) -> LearningRoute``, raising
          ``RouteRefusedError`` (``WallSideError`` for the side) with the reason and the fix.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass, field
from typing import Literal

import numpy as np
import pinocchio as pin

from ..cell import GuidePoint
from ..errors import InvalidInputError, RouteRefusedError, WallSideError
from ..part import Workpiece
from ..transforms import matrix_from_quaternion
from . import thresholds as th
from .law import LEG_SIZE, REF_SIZE
from .part_walls import PartWalls
from .settings import WALL_SIDE_CHOICES, PathLearningSettings
from .walk import (
    LegWalk,
    cross3,
    met_order,
    open_wall_return,
    pushed_against_walk,
    unreached_sentence,
    walk_beside,
    walk_route,
    walk_travel,
    walked_legs,
)

WallSide = Literal["left", "right"]


# --- the legs ------------------------------------------------------------------------------------


@dataclass(frozen=True)
class Leg:
    """One leg of the route: from guide point ``first`` to ``last`` (0-based)."""

    a: np.ndarray
    b: np.ndarray
    length: float
    xp: np.ndarray
    Ra: np.ndarray  # orientation at a
    omega: np.ndarray  # rotation vector from Ra to Rb, in Ra's axes (slerp Ra exp(f omega))
    first: int
    last: int
    beside: tuple[np.ndarray, np.ndarray] | None = None  # the walk's points beside a and b

    @property
    def height_chord(self) -> tuple[np.ndarray, np.ndarray, float]:
        """(start, unit direction, length) the height's progress along the leg is measured
        on: the walk's points beside its two guide points, where the route was walked and
        they stand ``MIN_SPACING_M`` apart or more, else the leg's own chord. Where a leg runs
        across the wall (a point taught off it, a neighbour close by on it), progress along
        its chord lags the travel along the wall, and a climb between the points came late."""
        if self.beside is not None:
            a, b = self.beside
            d = b - a
            n = float(np.linalg.norm(d))
            if n >= th.MIN_SPACING_M:
                return a, d / n, n
        return self.a, self.xp, self.length

    def progress(self, p: np.ndarray) -> float:
        """The share of the leg's height change done at ``p`` (0 to 1, ``law.route_height``)."""
        a, d, n = self.height_chord
        return min(max(float((p - a) @ d) / n, 0.0), 1.0)

    def row(self, offsets: tuple[float, float]) -> np.ndarray:
        """The leg as a row of the law's leg table (``law.LEG_A`` ...)."""
        ha, hxp, hlength = self.height_chord
        out = np.concatenate(
            [self.a, self.xp, [self.length], self.Ra.ravel(), self.omega, [self.first], offsets,
             ha, hxp, [hlength]]
        )  # fmt: skip
        assert len(out) == LEG_SIZE
        return out


def at_one_station(d: np.ndarray, normal: np.ndarray, axis: np.ndarray) -> bool:
    """Whether a neighbour the way ``d`` (across ``axis``) from a guide point standing by a
    wall face of unit ``normal`` (zero: by none) stands at the point's station of that wall:
    nearer than ``ONE_STATION_M``, the way to it more across the wall than along it (one point
    pressed on the wall, the other a gap off it). The way between two such points is no
    direction of travel, and the route cannot climb between them."""
    size = float(np.linalg.norm(d))
    if size >= th.ONE_STATION_M or not normal.any():
        return False
    return abs(float(d @ normal)) > abs(float(d @ np.cross(axis, normal)))


def route_legs(
    guides: Sequence[GuidePoint], closed: bool, normals: np.ndarray | None = None
) -> list[Leg]:
    """The legs through ``guides`` in order (back to the first when ``closed``), each measured
    across the tool axis (its direction and length: the progress along a leg, which sets the
    route's height, must not move with the tool's own height; along a leg steeper than it is
    long, progress measured in 3D held the tool at whatever height it had). Two points less
    than ``MIN_SPACING_M`` apart across the axis give no leg: the route goes on from the
    second, at its height.

    Raises:
        RouteRefusedError: two such points, or two at one station of their wall
            (``at_one_station``, with the ``normals`` of the wall faces the points stand by:
            ``station_normals``) less than ``MIN_SPACING_M`` apart along it, are more than
            ``TAUGHT_WALL_HEIGHT_BAND_M`` apart along the axis: the route holds one height at
            one place, so one of the two heights would be dropped without a word (a point 1.7
            mm off the wall 12.6 mm above its neighbour pressed on it at the same station was
            passed half-way between the two). Farther apart along the wall the route climbs
            between them, however steeply.
    """
    axis = mean_tool_axis(guides)
    order = list(range(len(guides))) + ([0] if closed else [])
    legs = []
    for i0, i1 in zip(order[:-1], order[1:], strict=True):
        a, b = guides[i0].position_m.copy(), guides[i1].position_m.copy()
        d = b - a
        across = d - axis * float(d @ axis)
        length = float(np.linalg.norm(across))
        one_place = length < th.MIN_SPACING_M or (
            normals is not None
            and any(
                at_one_station(way, normals[k], axis)
                and abs(float(way @ np.cross(axis, normals[k]))) < th.MIN_SPACING_M
                for k, way in ((i0, across), (i1, -across))
            )
        )
        rise = abs(float(d @ axis))
        if one_place and rise > th.TAUGHT_WALL_HEIGHT_BAND_M:
            where = "one above the other" if length < th.MIN_SPACING_M else "at one station"
            raise RouteRefusedError(
                f"G{i0 + 1} and G{i1 + 1} stand {where} ({length * 1e3:.1f} mm apart across "
                f"the tool axis, {rise * 1e3:.1f} mm along it): the route holds one height at "
                "one place; delete one of them, or move it along the wall"
            )
        if length < th.MIN_SPACING_M:
            continue
        Ra = matrix_from_quaternion(guides[i0].quaternion_wxyz)
        Rb = matrix_from_quaternion(guides[i1].quaternion_wxyz)
        legs.append(Leg(a, b, length, across / length, Ra, pin.log3(Ra.T @ Rb), i0, i1))
    return legs


# --- the side ------------------------------------------------------------------------------------


@dataclass(frozen=True)
class WallSideDecision:
    """The side of travel the wall is on, and what decided it.

    Attributes:
        side: "left" or "right" of travel, looking along the tool axis into the part.
        source: "setting" (the person's, which wins), "force" or "mesh".
        detail: One line for the operator (what the evidence was).
    """

    side: WallSide
    source: Literal["setting", "force", "mesh"]
    detail: str

    @property
    def sign(self) -> float:
        """+1 for the right, -1 for the left (``Yp = sign * (Zp x Xp)``)."""
        return 1.0 if self.side == "right" else -1.0


def mean_tool_axis(guides: Sequence[GuidePoint]) -> np.ndarray:
    """Unit mean of the guide points' tool axes (the axis the route's height is measured on)."""
    axes = np.array([g.T_base_tcp[:3, 2] for g in guides])
    u = axes.sum(axis=0)
    n = float(np.linalg.norm(u))
    return u / n if n > 1e-9 else axes[0]


def station_normals(guides: Sequence[GuidePoint], walls: PartWalls | None) -> np.ndarray | None:
    """(n, 3) the unit normal, across the axis, of the wall face each guide point stands by
    (its foot on a face within ``AT_WALL_GAP_M`` of its cutter); zero where it stands by none.
    None without walls."""
    if walls is None or walls.walls is None:
        return None
    pts = np.array([g.position_m for g in guides])
    closest, dist, on_face = walls.feet(pts)
    out = np.zeros_like(pts)
    axis = walls.axis
    for k in np.flatnonzero(on_face & (dist <= th.AT_WALL_GAP_M + walls.radius)):
        n = pts[k] - closest[k]
        n -= axis * float(n @ axis)
        size = float(np.linalg.norm(n))
        if size > 1e-9:
            out[k] = n / size
    return out


def travel_directions(
    guides: Sequence[GuidePoint],
    closed: bool,
    axis: np.ndarray,
    normals: np.ndarray | None = None,
) -> np.ndarray:
    """(n, 3) unit direction of travel at each point, across ``axis``: the mean of the
    directions to the points before and after it, each the nearest one at least
    ``MIN_SPACING_M`` away across the axis (two points taught one above the other give no
    direction) and not at the point's station of its wall (``at_one_station``, with the
    ``normals`` of ``station_normals``: one point pressed on the wall, the other a gap off it;
    the way between them is across the wall, and its side pointed along a slot at the other
    wall); one side at the ends of an open route; at a U-turn, the way in (the first point:
    the way out)."""
    pts = np.array([g.position_m for g in guides])
    pts = pts - np.outer(pts @ axis, axis)
    n = len(pts)
    out = np.zeros((n, 3))

    def toward(k: int, step: int) -> np.ndarray | None:
        j = k
        for _ in range(n - 1):
            j += step
            if not closed and not 0 <= j < n:
                return None
            d = (pts[j % n] - pts[k]) * step
            size = float(np.linalg.norm(d))
            if size >= th.MIN_SPACING_M and not (
                normals is not None and at_one_station(d, normals[k], axis)
            ):
                return d / size
        return None

    for k in range(n):
        units = [u for u in (toward(k, -1), toward(k, 1)) if u is not None]
        if not units:
            continue
        d = np.sum(units, axis=0)
        if len(units) == 2 and float(units[0] @ units[1]) < -0.5:  # a U-turn at this point
            d = units[1] if k == 0 else units[0]
        out[k] = d / max(float(np.linalg.norm(d)), 1e-12)
    return out


def right_of_travel(
    guides: Sequence[GuidePoint], closed: bool, walls: PartWalls | None = None
) -> tuple[np.ndarray, np.ndarray]:
    """(the mean tool axis, (n, 3) the unit right of travel at each point, across the axis;
    ``travel_directions``, with the walls the points stand by when the part's are known): the
    side a wall on the right is on."""
    axis = mean_tool_axis(guides)
    normals = station_normals(guides, walls)
    return axis, np.cross(axis, travel_directions(guides, closed, axis, normals))


def _points(numbers: Sequence[int] | np.ndarray) -> str:
    return ", ".join(f"G{k + 1}" for k in numbers)


def resolve_wall_side(
    guides: Sequence[GuidePoint],
    setting: str,
    *,
    closed: bool = True,
    walls: PartWalls | None = None,
) -> WallSideDecision:
    """The side of the wall to follow (module docstring): the setting wins.

    Raises:
        WallSideError: "auto" and no clear, consistent evidence.
    """
    if setting in ("left", "right"):
        side: WallSide = "left" if setting == "left" else "right"
        return WallSideDecision(side, "setting", f"the wall is on the {side} (as set)")
    if setting != "auto":
        raise InvalidInputError(f"wall side must be one of {', '.join(WALL_SIDE_CHOICES)}")
    if len(guides) < 2:
        raise WallSideError("the wall side needs at least 2 guide points")
    axis, right = right_of_travel(guides, closed, walls)
    forces = np.array([np.asarray(g.force_N, dtype=float) for g in guides])
    votes = -np.einsum("ij,ij->i", forces, right)  # > 0: the wall pushed from the right
    clear = np.abs(votes) >= th.WALL_FORCE_CLEAR_N
    pushed_r = np.flatnonzero(clear & (votes > 0))
    pushed_l = np.flatnonzero(clear & (votes < 0))
    if len(pushed_r) and len(pushed_l):
        raise WallSideError(
            f"the guide points were pushed against walls on both sides of the route "
            f"({_points(pushed_r)} on the right, {_points(pushed_l)} on the left): set the "
            "wall side, or record them again pushing towards the one wall to follow"
        )
    needed = min(th.MIN_FORCE_VOTES, len(guides))
    force_side: WallSide | None = None
    if len(pushed_r) >= needed:
        force_side = "right"
    elif len(pushed_l) >= needed:
        force_side = "left"
    mesh_side: WallSide | None = None
    mesh_detail = ""
    if walls is not None:
        r_gap, l_gap = walls.gaps(np.array([g.position_m for g in guides]), right)
        nearer_r = (r_gap <= th.AT_WALL_GAP_M) & (r_gap + th.NEARER_MARGIN_M < l_gap)
        nearer_l = (l_gap <= th.AT_WALL_GAP_M) & (l_gap + th.NEARER_MARGIN_M < r_gap)
        n_r, n_l = int(nearer_r.sum()), int(nearer_l.sum())
        if n_r + n_l >= math.ceil(len(guides) / 2) and max(n_r, n_l) >= th.MESH_MAJORITY * (
            n_r + n_l
        ):
            mesh_side = "right" if n_r > n_l else "left"
            mesh_detail = (
                f"{max(n_r, n_l)} of {len(guides)} points are nearer the wall on the {mesh_side}"
            )
        between = (np.maximum(r_gap, l_gap) <= th.AT_WALL_GAP_M) & ~nearer_r & ~nearer_l
        if force_side is None and mesh_side is None and between.sum() * 2 >= len(guides):
            k = int(np.flatnonzero(between)[0])
            raise WallSideError(
                f"the guide points stand between two walls, about as near the wall on the "
                f"right as the one on the left ({_points(np.flatnonzero(between))}; G{k + 1}: "
                f"{r_gap[k] * 1e3:.1f} mm to the right, {l_gap[k] * 1e3:.1f} mm to the left): "
                "set the wall side, or record them with a light push towards the wall to follow"
            )
        if mesh_side is None and n_r and n_l and force_side is None:
            raise WallSideError(
                f"the guide points sit nearer walls on both sides of the route "
                f"({_points(np.flatnonzero(nearer_r))} nearer the right, "
                f"{_points(np.flatnonzero(nearer_l))} nearer the left): set the wall side, "
                "or move them nearer the one wall to follow"
            )
    if force_side is not None:
        if mesh_side is not None and mesh_side != force_side:
            raise WallSideError(
                f"the guide points were pushed by a wall on the {force_side}, but the part's "
                f"mesh puts the nearest wall on the {mesh_side}: set the wall side"
            )
        pushes = pushed_r if force_side == "right" else pushed_l
        return WallSideDecision(
            force_side, "force", f"the wall pushed back from the {force_side} at {_points(pushes)}"
        )
    if mesh_side is not None:
        return WallSideDecision(mesh_side, "mesh", mesh_detail)
    raise WallSideError(
        "cannot tell which wall to follow: the guide points were not pushed against a wall "
        f"(at least {th.WALL_FORCE_CLEAR_N:g} N at {needed} points)"
        + (" and they are not clearly nearer one wall of the part" if walls is not None else "")
        + ": set the wall side (left or right of travel, looking along the tool into the "
        "part), or record the points with a light push towards the wall"
    )


def taught_wall_points(
    guides: Sequence[GuidePoint],
    side: str,
    closed: bool,
    walls: PartWalls,
    lifted_m: Sequence[float] | None = None,
    travel: np.ndarray | Sequence[Sequence[float]] | None = None,
) -> list[np.ndarray | None]:
    """The wall point each guide point was taught on: the nearest wall on its side of travel,
    within ``AT_WALL_GAP_M`` of the cutter, at the height it is learned at (``lifted_m`` above
    where it was recorded, off the floor); None where none is. The travel at a point is the
    walk's past it (``travel``, ``LearningRoute.guide_travel``: the way along its wall) where
    the walk passed it, else the chord through its neighbours (beside a jog of the wall, the
    chord runs across it and its side is the other wall's)."""
    axis, right = right_of_travel(guides, closed, walls)
    walked = np.zeros((0, 3)) if travel is None else np.asarray(travel, dtype=float)
    along = np.zeros(len(guides), dtype=bool)
    if walked.shape == right.shape:
        along = np.linalg.norm(walked, axis=1) > 0.5
        right[along] = np.cross(axis, walked[along])
    towards = right * (1.0 if side == "right" else -1.0)
    reach = th.AT_WALL_GAP_M + walls.radius
    lift = np.zeros(len(guides)) if lifted_m is None or not len(lifted_m) else lifted_m
    # where the walk passed, its way is the wall's: a wall met by a ray must face back within
    # the fan's angle of it (a stepped floor's riser across the groove faces along the travel:
    # taken for the wall 1.8 mm off a point 4.4 mm from it, it condemned a good program); off
    # a chord the way may be 60 deg or more off the wall, and any wall facing back is taken
    facing = np.where(along, math.cos(th.FAN_HALF_ANGLE_RAD), 0.0)
    return [
        walls.wall_point(g.position_m - axis * float(h), d, reach, float(f))
        for g, d, h, f in zip(guides, towards, lift, facing, strict=True)
    ]


# --- the height ----------------------------------------------------------------------------------


@dataclass
class HeightReference:
    """The surface the route's height is measured from (module docstring), and each guide
    point's offset over it.

    ``mode`` "floor": the mesh's floor under the tool; the offset is the cutter's centre's
    distance from the floor along its normal (radius + clearance), K = -1/cos(floor to axis).
    ``mode`` "points": the plane of the guide points' heights (h = H0 + G . (p - P0)); the
    offset is each point's height over it, K = 1.
    """

    mode: Literal["floor", "points"]
    axis: np.ndarray
    offsets_m: np.ndarray
    plane: np.ndarray  # REF_SIZE: the points' plane, or the last floor measured
    walls: PartWalls | None = None
    _last: np.ndarray | None = field(default=None, repr=False)
    _walked: tuple | None = field(default=None, repr=False)  # (tree, references) of the walk
    found: bool = field(default=True, repr=False)  # the last ``at`` measured a floor

    def remember(self, points: np.ndarray, references: np.ndarray) -> None:
        """Keep the references the walk measured at ``points``: the run takes the nearest
        (within ``WALK_MATCH_M``) instead of measuring the floor again."""
        from scipy.spatial import cKDTree

        if len(points):
            self._walked = (cKDTree(points), np.asarray(references))

    def at(
        self, p: np.ndarray, travel: np.ndarray | None = None, towards: np.ndarray | None = None
    ) -> np.ndarray:
        """(REF_SIZE,) the reference under ``p`` for the law (``law.REF_H0`` ...): in floor
        mode the highest floor under the cutter's centre, a radius behind it and a radius and
        ``STEP_LOOKAHEAD_M`` ahead along ``travel`` (a step up is climbed before the cutter
        reaches it); where none is below, the last one measured, extended as a plane. A floor
        above the cutter's centre counts only where the wall (``towards`` it) still stands
        beside it: a step up in the groove, not the top of the wall round a corner."""
        if self.mode == "points" or self.walls is None:
            return self.plane
        if self._walked is not None:
            distance, k = self._walked[0].query(p)
            if distance <= th.WALK_MATCH_M:
                return self._walked[1][k]
        r = self.walls.radius
        footprint = [p]
        if travel is not None:  # the cutter's footprint, and ahead of it along the travel
            side = cross3(travel, self.axis)
            footprint += [p + travel * (r + th.STEP_LOOKAHEAD_M), p - travel * r]
            footprint += [p + side * r, p - side * r]
        probes = np.array(footprint)
        height, normal = self.walls.floor(probes)
        a = self.axis
        cos = -(normal @ a)
        with np.errstate(divide="ignore", invalid="ignore"):  # no floor: nan, never used
            grad = (normal - np.outer(normal @ a, a)) / cos[:, None]  # dh/dp across the axis
            under_p = height + np.einsum("ij,ij->i", grad, p - probes)  # each plane at p
        usable = np.isfinite(height)
        for k in np.flatnonzero(usable & (height < float(p @ a))):  # above the cutter's centre
            above = probes[k] + a * (height[k] - float(probes[k] @ a) - th.FLOOR_ABOVE_M)
            reach = r + th.AT_WALL_GAP_M
            usable[k] = towards is not None and self.walls.faces_from_free_side(
                above, towards, reach
            )
        self.found = bool(usable.any())
        if not self.found:
            return self._last if self._last is not None else self.plane
        k = int(np.argmin(np.where(usable, under_p, np.inf)))  # the highest floor
        ref = np.empty(REF_SIZE)
        ref[0], ref[1:4], ref[4:7], ref[7] = under_p[k], grad[k], p, -1.0 / cos[k]
        self._last = ref
        return ref


def plan_heights(
    guides: Sequence[GuidePoint],
    axis: np.ndarray,
    floor_clearance_m: float,
    walls: PartWalls | None,
    *,
    closed: bool,
    sign: float,
) -> tuple[HeightReference, np.ndarray]:
    """The height reference and how far each point was lifted off the floor [m] (module
    docstring): the floor mode when every point has a floor below it in the mesh, measured
    under its whole cutter (a point beside a step up stands on the step's top)."""
    pts = np.array([g.position_m for g in guides])
    heights = pts @ axis
    lifted = np.zeros(len(guides))
    if walls is not None and all(np.isfinite(walls.floor(pts)[0])):
        reference = HeightReference("floor", axis, np.zeros(len(guides)), np.zeros(REF_SIZE), walls)
        travel = travel_directions(guides, closed, axis, station_normals(guides, walls))
        need = walls.radius + floor_clearance_m
        offsets = np.zeros(len(guides))
        for k, p in enumerate(pts):  # the highest floor under each point's cutter
            ref = reference.at(p, travel[k], cross3(axis, travel[k]) * sign)
            cos = -1.0 / ref[7]
            centre = (ref[0] - heights[k]) * cos  # the cutter's centre above that floor
            offsets[k] = max(centre, need)
            lifted[k] = max(0.0, (need - centre) / cos)
        reference.offsets_m = offsets
        reference.plane = reference.at(pts[0])
        return reference, lifted
    # The points' own plane; a point the floor pushed (beyond a wall's cone) is lifted.
    for k, g in enumerate(guides):
        f = np.asarray(g.force_N, dtype=float)
        along = float(f @ axis)
        across = float(np.linalg.norm(f - axis * along))
        if -along > th.FLOOR_CONE_TAN * across + th.FLOOR_FORCE_N:
            lifted[k] = floor_clearance_m
    heights = heights - lifted
    plane = _points_plane(pts, heights, axis)
    offsets = heights - np.array([route_height_plane(plane, p) for p in pts])
    return HeightReference("points", axis, offsets, plane), lifted


def route_height_plane(plane: np.ndarray, p: np.ndarray) -> float:
    return float(plane[0] + plane[1:4] @ (p - plane[4:7]))


def _points_plane(pts: np.ndarray, heights: np.ndarray, axis: np.ndarray) -> np.ndarray:
    """The least-squares plane of the points' heights over the plane across ``axis``; no
    slope along a direction the points do not spread over (``FLOOR_SEARCH_M``)."""
    across = pts - np.outer(pts @ axis, axis)
    centre = across.mean(axis=0)
    _, sv, vt = np.linalg.svd(across - centre, full_matrices=False)
    spread = sv / math.sqrt(max(len(pts), 1))
    dirs = [vt[i] for i in range(min(2, len(sv))) if spread[i] > th.PLANE_SPREAD_M]
    A = np.column_stack([np.ones(len(pts))] + [(across - centre) @ d for d in dirs])
    coef, *_ = np.linalg.lstsq(A, heights, rcond=None)
    ref = np.zeros(REF_SIZE)
    ref[0] = coef[0]
    ref[1:4] = sum((c * d for c, d in zip(coef[1:], dirs, strict=True)), np.zeros(3))
    ref[4:7] = centre
    ref[7] = 1.0
    return ref


# --- the route -----------------------------------------------------------------------------------


@dataclass(frozen=True)
class LearningRoute:
    """The route a run follows, planned once (module docstring).

    Attributes:
        guides: The guide points as recorded.
        legs: The legs through them.
        closed: The route returns to its first point.
        axis: (3,) the mean tool axis, into the part (the height axis, Zp).
        wall_side: The side of the wall and what decided it.
        heights: The height reference and the points' offsets over it.
        lifted_m: (n,) how far each point was lifted off the floor [m].
        start_towards_wall: (3,) from the first point towards the wall it was taught on, or
            None without a mesh (the force recorded there, or across the first leg).
        leg_wander_m: {(i, j): m}: how far the wall of the leg from point i to j may lead the
            tool off it, where the mesh says more than the default protection.
        walks: The route walked on the mesh (empty without one).
    """

    guides: tuple[GuidePoint, ...]
    legs: tuple[Leg, ...]
    closed: bool
    axis: np.ndarray
    wall_side: WallSideDecision
    heights: HeightReference
    lifted_m: np.ndarray
    start_towards_wall: np.ndarray | None = None
    leg_wander_m: dict[tuple[int, int], float] = field(default_factory=dict)
    walks: tuple[LegWalk, ...] = ()

    @property
    def guide_travel(self) -> np.ndarray:
        """(n, 3) the way the walk travels past each guide point (``walk_travel``)."""
        return walk_travel(self.guides, self.legs, self.walks, self.axis, self.wall_side.sign)

    def leg_offsets(self, leg: Leg) -> tuple[float, float]:
        o = self.heights.offsets_m
        return float(o[leg.first]), float(o[leg.last])


def _astray(
    guides: Sequence[GuidePoint],
    legs: Sequence[Leg],
    walks: Sequence[LegWalk],
    axis: np.ndarray,
    closed: bool,
) -> bool:
    """The walk meets the guide points out of the order taught (``met_order``), or passes
    a point's push with its wall the other way (``pushed_against_walk``)."""
    points = [w.points_m for w in walks if len(w.points_m)]
    if points and met_order([g.position_m for g in guides], np.vstack(points), axis, closed):
        return True
    return bool(pushed_against_walk(guides, legs, walks, axis))


def _nearest_wins(
    guides: Sequence[GuidePoint],
    legs: Sequence[Leg],
    by_chord: Sequence[LegWalk],
    by_nearest: Sequence[LegWalk],
    axis: np.ndarray,
    closed: bool,
) -> bool:
    """Whether the first point's walk starts from the wall it stands by (``by_nearest``)
    rather than the one its chord's side gives (``by_chord``): when the chord's walk meets the
    points out of order or against a push and the nearest's does not (a sparse loop whose first
    chord cuts across an island: its side's wall is the groove's outer one, round the other
    way); else when the first leg's walk from the wall it stands by reaches the second point in
    under ``FIRST_WALK_SHARE`` of the chord's (the chord's wall is across a slot's end or a
    bay, and its walk runs round it). Otherwise the chord's wall: a point nearer the groove's
    other wall, the side as taught."""
    if (
        by_nearest[-1].reached
        and _astray(guides, legs, by_chord, axis, closed)
        and not _astray(guides, legs, by_nearest, axis, closed)
    ):
        return True
    return by_nearest[0].reached and (
        not by_chord[0].reached
        or by_nearest[0].length_m < th.FIRST_WALK_SHARE * by_chord[0].length_m
    )


def plan_route(
    guides: Sequence[GuidePoint],
    settings: PathLearningSettings,
    *,
    workpiece: Workpiece | None = None,
    tool_radius_m: float | None = None,
) -> LearningRoute:
    """The route for ``guides`` (module docstring).

    Raises:
        NotEnoughGuidePointsError: fewer than two distinct points.
        WallSideError: the side is "auto" and neither the pushes nor the mesh tell it.
        RouteRefusedError: the route cannot be learned as taught (an open wall as a loop, two
            points one above the other).
    """
    from ..errors import NotEnoughGuidePointsError

    closed = settings.closed
    guides = tuple(guides)
    if len(guides) < 2:
        raise NotEnoughGuidePointsError(
            f"path learning needs at least 2 guide points, got {len(guides)}"
        )
    axis = mean_tool_axis(guides)
    walls = None
    if workpiece is not None and tool_radius_m is not None:
        walls = PartWalls(workpiece, axis, tool_radius_m)
        if walls.walls is None:
            walls = None
    legs = tuple(route_legs(guides, closed, station_normals(guides, walls)))
    if not legs:
        raise NotEnoughGuidePointsError("the guide points coincide; record distinct points")
    right = right_of_travel(guides, closed, walls)[1]
    decision = resolve_wall_side(guides, settings.wall_side, closed=closed, walls=walls)
    heights, lifted = plan_heights(
        guides, axis, settings.floor_clearance_m, walls, closed=closed, sign=decision.sign
    )
    route = LearningRoute(guides, legs, closed, axis, decision, heights, lifted)
    if walls is None:
        return route
    assert tool_radius_m is not None  # the walls are built with the tool's radius only
    towards = right[0] * decision.sign
    first = guides[0].position_m - axis * lifted[0]  # at the height it is learned at
    first_wall = walls.wall_point(first, towards, 2 * th.AT_WALL_GAP_M)
    (nearest,), (dist,), (on_face,) = walls.feet(first[None])
    way = nearest - first
    level = abs(float(way @ axis)) <= math.sqrt(1.0 - th.FOOT_ON_FACE_COS**2) * float(
        np.linalg.norm(way)
    )  # an edge between wall faces at its height (a corner), not a riser's top
    stands_by = (on_face or level) and dist <= th.AT_WALL_GAP_M + tool_radius_m
    offsets = [route.leg_offsets(leg) for leg in legs]
    if first_wall is None:
        # Nothing the chord's side's way. Diagonally off an outside corner (its foot on the
        # corner's edge), the corner is its wall: the chord's way past it is open space. Else
        # the part may not be where its mesh is (a point taught on a part shifted off its CAD
        # may stand inside the mesh): the run searches by force.
        if not (stands_by and level and not on_face) or walls.inside(first):
            return route
        starts = [nearest]
    else:
        starts = [first_wall]
        if stands_by and float(np.linalg.norm(nearest - first_wall)) > th.MIN_SPACING_M:
            # the wall it stands by is another than the one its chord's side gives (beside a
            # jog or bay the chord runs across or against the wall; or the point is nearer the
            # groove's other wall): both are walked
            starts.append(nearest)
    tried = []
    for wall_point in starts:
        start_dir = wall_point - first
        start_dir -= axis * float(start_dir @ axis)
        if float(np.linalg.norm(start_dir)) < 1e-9:
            continue
        start_dir /= float(np.linalg.norm(start_dir))
        start = first + start_dir * (float(np.linalg.norm(wall_point - first)) - tool_radius_m)
        walks = walk_route(legs, heights, offsets, decision.sign, walls, start, closed=closed)
        tried.append((start_dir, start, walks))
    if not tried:
        return route
    if len(tried) > 1:
        (chord_dir, _, by_chord), (near_dir, _, by_nearest) = tried
        if _nearest_wins(guides, legs, by_chord, by_nearest, axis, closed):
            walks, start_dir = by_nearest, near_dir
        else:  # walk it again: the height reference keeps the last walk's
            walks = walk_route(
                legs, heights, offsets, decision.sign, walls, tried[0][1], closed=closed
            )
            start_dir = chord_dir
    problem = open_wall_return(walks, legs, tool_radius_m) if closed else ""
    for leg, walk in zip(legs, walks, strict=False):
        if not problem and walk.off_floor_m > th.OPEN_RETURN_M:
            problem = (
                f"the leg G{leg.first + 1} -> G{leg.last + 1} would follow the wall off the part: "
                f"for {walk.off_floor_m * 1e3:.0f} mm there is no floor under the tool (the wall "
                "runs out of the part"
                + (", so the wall taught is open: learn it open (--open, or untick 'closed')"
                   if closed and leg is legs[-1] else "")
                + "); put a point where the route should go, or check the wall side"
            )  # fmt: skip
        if not problem and walk.over_top_m > th.OVER_TOP_M:
            problem = (
                f"between G{leg.first + 1} and G{leg.last + 1} the route's height takes the "
                f"cutter over the wall's top for {walk.over_top_m * 1e3:.0f} mm (the wall is lower "
                "there than at the points, a step in the floor or a lower top): teach these "
                "points lower on the wall"
            )
    if not problem and not walks[-1].reached:
        problem = unreached_sentence(walks, legs, decision.side, closed)
    if problem:
        raise RouteRefusedError(problem)
    wander = {
        (leg.first, leg.last): walk.wander_m + th.WANDER_MARGIN_M
        for leg, walk in zip(legs, walks, strict=False)
        if walk.reached
    }
    legs = walked_legs(legs, walk_beside(guides, legs, walks, axis), axis)
    return LearningRoute(
        guides, legs, closed, axis, decision, heights, lifted, start_dir, wander, tuple(walks)
    )
