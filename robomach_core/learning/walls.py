"""Walls of a part's mesh at one height: the loop a picked point belongs to, the floor's frame
and the machining height beside it.

PROBLEM   Pointing at the part must give a wall to follow: the picked face alone says nothing
          about where the wall goes, which side is free, how deep the groove is, or where the
          tool may stand without touching the floor or the other wall of a narrow groove. On a
          part that is not level in its mesh, a horizontal section cuts the walls obliquely.
STRATEGY  Find the floor beside the picked wall (a ray down beside it; the part's top just
          inside it on an outside edge) and work in the floor's frame, whose z is the floor's
          normal. There, cut the mesh with the plane at the machining height (trimesh's
          ``mesh_plane``): each segment comes with the face it cuts, whose normal says which
          side is free, so every segment is oriented with the material on the right (as the
          built-in walls are) and chained into loops, closed or open (GEOS's line merge). The
          machining height is the picked point's own, when the tool can work there
          (``_machining_height``).
SOLUTION  ``section_loops(mesh, z_m)`` -> ``WallLoop``s (x-y of the mesh's frame, metres), with
          arc length, points, free-side normals and a signed distance (+ free side, -
          material); ``pick_wall(mesh, point, normal, ...)`` -> ``WallPick`` (the floor frame,
          the loop, the machining height, floor and top, the arc length of the pick, notes).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from functools import cached_property

import numpy as np
import shapely
import trimesh

from ..errors import InvalidInputError
from ..part.mesh_query import closest_point, ray_hits, transformed
from ..transforms import unit_vector
from .thresholds import (
    AMBIGUOUS_CLICK_RADII,
    CONTACT_BELOW_TOP_M,
    CONTACT_BELOW_TOP_RADII,
    CUTTER_FLOOR_CLEARANCE_M,
    LEVEL_FLOOR_RAD,
    MAX_PICK_DISTANCE_M,
    SPINDLE_CLEARANCE_M,
    STITCH_M,
    WALL_FACE_MAX_COS,
)

MERGE_M = 1e-9  # segment ends on one point of this grid are one point of a loop
NORMAL_WINDOW_M = 5e-4  # the free-side normal is the mean over this much wall either side


@dataclass(frozen=True)
class WallLoop:
    """A wall of the part at one height, travelled with the material on its right.

    Attributes:
        points_m: (n, 2) points in the work-object x-y plane [m]; a closed loop does not repeat
            its first point.
        z_m: Height of the section in the work-object frame [m].
        closed: The wall returns to its start.
    """

    points_m: np.ndarray
    z_m: float
    closed: bool

    @cached_property
    def _chain(self) -> np.ndarray:
        p = np.asarray(self.points_m, dtype=float)
        return np.vstack([p, p[:1]]) if self.closed else p

    @cached_property
    def cumulative_m(self) -> np.ndarray:
        """(n or n + 1,) arc length at each point of the chain (closed: back to the start)."""
        d = np.linalg.norm(np.diff(self._chain, axis=0), axis=1)
        return np.concatenate([[0.0], np.cumsum(d)])

    @property
    def length_m(self) -> float:
        return float(self.cumulative_m[-1])

    def wrap(self, s: np.ndarray) -> np.ndarray:
        """Arc lengths brought into [0, length) on a closed loop, clipped on an open one."""
        s = np.asarray(s, dtype=float)
        return np.mod(s, self.length_m) if self.closed else np.clip(s, 0.0, self.length_m)

    def point_at(self, s: np.ndarray) -> np.ndarray:
        """(k, 2) points at arc lengths ``s`` (k,)."""
        s = self.wrap(np.atleast_1d(s))
        c = self.cumulative_m
        return np.column_stack(
            [np.interp(s, c, self._chain[:, 0]), np.interp(s, c, self._chain[:, 1])]
        )

    def free_normal_at(self, s: np.ndarray, window_m: float = NORMAL_WINDOW_M) -> np.ndarray:
        """(k, 2) unit normals towards the free side (left of travel), each the direction of
        the chord over ``window_m`` either side turned left: at a sharp corner, its bisector."""
        s = np.atleast_1d(np.asarray(s, dtype=float))
        d = self.point_at(s + window_m) - self.point_at(s - window_m)
        n = np.column_stack([-d[:, 1], d[:, 0]])
        return n / np.maximum(np.linalg.norm(n, axis=1, keepdims=True), 1e-15)

    @cached_property
    def _segments(self) -> shapely.STRtree:
        """The chain's segments in shapely's R-tree (index i: from point i to point i + 1)."""
        c = self._chain
        return shapely.STRtree(shapely.linestrings(np.stack([c[:-1], c[1:]], axis=1)))

    def _nearest(self, xy: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """(s, distance): the arc length of the nearest wall point to each of (k, 2) points
        and the distance to it, exact (the nearest segment from the R-tree, the foot of the
        perpendicular on it)."""
        (point, segment), distance = self._segments.query_nearest(
            shapely.points(xy), return_distance=True, all_matches=False
        )
        start, d = self._chain[segment], np.diff(self._chain, axis=0)[segment]
        length2 = np.einsum("ij,ij->i", d, d)
        along = np.einsum("ij,ij->i", xy[point] - start, d) / np.where(length2 > 0, length2, 1.0)
        s, dist = np.empty(len(xy)), np.empty(len(xy))
        s[point] = self.cumulative_m[segment] + np.clip(along, 0.0, 1.0) * np.sqrt(length2)
        dist[point] = distance
        return self.wrap(s), dist

    def project(self, points_xy: np.ndarray) -> np.ndarray:
        """(k,) arc length of the nearest wall point to each of (k, 2) points."""
        return self._nearest(np.atleast_2d(np.asarray(points_xy, dtype=float)))[0]

    def signed_distance(self, points_xy: np.ndarray) -> np.ndarray:
        """(k,) distance of (k, 2) points from the wall: positive on the free side, negative
        in the material (the side is the one of the chord over the nearest point)."""
        xy = np.atleast_2d(np.asarray(points_xy, dtype=float))
        s, distance = self._nearest(xy)
        free = np.sum((xy - self.point_at(s)) * self.free_normal_at(s, 1e-5), axis=1)
        return np.where(free >= 0.0, distance, -distance)

    def sample(self, spacing_m: float) -> tuple[np.ndarray, np.ndarray]:
        """(s, points): arc lengths every ~``spacing_m`` and the (k, 2) points there."""
        n = max(2, int(math.ceil(self.length_m / spacing_m)) + (0 if self.closed else 1))
        s = np.linspace(0.0, self.length_m, n, endpoint=not self.closed)
        return s, self.point_at(s)

    def piece(self, s0: float, s1: float, spacing_m: float = 1e-4) -> WallLoop:
        """The open wall from ``s0`` to ``s1`` (on a closed loop it may run over the start)."""
        if self.closed and s1 < s0:
            s1 += self.length_m
        c = self.cumulative_m
        inner = c[(c > s0) & (c < s1)]
        if self.closed:  # the chain's vertices once more, shifted, for a piece over the start
            inner = np.concatenate([inner, c[(c + self.length_m > s0) & (c + self.length_m < s1)]
                                    + self.length_m])  # fmt: skip
        s = np.unique(np.concatenate([[s0], inner, [s1]]))
        return WallLoop(self.point_at(s), self.z_m, closed=False)


def section_loops(mesh: trimesh.Trimesh, z_m: float) -> list[WallLoop]:
    """Every wall of ``mesh`` (its own frame) at height ``z_m``, oriented with the material on
    the right (the cut face's normal on the left of travel), longest first. A height on a
    vertex is moved off it by a micrometre (a plane through vertices cuts faces edge-on)."""
    z_m = _off_vertices(mesh, z_m)
    lines, face_index = trimesh.intersections.mesh_plane(
        mesh, [0.0, 0.0, 1.0], [0.0, 0.0, float(z_m)], return_faces=True
    )
    if len(lines) == 0:
        return []
    a = lines[:, 0, :2].copy()
    b = lines[:, 1, :2].copy()
    n = np.asarray(mesh.face_normals)[face_index][:, :2]
    d = b - a
    keep = np.linalg.norm(d, axis=1) > 1e-13
    a, b, n, d = a[keep], b[keep], n[keep], d[keep]
    flip = (-d[:, 1] * n[:, 0] + d[:, 0] * n[:, 1]) < 0  # the free side must be on the left
    a[flip], b[flip] = b[flip].copy(), a[flip].copy()
    # Ends on one point of a MERGE_M grid are one point (they move by under a nanometre);
    # GEOS chains the oriented segments into closed rings and open lines.
    segments = shapely.set_precision(shapely.linestrings(np.stack([a, b], axis=1)), MERGE_M)
    merged = shapely.line_merge(
        shapely.multilinestrings(segments[~shapely.is_empty(segments)]), directed=True
    )
    loops = []
    for line in shapely.get_parts(merged):
        points, closed = shapely.get_coordinates(line), bool(line.is_closed)
        loops.append(WallLoop(points[:-1] if closed else points, float(z_m), closed))
    loops = _stitched([lp for lp in loops if len(lp.points_m) >= 2 and lp.length_m > 1e-6])
    return sorted(loops, key=lambda lp: -lp.length_m)


def _stitched(loops: list[WallLoop]) -> list[WallLoop]:
    """Open chains joined where one ends within ``STITCH_M`` of another's start (a crack in
    the mesh: faces that meet along an edge one of them has a vertex on), and a chain closed
    when its ends meet so."""
    closed = [lp for lp in loops if lp.closed]
    chains = [lp.points_m for lp in loops if not lp.closed]
    joined = True
    while joined and chains:
        joined = False
        for i, a in enumerate(chains):
            for j, b in enumerate(chains):
                if i != j and np.linalg.norm(a[-1] - b[0]) < STITCH_M:
                    chains[i] = np.vstack([a, b])
                    del chains[j]
                    joined = True
                    break
            if joined:
                break
    z = loops[0].z_m if loops else 0.0
    for c in chains:
        ends_meet = bool(len(c) > 2 and np.linalg.norm(c[-1] - c[0]) < STITCH_M)
        closed.append(WallLoop(c[:-1] if ends_meet else c, z, ends_meet))
    return [lp for lp in closed if len(lp.points_m) >= 2 and lp.length_m > 1e-5]


@dataclass(frozen=True)
class WallPick:
    """A wall picked at a point, at the machining height, in the floor's frame.

    The floor frame (``T_wobj_floor``) is the work object's turned so that its z is the
    normal of the floor beside the pick (the identity on a level part): the section, the
    heights and the loops are in it, and ``mesh`` is the part there.

    Attributes:
        point_m: (3,) the picked point (work-object frame).
        normal: (3,) the surface normal there (work-object frame, out of the material).
        loop: The wall at the machining height.
        s_m: Arc length of the picked point along ``loop``.
        z_m: The machining height: the TCP's z (floor frame).
        floor_z_m: The floor beside the wall (the part's bottom when it stands free).
        top_z_m: The top of the wall.
        others: Every other wall at that height (the groove's other side, islands).
        notes: What was changed and why, for people (e.g. the height raised for the spindle).
        T_wobj_floor: 4x4 floor frame in the work object (a rotation about its origin).
        mesh: The part in the floor frame.
    """

    point_m: np.ndarray
    normal: np.ndarray
    loop: WallLoop
    s_m: float
    z_m: float
    floor_z_m: float
    top_z_m: float
    others: tuple[WallLoop, ...] = ()
    notes: tuple[str, ...] = field(default=())
    T_wobj_floor: np.ndarray = field(default_factory=lambda: np.eye(4))
    mesh: trimesh.Trimesh | None = None

    def to_wobj(self, points_floor_m: np.ndarray) -> np.ndarray:
        """(k, 3) floor-frame points in the work-object frame."""
        return np.atleast_2d(points_floor_m) @ self.T_wobj_floor[:3, :3].T

    def to_floor(self, points_wobj_m: np.ndarray) -> np.ndarray:
        """(k, 3) work-object points in the floor frame."""
        return np.atleast_2d(points_wobj_m) @ self.T_wobj_floor[:3, :3]

    def heights(self, xy_m: np.ndarray) -> np.ndarray:
        """(k,) TCP heights (floor frame) at (k, 2) places beside the wall: the pick's height
        above the floor under each (a stepped or sloped floor; the pick's floor where there
        is none under it: an outside edge)."""
        xy = np.atleast_2d(np.asarray(xy_m, dtype=float))
        origins = np.column_stack([xy, np.full(len(xy), self.z_m + RAY_START_M)])
        assert self.mesh is not None  # pick_wall gives every pick its part
        floor, _ = _below(self.mesh, origins, _Z)
        floor = np.where(np.isnan(floor[:, 2]), self.floor_z_m, floor[:, 2])
        return floor + (self.z_m - self.floor_z_m)


_Z = np.array([0.0, 0.0, 1.0])
RAY_START_M = 1e-6  # a ray starts this far off the surface it leaves (no hit on it)
INSIDE_M = 3e-4  # the wall's top is looked for this far inside it
TOP_PROBES_M = (INSIDE_M, 0.001, 0.003, 0.010)  # and the part's top (an edge's floor) so far in
SPINDLE_RING = 8  # rays round the spindle's rim (and at half its radius, and on its axis)


def _hits(
    mesh: trimesh.Trimesh,
    origins: np.ndarray,
    directions: np.ndarray,
    *,
    floor_up: np.ndarray | None = None,
) -> tuple[np.ndarray, np.ndarray]:
    """(points (k, 3), face normals (k, 3)) of the first surface along each ray (one
    direction for all, or one each), or with ``floor_up`` the first floor-like one (facing
    within 45 deg of it: past a wall that leans over the ray); NaN rows where none."""
    origins = np.atleast_2d(origins)
    points = np.full((len(origins), 3), np.nan)
    normals = np.full((len(origins), 3), np.nan)
    directions = np.broadcast_to(np.asarray(directions, dtype=float), origins.shape)
    hits, ray, tri = ray_hits(mesh, origins, directions, multiple_hits=floor_up is not None)
    faces = np.asarray(mesh.face_normals)[tri]
    if floor_up is not None:  # nearest first, floor-like only, one per ray
        keep = faces @ floor_up >= WALL_FACE_MAX_COS
        hits, ray, faces = hits[keep], ray[keep], faces[keep]
        along = np.einsum("ij,ij->i", hits - origins[ray], directions[ray])
        order = np.lexsort((along, ray))
        first = order[np.r_[True, np.diff(ray[order]) != 0]] if len(order) else order
        hits, ray, faces = hits[first], ray[first], faces[first]
    points[ray] = hits
    normals[ray] = faces
    return points, normals


def _below(
    mesh: trimesh.Trimesh, origins: np.ndarray, up: np.ndarray, *, floors: bool = True
) -> tuple[np.ndarray, np.ndarray]:
    """``_hits`` straight down ``-up`` from each origin: the first floor-like surface (any
    surface without ``floors``)."""
    up = np.asarray(up, dtype=float)
    return _hits(mesh, origins, -up, floor_up=up if floors else None)


def _across(normal: np.ndarray, up: np.ndarray) -> np.ndarray | None:
    """The unit direction off the wall parallel to the floor (None: a face parallel to it)."""
    a = normal - (normal @ up) * up
    size = float(np.linalg.norm(a))
    return a / size if size > 1e-9 else None


def _free_width(mesh: trimesh.Trimesh, on: np.ndarray, across: np.ndarray) -> float:
    """How far the free space reaches off the wall at ``on`` along ``across`` (inf: open)."""
    (hit, *_), _ = _hits(mesh, on + across * 2e-5, across)
    return math.inf if np.isnan(hit[0]) else float(np.linalg.norm(hit - on))


def floor_frame(
    mesh: trimesh.Trimesh, on_m: np.ndarray, normal: np.ndarray, beside_m: float
) -> np.ndarray:
    """T_wobj_floor: the work object turned so that its z is the normal of the floor beside
    the wall point ``on_m`` (``beside_m`` off it, or the free space's middle when narrower),
    or, where nothing floor-like is there (an outside edge), of the part's top nearest inside
    the wall; the identity on a level part, or where no face within 45 deg of level
    (``WALL_FACE_MAX_COS``) is found."""
    up = _Z
    level = WALL_FACE_MAX_COS  # a face nearer level than a wall is a floor
    span = float(np.linalg.norm(np.ptp(mesh.bounds, axis=0))) + 0.01
    for _ in range(2):  # the second pass measures beside the wall along the new floor
        across = _across(normal, up)
        if across is None:
            break
        beside = min(beside_m, 0.5 * _free_width(mesh, on_m, across))
        origins = np.vstack(
            [on_m + across * beside + up * RAY_START_M]
            + [on_m - across * k + up * span for k in TOP_PROBES_M]
        )
        _, faces = _below(mesh, origins, up)
        floors = [f for f in faces if f @ _Z >= level]  # NaN rows compare False
        if not floors:
            break
        up = floors[0] / np.linalg.norm(floors[0])
    return _frame(up)


def _frame(up: np.ndarray) -> np.ndarray:
    """T_wobj_floor whose z is ``up``, its x the work object's turned into the floor (the
    identity within ``LEVEL_FLOOR_RAD`` of level)."""
    T = np.eye(4)
    if math.acos(min(1.0, float(up @ _Z))) < LEVEL_FLOOR_RAD:
        return T
    x = np.array([1.0, 0.0, 0.0]) - up[0] * up
    x /= np.linalg.norm(x)
    T[:3, :3] = np.column_stack([x, np.cross(up, x), up])
    return T


def floor_under(mesh: trimesh.Trimesh, point_wobj_m: np.ndarray) -> np.ndarray:
    """T_wobj_floor at a TCP position beside a wall (work-object frame): ``floor_frame`` at
    the nearest point of the part (its floor's normal when that is a floor)."""
    p = np.asarray(point_wobj_m, dtype=float).reshape(3)
    closest, distance, triangle = closest_point(mesh, p[None])
    n = np.asarray(mesh.face_normals[int(triangle[0])], dtype=float)
    if n @ _Z >= WALL_FACE_MAX_COS:
        return _frame(n)
    return floor_frame(mesh, np.asarray(closest[0], dtype=float), n, float(distance[0]))


def walls_near(
    mesh: trimesh.Trimesh, points_wobj_m: np.ndarray
) -> tuple[np.ndarray, np.ndarray, list[WallLoop]]:
    """(T_wobj_floor, the points in the floor frame, the walls at their median height there)
    for TCP positions beside a wall (work-object frame): the frame of the floor under the
    first point (level where nothing floor-like is under it)."""
    p = np.atleast_2d(np.asarray(points_wobj_m, dtype=float))
    T = floor_under(mesh, p[0])
    pf = p @ T[:3, :3]
    moved = transformed(mesh, np.linalg.inv(T))
    return T, pf, section_loops(moved, float(np.median(pf[:, 2])))


def pick_wall(
    mesh: trimesh.Trimesh,
    point_m: np.ndarray,
    normal: np.ndarray | None = None,
    *,
    tool_radius_m: float,
    gap_m: float,
    height_above_floor_m: float,
    tool_reach_m: float | None = None,
) -> WallPick:
    """The wall through a picked point (work-object frame) and the machining height there.

    The point's height above the floor is kept when the cutter clears the floor there, the
    spindle the part's top and the cutter touches the wall below its top; otherwise the
    height changes, to ``height_above_floor_m`` above the floor or the nearest height that
    is clear, and a note says why (``_machining_height``). A point about as near two walls
    (within ``AMBIGUOUS_CLICK_RADII`` tool radii) is refused with both named.

    Args:
        mesh: The part in its work-object frame (the CAD: what the user sees).
        point_m: (3,) the picked point [m]; it must lie on (within 2 mm of) the surface.
        normal: (3,) the surface normal there (out of the material); default: the normal of
            the nearest face.
        tool_radius_m: Ball cutter radius.
        gap_m: Gap between the cutter and the wall where the tool stands.
        height_above_floor_m: The TCP's height above the floor where the point's own height
            cannot be kept.
        tool_reach_m: How deep the tool reaches below the spindle body (along the tool axis,
            the work object's z); None: no limit.

    Raises:
        InvalidInputError: the point is off the part, on a floor or a top, between two walls,
            the wall is too low for the cutter or too deep for the spindle, or no wall is
            found at the machining height.
    """
    p = np.asarray(point_m, dtype=float).reshape(3)
    if not np.all(np.isfinite(p)):
        raise InvalidInputError("the picked point must be 3 finite coordinates")
    lo, hi = mesh.bounds
    if np.any(p < lo - MAX_PICK_DISTANCE_M) or np.any(p > hi + MAX_PICK_DISTANCE_M):
        raise InvalidInputError(
            f"the point ({_mm(p)}) mm is off the part, which spans ({_mm(lo)}) to ({_mm(hi)}) mm "
            "in its work-object frame; pick a point on a wall"
        )
    closest, distance, triangle = closest_point(mesh, p[None, :])
    if len(distance) == 0 or float(distance[0]) > MAX_PICK_DISTANCE_M:
        raise InvalidInputError(
            f"the point ({_mm(p)}) mm is "
            f"{distance[0] * 1e3 if len(distance) else float('inf'):.1f} mm from the part's "
            "surface; pick a point on the wall (work-object frame, mm)"
        )
    if normal is None:
        n = np.asarray(mesh.face_normals[int(triangle[0])], dtype=float)
    else:
        n = unit_vector(np.asarray(normal, dtype=float).reshape(-1), "the surface normal")
    on = np.asarray(closest[0], dtype=float)
    T = floor_frame(mesh, on, n, tool_radius_m + gap_m)
    R = T[:3, :3]
    mf = transformed(mesh, np.linalg.inv(T))
    pf, onf, nf = p @ R, on @ R, n @ R
    if abs(nf[2]) >= WALL_FACE_MAX_COS:
        face = "a floor or a top" if nf[2] > 0 else "an overhang"
        raise InvalidInputError(
            f"the point ({_mm(p)}) mm is on {face} (its surface faces "
            f"{'up' if nf[2] > 0 else 'down'}); pick a point on a wall"
        )
    across = _across(nf, _Z)
    assert across is not None  # a face within WALL_FACE_MAX_COS of vertical leans off the floor
    near, other = float(distance[0]), _free_width(mf, pf, across)  # the wall across the space
    if other - near < AMBIGUOUS_CLICK_RADII * tool_radius_m:
        far = pf + across * other
        raise InvalidInputError(
            f"the point ({_mm(p)}) mm is between two walls: {near * 1e3:.1f} mm from the wall "
            f"at ({_mm(R @ onf)}) mm and {other * 1e3:.1f} mm from the wall at ({_mm(R @ far)}) "
            f"mm (the free space is {(near + other) * 1e3:.1f} mm wide there); pick a point on "
            "the wall to follow"
        )
    width = _free_width(mf, onf, across)
    beside = onf + across * min(tool_radius_m + gap_m, 0.5 * width)
    (floor_at, *_), _ = _below(mf, beside + _Z * RAY_START_M, _Z)
    floor = float(mf.bounds[0, 2]) if np.isnan(floor_at[2]) else float(floor_at[2])
    (top_at, *_), _ = _below(mf, onf - across * INSIDE_M + _Z * (mf.bounds[1, 2] + 0.01), _Z)
    top = onf[2] if np.isnan(top_at[2]) or top_at[2] < onf[2] - 1e-6 else float(top_at[2])
    tcp = np.array([beside[0], beside[1], pf[2]])
    spindle = _spindle_lowest(mf, tcp, R[2], tool_reach_m)
    z, note = _machining_height(
        float(pf[2]), floor, top, spindle, tool_radius_m, height_above_floor_m, p
    )
    loops = section_loops(mf, z)
    if not loops:
        raise InvalidInputError(f"no wall {(z - floor) * 1e3:.1f} mm above the floor there")
    xy = onf[:2]
    distances = [abs(lp.signed_distance(xy[None])[0]) for lp in loops]
    k = int(np.argmin(distances))
    if distances[k] > MAX_PICK_DISTANCE_M + tool_radius_m:
        raise InvalidInputError(
            f"the wall through ({_mm(p)}) mm does not reach down to the machining height "
            f"({(z - floor) * 1e3:.1f} mm above the floor); pick a wall that does"
        )
    loop = loops[k]
    s = float(loop.project(xy[None])[0])
    if float(loop.free_normal_at(np.array([s]))[0] @ across[:2]) < 0.0:
        raise InvalidInputError(
            f"the wall at ({_mm(p)}) mm faces the other way at the machining height; pick it "
            "where it is vertical"
        )
    others = tuple(lp for i, lp in enumerate(loops) if i != k)
    notes = (note,) if note else ()
    return WallPick(p, n, loop, s, float(z), floor, float(top), others, notes, T, mf)


def _spindle_lowest(
    mesh: trimesh.Trimesh, tcp: np.ndarray, up_tool: np.ndarray, reach_m: float | None
) -> float:
    """The lowest TCP height (floor frame, moving along the floor's normal) at which the
    spindle body, ``reach_m`` up the tool axis from the TCP, stays ``SPINDLE_CLEARANCE_M``
    above the part within its radius (rays down the tool axis); -inf without a reach."""
    if reach_m is None:
        return -math.inf
    from ..cell.supervision.supervisor import SPINDLE_RADIUS_M

    e1 = np.cross(up_tool, [1.0, 0.0, 0.0] if abs(up_tool[0]) < 0.9 else [0.0, 1.0, 0.0])
    e1 /= np.linalg.norm(e1)
    e2 = np.cross(up_tool, e1)
    angles = np.linspace(0.0, 2 * math.pi, SPINDLE_RING, endpoint=False)
    ring = np.outer(np.cos(angles), e1) + np.outer(np.sin(angles), e2)
    offsets = np.vstack([np.zeros(3), 0.5 * SPINDLE_RADIUS_M * ring, SPINDLE_RADIUS_M * ring])
    span = float(np.linalg.norm(np.ptp(mesh.bounds, axis=0))) + 0.01
    top, _ = _below(mesh, tcp + offsets + up_tool * (span + reach_m), up_tool, floors=False)
    rise = (top - tcp) @ up_tool
    if np.all(np.isnan(rise)):
        return -math.inf
    lift = float(np.nanmax(rise)) + SPINDLE_CLEARANCE_M - reach_m
    return float(tcp[2] + lift / max(float(up_tool[2]), 1e-3))


def _machining_height(
    z_m: float,
    floor_m: float,
    top_m: float,
    spindle_m: float,
    radius_m: float,
    fallback_m: float,
    point_m: np.ndarray,
) -> tuple[float, str]:
    """(TCP height, note): the point's own height ``z_m`` when the cutter clears the floor by
    ``CUTTER_FLOOR_CLEARANCE_M``, the spindle the part (``spindle_m``) and the TCP stays
    below the wall's top (``CONTACT_BELOW_TOP_*``); otherwise ``fallback_m`` above the floor
    brought into that range, with a note that says why (floor frame, metres)."""
    cutter = floor_m + radius_m + CUTTER_FLOOR_CLEARANCE_M
    low = max(cutter, spindle_m)
    high = top_m - max(CONTACT_BELOW_TOP_RADII * radius_m, CONTACT_BELOW_TOP_M)
    if low > high:
        if spindle_m > high:
            raise InvalidInputError(
                f"the wall at ({_mm(point_m)}) mm is too deep for the tool: the spindle "
                f"would meet the part round it before the cutter reached "
                f"{(top_m - floor_m) * 1e3:.1f} mm high wall (lower the wall's surroundings "
                "or use a longer tool)"
            )
        raise InvalidInputError(
            f"the wall at ({_mm(point_m)}) mm is {(top_m - floor_m) * 1e3:.1f} mm high, too "
            f"low for the {radius_m * 1e3:g} mm cutter above its floor"
        )
    if low - 1e-9 <= z_m <= high + 1e-9:
        return z_m, ""
    z = float(np.clip(floor_m + fallback_m, low, high))
    above = f"{(z_m - floor_m) * 1e3:.1f} mm above the floor"
    if z_m < cutter:
        why = (
            f"the point is {above}: the {radius_m * 1e3:g} mm cutter would not clear the "
            f"floor by {CUTTER_FLOOR_CLEARANCE_M * 1e3:g} mm there"
        )
    elif z_m < spindle_m:
        why = (
            f"the point is {above}: the spindle would come within "
            f"{SPINDLE_CLEARANCE_M * 1e3:g} mm of the part"
        )
    else:
        why = (
            f"the point is {above}, {(top_m - z_m) * 1e3:.1f} mm below the wall's top: the "
            "cutter would not touch the wall below its rim"
        )
    return z, f"{why}; the tool works {(z - floor_m) * 1e3:.1f} mm above the floor instead"


def _off_vertices(mesh: trimesh.Trimesh, z: float) -> float:
    """``z`` moved off any vertex height by a micrometre (a plane through vertices cuts
    faces edge-on)."""
    zs = np.asarray(mesh.vertices)[:, 2]
    while np.any(np.abs(zs - z) < 1e-7):
        z += 1e-6
    return z


def _mm(p: np.ndarray) -> str:
    return ", ".join(f"{v * 1e3:.1f}" for v in p)
