"""Walls of a part's mesh at one height: the loop a picked point belongs to, and where the tool
goes beside it.

PROBLEM   Pointing at the part must give a wall to follow: the picked face alone says nothing
          about where the wall goes, which side is free, how deep the groove is, or where the
          tool may stand without touching the floor or the other wall of a narrow groove.
STRATEGY  Cut the mesh with the horizontal plane at the machining height (trimesh's
          ``mesh_plane``): each segment comes with the face it cuts, whose normal says which
          side is free, so every segment is oriented with the material on the right (as the
          built-in walls are) and chained into loops, closed or open. The picked point's
          face gives the free side; a ray down beside the wall finds the floor and one down
          just inside the wall its top, which fix the machining height.
SOLUTION  ``section_loops(mesh, z_m)`` -> ``WallLoop``s (work-object x-y, metres), with arc
          length, points, free-side normals and a signed distance (+ free side, - material);
          ``pick_wall(mesh, point, normal, ...)`` -> ``WallPick`` (the loop, the machining
          height, floor and top, the arc length of the pick).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from functools import cached_property

import numpy as np
import shapely
import trimesh
from scipy.sparse import coo_matrix
from scipy.sparse.csgraph import connected_components
from scipy.spatial import cKDTree

from ..errors import InvalidInputError
from ..mesh_query import closest_point, ray_hits

WALL_NORMAL_Z_MAX = 0.5  # a picked face whose normal has |z| above this is a floor or a top
MAX_PICK_DISTANCE_M = 0.002  # a picked point farther than this from the surface is refused
MERGE_M = 1e-9  # segment ends closer than this are one point of a loop
STITCH_M = 2e-5  # chains ending this close to each other are one wall across a crack
NORMAL_WINDOW_M = 5e-4  # the free-side normal is the mean over this much wall either side
TOOL_REACH_MARGIN_M = 0.005  # the spindle body stays this far above the part's top
DENSE_M = 2e-5  # wall points this far apart measure distances to it


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

    @cached_property
    def _line(self) -> shapely.LineString:
        return shapely.LineString(self._chain)

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
    def _dense(self) -> tuple[np.ndarray, cKDTree]:
        """Arc lengths every ``DENSE_M`` (and at every vertex) and a tree of their points."""
        n = max(2, int(math.ceil(self.length_m / DENSE_M)) + 1)
        s = np.unique(np.concatenate([np.linspace(0.0, self.length_m, n), self.cumulative_m]))
        if self.closed:
            s = s[s < self.length_m]
        return s, cKDTree(self.point_at(s))

    def project(self, points_xy: np.ndarray) -> np.ndarray:
        """(k,) arc length of the nearest wall point to each of (k, 2) points (to within
        ``DENSE_M`` / 2)."""
        s, tree = self._dense
        _, i = tree.query(np.atleast_2d(np.asarray(points_xy, dtype=float)))
        return s[i]

    def signed_distance(self, points_xy: np.ndarray) -> np.ndarray:
        """(k,) distance of (k, 2) points from the wall: positive on the free side, negative
        in the material (the side is the one of the chord over the nearest point). Measured
        to the nearest of points ``DENSE_M`` apart: 0.1 um too long at 0.5 mm."""
        xy = np.atleast_2d(np.asarray(points_xy, dtype=float))
        s_all, tree = self._dense
        distance, i = tree.query(xy)
        s = s_all[i]
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
    ends = np.vstack([a, b])
    pairs = cKDTree(ends).query_pairs(MERGE_M, output_type="ndarray")
    n = len(ends)
    graph = coo_matrix((np.ones(len(pairs)), (pairs[:, 0], pairs[:, 1])), shape=(n, n))
    _, ids = connected_components(graph, directed=False)
    start, stop = ids[: len(a)], ids[len(a) :]
    point = np.zeros((ids.max() + 1, 2))
    point[start], point[stop] = a, b
    moving = np.flatnonzero(start != stop)
    # The first segment leaving each point (reversed so the first one wins in the dict).
    successor = dict(zip(start[moving][::-1].tolist(), moving[::-1].tolist(), strict=True))
    incoming = set(stop.tolist())
    used = np.zeros(len(a), dtype=bool)
    loops: list[WallLoop] = []

    def walk(first: int) -> tuple[list[int], bool]:
        chain = [int(start[first])]
        i = first
        while True:
            used[i] = True
            v = int(stop[i])
            if v == chain[0]:
                return chain, True
            chain.append(v)
            i = successor.get(v, -1)
            if i < 0 or used[i]:
                return chain, False

    # Open chains first (from a point with no incoming segment), then the closed loops.
    for first in [i for i in range(len(a)) if int(start[i]) not in incoming]:
        if not used[first]:
            chain, closed = walk(first)
            loops.append(WallLoop(point[chain], float(z_m), closed))
    for first in range(len(a)):
        if not used[first]:
            chain, closed = walk(first)
            loops.append(WallLoop(point[chain], float(z_m), closed))
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
    """A wall picked at a point, at the machining height.

    Attributes:
        point_m: (3,) the picked point on the surface (work-object frame).
        normal: (3,) the surface normal there (out of the material).
        loop: The wall at the machining height.
        s_m: Arc length of the picked point along ``loop``.
        z_m: The machining height (TCP, work-object z).
        floor_z_m: The floor beside the wall (the part's bottom when it stands free).
        top_z_m: The top of the wall.
        others: Every other wall at that height (the groove's other side, islands).
        notes: What was adjusted, for people (e.g. the height raised for the spindle).
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


def _first_hit_below(mesh: trimesh.Trimesh, origin: np.ndarray) -> float | None:
    """z of the highest surface straight below ``origin`` (None: nothing below)."""
    hits, _, _ = ray_hits(mesh, np.asarray([origin]), np.array([[0.0, 0.0, -1.0]]))
    below = [h[2] for h in hits if h[2] < origin[2] - 1e-7]
    return max(below) if below else None


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
    """The wall through a picked point (work-object frame) and the machining height beside it.

    Args:
        mesh: The part in its work-object frame (the CAD: what the user sees).
        point_m: (3,) the picked point [m]; it must lie on (within 2 mm of) the surface.
        normal: (3,) the surface normal there (out of the material); default: the normal of
            the nearest face.
        tool_radius_m: Ball cutter radius.
        gap_m: Gap between the cutter and the wall where the tool stands.
        height_above_floor_m: The TCP's height above the floor beside the wall.
        tool_reach_m: How deep the tool reaches below the spindle body (the height is raised
            so that the body stays above the part's top); None: no limit.

    Raises:
        InvalidInputError: the point is off the part, on a floor or a top, the wall is too
            low for the cutter, or no wall is found at the machining height.
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
        n = np.asarray(normal, dtype=float).reshape(3)
        if not (np.all(np.isfinite(n)) and np.linalg.norm(n) > 1e-9):
            raise InvalidInputError("the surface normal must be 3 finite numbers, not all zero")
        n = n / np.linalg.norm(n)
    if abs(n[2]) > WALL_NORMAL_Z_MAX:
        face = "a floor or a top" if n[2] > 0 else "an overhang"
        raise InvalidInputError(
            f"the point ({_mm(p)}) mm is on {face} (its surface faces "
            f"{'up' if n[2] > 0 else 'down'}); pick a point on a wall"
        )
    n_xy = n[:2] / np.linalg.norm(n[:2])
    on = np.asarray(closest[0], dtype=float)
    # The floor beside the wall: straight down from where the tool will stand, or from the
    # middle of a free space narrower than that (a narrow slot).
    across = np.array([n_xy[0], n_xy[1], 0.0])
    hits, _, _ = ray_hits(mesh, (on + across * 2e-5)[None], across[None], multiple_hits=False)
    width = float(np.linalg.norm(hits[0] - on)) if len(hits) else np.inf
    beside = on + across * min(tool_radius_m + gap_m, 0.5 * width)
    bottom = float(mesh.bounds[0, 2])
    floor = _first_hit_below(mesh, beside + np.array([0.0, 0.0, 1e-6]))
    floor = bottom if floor is None else floor
    inside = on.copy()
    inside[:2] -= n_xy * 3e-4
    top = _first_hit_below(mesh, np.array([inside[0], inside[1], mesh.bounds[1, 2] + 0.01]))
    top = on[2] if top is None or top < on[2] - 1e-6 else top
    notes: list[str] = []
    z = floor + height_above_floor_m
    if tool_reach_m is not None:
        lowest = float(mesh.bounds[1, 2]) - tool_reach_m + TOOL_REACH_MARGIN_M
        if z < lowest:
            z = lowest
            notes.append(
                f"the machining height is {(z - floor) * 1e3:.1f} mm above the floor, so that "
                "the spindle stays above the part"
            )
    if z > top - max(tool_radius_m * 0.5, 5e-4):
        z = 0.5 * (floor + top)
        notes.append(f"the wall is {(top - floor) * 1e3:.1f} mm high: the tool works at its middle")
    if z < floor + tool_radius_m + 2e-4 or z > top:
        raise InvalidInputError(
            f"the wall at ({_mm(p)}) mm is {(top - floor) * 1e3:.1f} mm high, too low for the "
            f"{tool_radius_m * 1e3:g} mm cutter above its floor"
        )
    loops = section_loops(mesh, z)
    if not loops:
        raise InvalidInputError(f"no wall at {z * 1e3:.1f} mm (work-object z)")
    xy = on[:2]
    distances = [abs(lp.signed_distance(xy[None])[0]) for lp in loops]
    k = int(np.argmin(distances))
    if distances[k] > MAX_PICK_DISTANCE_M + tool_radius_m:
        raise InvalidInputError(
            f"the wall through ({_mm(p)}) mm does not reach down to the machining height "
            f"({z * 1e3:.1f} mm); pick a wall that does"
        )
    loop = loops[k]
    s = float(loop.project(xy[None])[0])
    if float(loop.free_normal_at(np.array([s]))[0] @ n_xy) < 0.0:
        raise InvalidInputError(
            f"the wall at ({_mm(p)}) mm faces the other way at the machining height; pick it "
            "where it is vertical"
        )
    others = tuple(lp for i, lp in enumerate(loops) if i != k)
    return WallPick(p, n, loop, s, float(z), float(floor), float(top), others, tuple(notes))


def _off_vertices(mesh: trimesh.Trimesh, z: float) -> float:
    """``z`` moved off any vertex height by a micrometre (a plane through vertices cuts
    faces edge-on)."""
    zs = np.asarray(mesh.vertices)[:, 2]
    while np.any(np.abs(zs - z) < 1e-7):
        z += 1e-6
    return z


def _mm(p: np.ndarray) -> str:
    return ", ".join(f"{v * 1e3:.1f}" for v in p)
