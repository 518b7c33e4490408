"""The part's walls for one tool axis, as path learning asks about them: the nearest wall point,
the wall a guide point faces on its side, the floor under a point, the gaps either side.

PROBLEM   "Is this point at that wall" must have one answer for the route's side, its start,
          the walk and the taught-wall check, on level, tilted and stepped floors, beside
          corners and ends of bosses (docs/learning_model.md, "the taught wall").
STRATEGY  The mesh's wall faces for the tool axis (``mesh_query.wall_faces``) and the whole
          mesh, in the base frame through the work object: closest points with their faces'
          normals, rays cast along the floor under a point, and the floor found by a ray down
          the axis (past a wall that leans over the tool).
SOLUTION  ``PartWalls(workpiece, axis, tool_radius_m)``: ``nearest``, ``wall_point``,
          ``gaps``, ``floor``, ``along_floor``, ``faces_from_free_side``.
"""

from __future__ import annotations

import math

import numpy as np

from ..part import Workpiece, mesh_query
from . import thresholds as th


class PartWalls:
    """The part's walls for one tool axis (the CAD, in the base frame): the nearest wall point
    on a side, the floor under a point. The one answer to "is this point at that wall"."""

    def __init__(self, workpiece: Workpiece, axis: np.ndarray, tool_radius_m: float) -> None:
        T = workpiece.T_base_wobj
        self.R, self.t = T[:3, :3], T[:3, 3]
        self.axis, self.radius = axis, tool_radius_m
        self.mesh = workpiece.mesh
        self.walls = mesh_query.wall_faces(self.mesh, self.R.T @ axis)
        self._normals = np.asarray(self.mesh.face_normals)  # trimesh checks its cache per read
        self._wall_normals = (
            np.zeros((0, 3)) if self.walls is None else np.asarray(self.walls.face_normals)
        )
        self._corners = np.asarray(self.mesh.vertices)[np.asarray(self.mesh.faces)[:, 0]]
        self._ray = self.mesh.ray

    def nearest(self, points: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Nearest wall points (k, 3) and their distances (k,) [m] to ``points`` (k, 3)."""
        closest, dist, _ = self._closest(points)
        return closest, dist

    def _closest(self, points: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """``nearest`` and the unit normals (k, 3) of the wall faces the points lie on (base
        frame; zero where no walls)."""
        k = len(points)
        if self.walls is None:
            return np.full((k, 3), np.nan), np.full(k, np.inf), np.zeros((k, 3))
        with np.errstate(divide="ignore", invalid="ignore"):
            c, d, tri = mesh_query.closest_point(self.walls, (points - self.t) @ self.R)
        normals = self._wall_normals[tri] @ self.R.T
        return c @ self.R.T + self.t, np.asarray(d, dtype=float), normals

    def feet(self, points: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """``nearest``, and whether each nearest wall point is the foot on a wall face (the way
        to it within ``FOOT_ON_FACE_COS`` of the face's normal): a wall standing at the
        point's height, not the edge of one below it (a floor step's riser) nor a corner's."""
        closest, dist, normals = self._closest(points)
        way = closest - points
        with np.errstate(invalid="ignore"):  # no walls: NaN, never on a face
            on_face = -np.einsum("ij,ij->i", way, normals) >= th.FOOT_ON_FACE_COS * np.linalg.norm(
                way, axis=1
            )
        return closest, dist, on_face

    def inside(self, point: np.ndarray) -> bool:
        """Whether ``point`` (base frame) is inside the part's mesh: its generalised winding
        number (libigl's, exact) over one half, the point taken into the mesh's frame."""
        import igl

        vertices = np.asarray(self.mesh.vertices, dtype=np.float64)
        faces = np.asarray(self.mesh.faces, dtype=np.int64)
        local = ((np.asarray(point, dtype=float) - self.t) @ self.R)[None]
        return bool(igl.winding_number(vertices, faces, local)[0] > 0.5)

    def faces_from_free_side(self, point: np.ndarray, direction: np.ndarray, reach: float) -> bool:
        """True when the first wall along ``direction`` from ``point`` is within ``reach`` and
        met from its free side: ``point`` stands in the free space beside a wall."""
        if self.walls is None:
            return False
        with mesh_query.LOCK:
            tri = self.walls.ray.intersects_first(
                ((point - self.t) @ self.R)[None], (self.R.T @ direction)[None]
            )[0]
        if tri < 0:
            return False
        n = self.R @ self._wall_normals[tri]
        corner = self.R @ self.walls.vertices[self.walls.faces[tri, 0]] + self.t
        along = float(n @ (corner - point)) / float(n @ direction)
        return float(n @ direction) < 0.0 and 0.0 <= along <= reach

    def risers(self, points: np.ndarray, towards: np.ndarray) -> np.ndarray:
        """Whether the wall at each of ``points`` (k, 3), on walls met looking ``towards``, is
        a step in the floor the route climbs rather than a wall it follows: a floor stands on
        it within the cutter's reach above the point (``floor``, a radius past the face), and
        from just over that floor a wall still stands ``towards`` within ``AT_WALL_GAP_M`` of
        the cutter. The height reference's rule for a floor above the cutter
        (``HeightReference.at``), so a riser beside a guide point is never taken for its
        taught wall (a riser across the groove 1 mm behind a first point, met by a ray of the
        fan before the wall 4 mm across, was learned and passed as the taught wall)."""
        points = np.asarray(points, dtype=float).reshape(-1, 3)
        out = np.zeros(len(points), dtype=bool)
        if self.walls is None or not len(points):
            return out
        _, _, normals = self._closest(points)
        beyond = points - normals * self.radius
        height, _ = self.floor(beyond)
        a = self.axis
        reach = self.radius + th.AT_WALL_GAP_M
        for k in np.flatnonzero(np.isfinite(height) & (height < points @ a)):
            above = beyond[k] + a * (height[k] - float(beyond[k] @ a) - th.FLOOR_ABOVE_M)
            out[k] = self.faces_from_free_side(above, towards, reach)
        return out

    def along_floor(self, point: np.ndarray, directions: np.ndarray) -> np.ndarray:
        """``directions`` (3,) or (k, 3), across the axis, turned into the plane of the floor
        under ``point`` (one floor for all): the way the cutter moves there. On a tilted floor a
        ray straight across the axis leaves the groove through its floor, under the walls it
        was cast at; unchanged where no floor is below."""
        _, normal = self.floor(point[None])
        n = normal[0]
        cos = float(n @ self.axis)
        if abs(cos) < th.WALL_FACE_MAX_COS:  # no floor (zero normal)
            return directions
        tilted = directions - np.multiply.outer(directions @ n / cos, self.axis)
        return tilted / np.linalg.norm(tilted, axis=-1, keepdims=True)

    def across_ray(self, point: np.ndarray, direction: np.ndarray) -> float:
        """Distance [m] from ``point`` to the first wall along ``direction`` (inf: none)."""
        if self.walls is None:
            return math.inf
        hits, _, _ = mesh_query.ray_hits(
            self.walls, ((point - self.t) @ self.R)[None], (self.R.T @ direction)[None]
        )
        if not len(hits):
            return math.inf
        return float(np.min(np.linalg.norm(hits @ self.R.T + self.t - point, axis=1)))

    def gaps(self, points: np.ndarray, right: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """The cutter's gaps [m] to the nearest wall on the right and on the left of each
        point (``right``: (k, 3) the right of travel at each); inf where none is in reach."""
        closest, dist = self.nearest(points)
        r_gap, l_gap = np.full(len(points), np.inf), np.full(len(points), np.inf)
        for k, p in enumerate(points):
            if not math.isfinite(dist[k]):
                continue
            rel = closest[k] - p
            rel = rel - self.axis * float(rel @ self.axis)
            on_right = float(rel @ right[k]) > 0.0
            gap = float(dist[k]) - self.radius
            (r_gap if on_right else l_gap)[k] = gap
            # the wall across: straight away from the nearest one (across a groove, its width)
            away = -rel / max(float(np.linalg.norm(rel)), 1e-12)
            other = self.across_ray(p, away) - self.radius
            (l_gap if on_right else r_gap)[k] = max(other, gap)
        return r_gap, l_gap

    def wall_point(
        self, point: np.ndarray, towards: np.ndarray, reach_m: float, facing_cos: float = 0.0
    ) -> np.ndarray | None:
        """The wall point a point at ``point`` faces in direction ``towards`` (across the
        axis): its nearest wall point when that lies that way, else the first wall along it
        facing back across it by more than ``facing_cos`` (``_first_wall_that_way``); None
        when none is within ``reach_m``."""
        (closest,), (dist,), (on_face,) = self.feet(point[None])
        within = False
        if math.isfinite(dist):
            rel3 = closest - point
            rel = rel3 - self.axis * float(rel3 @ self.axis)
            within = float(np.linalg.norm(rel)) > 1e-9 and dist <= reach_m
            # the nearest wall when it lies that way (within the fan's angle); else the first
            # wall that way
            that_way = math.cos(th.FAN_HALF_ANGLE_RAD) * float(np.linalg.norm(rel))
            if within and on_face and self.risers(closest[None], towards)[0]:
                within = False  # a step the route climbs, not a wall it follows
            if within and on_face and float(rel @ towards) > that_way:
                return closest
        hit, d = self._first_wall_that_way(point, towards, facing_cos)
        if d <= reach_m:
            return hit
        # no wall within reach that way (a leg cutting across a concave stretch, or through
        # the part, turns "that way" off the wall): the wall face the point stands by; not a
        # corner's edge, which may be another wall's (a part off its mesh: the run then
        # searches by force)
        return closest if within and on_face else None

    def _first_wall_that_way(
        self, point: np.ndarray, towards: np.ndarray, facing_cos: float = 0.0
    ) -> tuple[np.ndarray, float]:
        """The nearest wall point met by a fan of rays within ``FAN_HALF_ANGLE_RAD`` of
        ``towards``, each along the floor, on a wall facing back across ``towards`` (its
        normal's component against it over ``facing_cos``), and its distance [m] (inf: none).
        One ray straight that way misses the wall where the travel is a chord round a corner
        (an open route's first point: the way to the next point, round the corner, turns
        "that way" along the groove)."""
        if self.walls is None:
            return np.full(3, np.nan), math.inf
        side = np.cross(self.axis, towards)
        angles = np.linspace(-th.FAN_HALF_ANGLE_RAD, th.FAN_HALF_ANGLE_RAD, th.FAN_RAYS)
        fan = self.along_floor(
            point, np.cos(angles)[:, None] * towards + np.sin(angles)[:, None] * side
        )
        hits, _, tri = mesh_query.ray_hits(
            self.walls, np.repeat(((point - self.t) @ self.R)[None], len(fan), 0), fan @ self.R
        )
        # a wall on that side faces back across it: the wall across the groove, met by a ray
        # swung towards it, faces the other way (``taught_wall_points`` asks more where the
        # way is the walk's, exact)
        normals = self._wall_normals[tri] @ self.R.T
        hits = hits[normals @ towards < -facing_cos] @ self.R.T + self.t
        hits = hits[~self.risers(hits, towards)]
        if not len(hits):
            return np.full(3, np.nan), math.inf
        d = np.linalg.norm(hits - point, axis=1)
        k = int(np.argmin(d))
        return hits[k], float(d[k])

    def floor(self, points: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """The floor below each point (k, 3): its height along the axis [m] (nan where no
        floor lies within ``FLOOR_SEARCH_M`` below the cutter) and its unit normal (k, 3). A
        ray each, from ``FLOOR_ABOVE_M`` above the cutter; where its first face is a wall (a
        wall leaning over the tool, met from inside), once more from just past it."""
        a = self.axis
        a_w = self.R.T @ a
        up = self.radius + th.FLOOR_ABOVE_M
        origins = (np.asarray(points, dtype=float) - a * up - self.t) @ self.R
        height = np.full(len(origins), np.nan)
        normal = np.zeros((len(origins), 3))
        start = np.zeros(len(origins))  # how far along each ray it was cast from
        todo = np.arange(len(origins))
        for _ in range(2):
            with mesh_query.LOCK:
                tri = self._ray.intersects_first(
                    origins[todo], np.broadcast_to(a_w, (len(todo), 3))
                )
            n_w = self._normals[tri]
            cos = -(n_w @ a_w)
            with np.errstate(divide="ignore", invalid="ignore"):
                along = np.einsum("ij,ij->i", n_w, self._corners[tri] - origins[todo]) / -cos
            hit = (tri >= 0) & (start[todo] + along <= up + self.radius + th.FLOOR_SEARCH_M)
            floor = hit & (cos >= th.WALL_FACE_MAX_COS)
            k = todo[floor]
            height[k] = (origins[k] + np.outer(along[floor], a_w)) @ a_w + self.t @ a
            normal[k] = n_w[floor] @ self.R.T
            again = hit & ~floor  # a wall first: look on from just past it
            step = along[again] + 1e-6
            origins[todo[again]] += np.outer(step, a_w)
            start[todo[again]] += step
            todo = todo[again]
            if not len(todo):
                break
        return height, normal
