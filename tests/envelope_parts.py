"""Parts for the learning envelope (issue 28), each with the true walls the tests score against.

A part is made in its own frame (mm): level, its walls vertical, each wall a dense polyline
travelled with the material on the right, with the floor under it and its top. It reaches the
cell in one of three ways:

- built in (``water_pump``, ``block``, ``s_groove``): the product's own part, its walls from the
  same geometry the product builds its mesh from;
- uploaded level (``T_wobj_part`` the identity), as a user uploads an STL;
- tilted 10-20 deg, either inside the mesh on a level work object (the job's tool axis is
  vertical) or level in the mesh on a tilted work object (``CellSettings.wobj_mm_deg`` with
  rx, ry: the tool is normal to the plate).

The scoring is independent of the product's: a program point is taken into the part's frame,
where the wall is a vertical extrusion of its polyline between the floor and the top, so its
distance to the wall is exact whatever the tilt.
"""

from __future__ import annotations

import io
import math
from dataclasses import dataclass, field, replace
from functools import cached_property
from typing import Literal

import numpy as np
import shapely
import shapely.geometry
import trimesh
from scipy.spatial import cKDTree
from scipy.spatial.transform import Rotation

from robomach_core.cell import Cell, CellConfig
from robomach_core.part import Workpiece, default_T_base_wobj, mesh_from_bytes
from robomach_core.project import CellSettings
from robomach_core.project._stages import build_cell_workpiece

WALL_SPACING_MM = 0.05  # the true walls' polylines, dense enough that a vertex is the foot
PLATE_MM = (160.0, 110.0)  # the generated plates' footprint
FLOOR_MM, TOP_MM = 14.0, 20.0  # their grooves' floor and top

ToolAxis = Literal["vertical", "normal"]


@dataclass(frozen=True)
class TrueWall:
    """One wall of a part, in the part's own frame (mm).

    Attributes:
        xy_mm: (n, 2) dense polyline, the material on the right of travel (closed: the last
            vertex joins the first).
        closed: A loop (True) or a wall that ends.
        floor_mm: (n,) the floor beside the wall at each vertex (the lowest the cutter rests).
        top_mm: The wall's top.
        free_mm: Width of the groove in front of the wall (None: open space, an outside edge).
        other: The wall across the groove, if any.
    """

    xy_mm: np.ndarray
    closed: bool
    floor_mm: np.ndarray
    top_mm: float
    free_mm: float | None = None
    other: str | None = None

    @property
    def length_mm(self) -> float:
        return float(self.cumulative_mm[-1])

    @cached_property
    def cumulative_mm(self) -> np.ndarray:
        """(n + 1,) arc length at each vertex, closing vertex included for a loop."""
        chain = np.vstack([self.xy_mm, self.xy_mm[:1]]) if self.closed else self.xy_mm
        return np.concatenate([[0.0], np.cumsum(np.linalg.norm(np.diff(chain, axis=0), axis=1))])

    def at(self, s_mm: float) -> tuple[np.ndarray, np.ndarray, float]:
        """Point, unit tangent and floor at arc length ``s_mm`` (wrapped on a loop)."""
        cum = self.cumulative_mm
        s = s_mm % cum[-1] if self.closed else min(max(s_mm, 0.0), cum[-1])
        i = int(np.clip(np.searchsorted(cum, s, side="right") - 1, 0, len(cum) - 2))
        a = self.xy_mm[i]
        b = self.xy_mm[(i + 1) % len(self.xy_mm)]
        t = (b - a) / np.linalg.norm(b - a)
        return a + t * (s - cum[i]), t, float(self.floor_mm[i])

    @cached_property
    def free_normals(self) -> np.ndarray:
        """(n, 2) unit normal at each vertex towards the free side (the left of travel)."""
        xy = self.xy_mm
        nxt = np.roll(xy, -1, axis=0) if self.closed else np.vstack([xy[1:], 2 * xy[-1] - xy[-2]])
        prv = np.roll(xy, 1, axis=0) if self.closed else np.vstack([2 * xy[0] - xy[1], xy[:-1]])
        t_out = _unit(nxt - xy)
        t_in = _unit(xy - prv)
        n = np.column_stack([-(t_in + t_out)[:, 1], (t_in + t_out)[:, 0]])
        return _unit(n)

    @cached_property
    def _tree(self) -> cKDTree:
        return cKDTree(self.xy_mm)

    def signed_distance(self, p_mm: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Distance (mm) of part-frame points (n, 3) from the wall surface, positive on the
        free side, and the index of the nearest vertex. Above the top or below the floor the
        distance runs to the wall's edge."""
        p = np.atleast_2d(p_mm)
        d_xy, i = self._tree.query(p[:, :2])
        side = np.sign(np.einsum("ij,ij->i", p[:, :2] - self.xy_mm[i], self.free_normals[i]))
        side[side == 0] = 1.0
        dz = np.maximum(0.0, np.maximum(self.floor_mm[i] - p[:, 2], p[:, 2] - self.top_mm))
        return side * np.hypot(d_xy, dz), i

    def stretch(self, span_mm: tuple[float, float] | None, margin_mm: float = 0.0) -> np.ndarray:
        """Indices of the vertices from arc length ``span_mm[0]`` to ``span_mm[1]`` along
        travel, ``margin_mm`` in from each end (wrapping on a loop); None: the whole wall."""
        cum = self.cumulative_mm[:-1] if self.closed else self.cumulative_mm
        if span_mm is None:
            return np.arange(len(self.xy_mm))
        s0, s1 = span_mm[0] + margin_mm, span_mm[1] - margin_mm
        if self.closed:
            rel = (cum - s0) % self.length_mm
            return np.flatnonzero(rel <= (s1 - s0) % self.length_mm)
        return np.flatnonzero((cum >= s0) & (cum <= s1))

    def nearest(self, xy_mm: np.ndarray) -> np.ndarray:
        """Index of the nearest vertex for each (n, 2) point."""
        return self._tree.query(np.atleast_2d(xy_mm))[1]

    def project(self, xy_mm: np.ndarray) -> np.ndarray:
        """Arc length of the nearest vertex for each (n, 2) point."""
        return self.cumulative_mm[self.nearest(xy_mm)]


@dataclass(frozen=True)
class EnvelopePart:
    """A part, its placement in the cell and its true walls.

    Attributes:
        name: File stem (uploaded) or built-in name.
        walls: Wall name -> true wall (part frame, mm).
        builtin: The built-in workpiece's name, or None for an uploaded mesh.
        mesh_mm: The mesh as uploaded (work-object frame, mm), None when built in.
        T_wobj_part: 4x4 (mm) the part's own frame in the work object: a tilt inside the mesh.
        wobj_mm_deg: The cell's work-object setting (x, y, z, rx, ry, rz) or None (default).
        tool_axis: The job's tool axis: "vertical" (base -z) or "normal" (to the plate).
        open_walls: Names of the walls that end.
        description: One line for failure messages.
    """

    name: str
    walls: dict[str, TrueWall]
    builtin: str | None = None
    mesh_mm: trimesh.Trimesh | None = None
    T_wobj_part: np.ndarray = field(default_factory=lambda: np.eye(4))
    wobj_mm_deg: tuple[float, ...] | None = None
    tool_axis: ToolAxis = "vertical"
    description: str = ""

    @property
    def open_walls(self) -> tuple[str, ...]:
        return tuple(name for name, wall in self.walls.items() if not wall.closed)

    def cell_settings(self, seed: int, robot: str = "ur10") -> CellSettings:
        if self.builtin is not None:
            return CellSettings(robot=robot, workpiece=self.builtin, seed=seed)
        return CellSettings(
            robot=robot,
            workpiece=self.name,
            workpiece_builtin=False,
            seed=seed,
            wobj_mm_deg=self.wobj_mm_deg,
        )

    def mesh_file(self) -> tuple[str, bytes] | None:
        """(filename, STL bytes) as the project holds an upload; None when built in."""
        if self.mesh_mm is None:
            return None
        return f"{self.name}.stl", self._stl

    @cached_property
    def _stl(self) -> bytes:
        mesh = self.mesh_mm.copy()
        mesh.apply_transform(self.T_wobj_part)
        return mesh.export(file_type="stl")

    @cached_property
    def _parsed(self) -> Workpiece | None:
        """The uploaded mesh read once (``mesh_from_bytes``: a process of its own per read);
        each cell places it, as the workbench places an upload it has read (``parsed``)."""
        if self.mesh_mm is None:
            return None
        return mesh_from_bytes(self._stl, ".stl", name=self.name)

    def workpiece(self, seed: int = 0, robot: str = "ur10") -> Workpiece:
        """The part the cell's contact meets, built the project's way."""
        return build_cell_workpiece(
            self.cell_settings(seed, robot), self.mesh_file(), parsed=self._parsed
        )

    def cell(self, seed: int, robot: str = "ur10") -> Cell:
        return Cell(CellConfig(robot=robot, workpiece=self.workpiece(seed, robot), seed=seed))

    def R_base_part(self, workpiece: Workpiece) -> np.ndarray:
        return workpiece.T_base_wobj[:3, :3] @ self.T_wobj_part[:3, :3]

    def to_part_mm(self, workpiece: Workpiece, points_base_m: np.ndarray) -> np.ndarray:
        """(n, 3) base-frame points [m] in the part's frame [mm]."""
        T = workpiece.T_base_wobj
        wobj_mm = (np.atleast_2d(points_base_m) - T[:3, 3]) @ T[:3, :3] * 1e3
        return (wobj_mm - self.T_wobj_part[:3, 3]) @ self.T_wobj_part[:3, :3]

    def to_base_m(self, workpiece: Workpiece, points_part_mm: np.ndarray) -> np.ndarray:
        """(n, 3) part-frame points [mm] in the base frame [m]."""
        wobj_mm = (
            np.atleast_2d(points_part_mm) @ self.T_wobj_part[:3, :3].T + self.T_wobj_part[:3, 3]
        )
        T = workpiece.T_base_wobj
        return wobj_mm * 1e-3 @ T[:3, :3].T + T[:3, 3]

    def tool_down(self, workpiece: Workpiece) -> np.ndarray:
        """(3,) the job's tool axis in the base frame (pointing into the part)."""
        if self.tool_axis == "vertical":
            return np.array([0.0, 0.0, -1.0])
        return -self.R_base_part(workpiece)[:, 2]

    def pick_wobj_mm(self, wall: str, s_mm: float | None = None) -> np.ndarray:
        """A point on ``wall`` at mid-height (work-object frame, mm): where a user points."""
        w = self.walls[wall]
        c, _, floor = w.at(w.length_mm * 0.3 if s_mm is None else s_mm)
        p = np.array([c[0], c[1], 0.5 * (floor + w.top_mm)])
        return self.T_wobj_part[:3, :3] @ p + self.T_wobj_part[:3, 3]


# --- walls from outlines ----------------------------------------------------------------------


def _unit(v: np.ndarray) -> np.ndarray:
    return v / np.maximum(np.linalg.norm(v, axis=-1, keepdims=True), 1e-12)


def _dense(coords: np.ndarray, closed: bool) -> np.ndarray:
    geom = shapely.LinearRing(coords) if closed else shapely.LineString(coords)
    xy = np.asarray(shapely.segmentize(geom, WALL_SPACING_MM).coords)
    return xy[:-1] if closed else xy


def ring_wall(
    ring: shapely.geometry.LinearRing | np.ndarray,
    *,
    material_inside: bool,
    floor_mm: float | object,
    top_mm: float,
    free_mm: float | None = None,
    other: str | None = None,
) -> TrueWall:
    """A loop wall from an outline: material inside (a boss, an island) is travelled clockwise,
    material outside (a groove's outer wall) anticlockwise. ``floor_mm``: a height, or a
    function of (n, 2) points giving the floor under each."""
    coords = np.asarray(getattr(ring, "coords", ring), dtype=float)
    if np.allclose(coords[0], coords[-1]):
        coords = coords[:-1]
    if shapely.LinearRing(coords).is_ccw == material_inside:
        coords = coords[::-1]
    xy = _dense(coords, closed=True)
    return TrueWall(xy, True, _floor(floor_mm, xy), top_mm, free_mm, other)


def line_wall(
    line: shapely.geometry.LineString,
    *,
    material_right: bool,
    floor_mm: float,
    top_mm: float,
    free_mm: float | None = None,
    other: str | None = None,
) -> TrueWall:
    """An open wall along ``line``, reversed when its material is on the left."""
    coords = np.asarray(line.coords, dtype=float)
    xy = _dense(coords if material_right else coords[::-1], closed=False)
    return TrueWall(xy, False, _floor(floor_mm, xy), top_mm, free_mm, other)


def _floor(floor_mm: float | object, xy: np.ndarray) -> np.ndarray:
    if callable(floor_mm):
        return np.asarray(floor_mm(xy), dtype=float)
    return np.full(len(xy), float(floor_mm))


# --- meshes ----------------------------------------------------------------------------------


def _extrude(polygon: shapely.geometry.base.BaseGeometry, z0: float, z1: float) -> trimesh.Trimesh:
    polys = getattr(polygon, "geoms", [polygon])
    parts = []
    for poly in polys:
        mesh = trimesh.creation.extrude_polygon(poly, z1 - z0)
        mesh.apply_translation([0.0, 0.0, z0])
        parts.append(mesh)
    return trimesh.util.concatenate(parts)


def _solid(*bodies: trimesh.Trimesh) -> trimesh.Trimesh:
    return trimesh.boolean.union(list(bodies), engine="manifold")


def _plate() -> shapely.geometry.Polygon:
    sx, sy = PLATE_MM
    return shapely.geometry.box(-sx / 2, -sy / 2, sx / 2, sy / 2)


def _rounded_rect(w: float, h: float, r: float) -> shapely.geometry.Polygon:
    return shapely.geometry.box(-w / 2, -h / 2, w / 2, h / 2).buffer(-r).buffer(r, quad_segs=32)


def _groove_part(
    name: str,
    outer: shapely.geometry.Polygon,
    width_mm: float,
    *,
    floor: float | object = FLOOR_MM,
    base: trimesh.Trimesh | None = None,
    description: str = "",
) -> EnvelopePart:
    """A plate with a groove ``width_mm`` wide round an island: walls "outer" and "island"."""
    island = outer.buffer(-width_mm, quad_segs=32)
    base = base if base is not None else _extrude(_plate(), 0.0, FLOOR_MM)
    rim = _plate().difference(outer)
    mesh = _solid(base, _extrude(rim, 0.0, TOP_MM), _extrude(island, 0.0, TOP_MM))
    walls = {
        "outer": ring_wall(
            outer.exterior, material_inside=False, floor_mm=floor, top_mm=TOP_MM,
            free_mm=width_mm, other="island",
        ),
        "island": ring_wall(
            island.exterior, material_inside=True, floor_mm=floor, top_mm=TOP_MM,
            free_mm=width_mm, other="outer",
        ),
    }  # fmt: skip
    return EnvelopePart(name, walls, mesh_mm=mesh, description=description)


# --- the parts -------------------------------------------------------------------------------


def water_pump() -> EnvelopePart:
    """The built-in pump: its groove's outer wall (the taught one of the example) and island."""
    from robomach_core.part import water_pump_wall
    from robomach_core.part.workpiece import PUMP_GROOVE_WIDTH_M, PUMP_WALL_SPACING_M

    outer = shapely.geometry.Polygon(water_pump_wall().sample(PUMP_WALL_SPACING_M) * 1e3)
    island = outer.buffer(-PUMP_GROOVE_WIDTH_M * 1e3, join_style="round", quad_segs=16)
    w = PUMP_GROOVE_WIDTH_M * 1e3
    walls = {
        "outer": ring_wall(
            water_pump_wall().sample(0.0001) * 1e3, material_inside=False, floor_mm=14.0,
            top_mm=20.0, free_mm=w, other="island",
        ),
        "island": ring_wall(
            island.exterior, material_inside=True, floor_mm=14.0, top_mm=20.0, free_mm=w,
            other="outer",
        ),
    }  # fmt: skip
    return EnvelopePart("water_pump", walls, builtin="water_pump", description="built-in pump")


def block() -> EnvelopePart:
    """The built-in 150 x 50 x 40 mm block: an outside edge on the table (its mesh is a box
    with sharp edges: the wall the tool meets)."""
    outline = shapely.geometry.box(-75.0, -25.0, 75.0, 25.0).exterior
    walls = {"outline": ring_wall(outline, material_inside=True, floor_mm=0.0, top_mm=40.0)}
    return EnvelopePart("block", walls, builtin="block", description="built-in block")


def s_groove() -> EnvelopePart:
    """The built-in open S-slot (flat ends): its right side (the taught wall) and left side."""
    from robomach_core.part.s_groove import S_GROOVE_WIDTH_M, s_groove_centre_line

    centre = shapely.geometry.LineString(s_groove_centre_line().sample(0.0001) * 1e3)
    half = S_GROOVE_WIDTH_M * 1e3 / 2
    walls = {
        "right side": line_wall(
            centre.offset_curve(-half), material_right=True, floor_mm=14.0, top_mm=20.0,
            free_mm=2 * half, other="left side",
        ),
        "left side": line_wall(
            centre.offset_curve(half), material_right=False, floor_mm=14.0, top_mm=20.0,
            free_mm=2 * half, other="right side",
        ),
    }  # fmt: skip
    return EnvelopePart("s_groove", walls, builtin="s_groove", description="built-in S-slot")


def t_boss() -> EnvelopePart:
    """The uploaded T-shaped boss of tests/sloppy_guides.py: six sharp outside corners."""
    from tests.sloppy_guides import cornered_boss_stl

    data, outline = cornered_boss_stl()
    mesh = trimesh.load(io.BytesIO(data), file_type="stl", force="mesh")
    walls = {
        "boss": ring_wall(
            outline.sample(0.0001) * 1e3, material_inside=True, floor_mm=10.0, top_mm=18.0
        )
    }
    return EnvelopePart("tboss", walls, mesh_mm=mesh, description="uploaded T-boss")


def grooved_plate(width_mm: float = 6.0) -> EnvelopePart:
    """A level plate, a groove round a rounded 110 x 70 mm island (the tilted plate's shape)."""
    return _groove_part(
        "grooved_plate", _rounded_rect(110, 70, 10), width_mm,
        description=f"uploaded plate, {width_mm:g} mm groove round an island",
    )  # fmt: skip


def boss_plate() -> EnvelopePart:
    """A level plate with an L-shaped boss 6 mm high: five sharp outside corners and one
    inside corner filleted at 3 mm (an outside edge with the plate as its floor)."""
    outline = shapely.geometry.Polygon(
        [(-45, -25), (45, -25), (45, 0), (10, 0), (10, 25), (-45, 25)]
    )
    boss = outline.buffer(3, quad_segs=32).buffer(-3, join_style="mitre")
    mesh = _solid(_extrude(_plate(), 0.0, FLOOR_MM), _extrude(boss, FLOOR_MM - 1.0, TOP_MM))
    walls = {
        "boss": ring_wall(boss.exterior, material_inside=True, floor_mm=FLOOR_MM, top_mm=TOP_MM)
    }
    return EnvelopePart("boss_plate", walls, mesh_mm=mesh, description="uploaded L-boss plate")


def stepped_groove(steps_mm: tuple[float, float, float] = (12.0, 14.0, 16.0)) -> EnvelopePart:
    """A groove round an island whose floor steps up along x: ``steps_mm`` for x below -25,
    between -25 and 25, and above 25 mm (2 mm risers across the groove)."""
    sx, sy = PLATE_MM
    edges = (-sx / 2, -25.0, 25.0, sx / 2)
    base = _solid(
        *(
            _extrude(shapely.geometry.box(x0, -sy / 2, x1, sy / 2), 0.0, z)
            for x0, x1, z in zip(edges[:-1], edges[1:], steps_mm, strict=True)
        )
    )

    def floor(xy: np.ndarray) -> np.ndarray:
        return np.select([xy[:, 0] < edges[1], xy[:, 0] < edges[2]], steps_mm[:2], steps_mm[2])

    part = _groove_part(
        "stepped_groove", _rounded_rect(110, 70, 10), 6.0, floor=floor, base=base,
        description=f"uploaded groove, floor stepping {steps_mm} mm along x",
    )  # fmt: skip
    return part


def s_slot(width_mm: float = 6.0) -> EnvelopePart:
    """An S-shaped slot running out of the plate at both ends: two open walls."""
    t = np.linspace(-1.0, 1.0, 801)
    centre = shapely.geometry.LineString(
        np.column_stack([t * (PLATE_MM[0] / 2 + 5), 25.0 * np.sin(t * math.pi)])
    )
    slot = centre.buffer(width_mm / 2, cap_style="flat", quad_segs=32)
    mesh = _solid(
        _extrude(_plate(), 0.0, FLOOR_MM), _extrude(_plate().difference(slot), FLOOR_MM - 1, TOP_MM)
    )
    inside = shapely.geometry.box(-PLATE_MM[0] / 2, -60, PLATE_MM[0] / 2, 60)
    half = width_mm / 2
    walls = {
        "right side": line_wall(
            centre.offset_curve(-half).intersection(inside), material_right=True,
            floor_mm=FLOOR_MM, top_mm=TOP_MM, free_mm=width_mm, other="left side",
        ),
        "left side": line_wall(
            centre.offset_curve(half).intersection(inside), material_right=False,
            floor_mm=FLOOR_MM, top_mm=TOP_MM, free_mm=width_mm, other="right side",
        ),
    }  # fmt: skip
    return EnvelopePart("s_slot", walls, mesh_mm=mesh, description="uploaded S-slot, open ends")


def narrow_groove(width_mm: float = 3.5) -> EnvelopePart:
    """A groove only ``width_mm`` wide round a rounded 100 x 60 mm island."""
    part = _groove_part(
        "narrow_groove", _rounded_rect(100, 60, 8), width_mm,
        description=f"uploaded {width_mm:g} mm groove",
    )  # fmt: skip
    return part


def cam_groove(width_mm: float = 4.0) -> EnvelopePart:
    """A groove ``width_mm`` wide round a cam: a 28 mm base circle with a lobe rising 14 mm."""
    theta = np.linspace(0.0, 2 * math.pi, 360, endpoint=False)
    radius = 28.0 + 14.0 * np.maximum(0.0, np.cos(theta)) ** 3
    cam = shapely.geometry.Polygon(
        np.column_stack([np.cos(theta), np.sin(theta)]) * radius[:, None]
    )
    return _groove_part(
        "cam_groove", cam.buffer(width_mm, quad_segs=32), width_mm,
        description=f"uploaded {width_mm:g} mm cam groove",
    )  # fmt: skip


# --- tilting ---------------------------------------------------------------------------------


def tilted(
    part: EnvelopePart,
    tilt_deg: float,
    azimuth_deg: float,
    how: Literal["mesh", "wobj"],
    robot: str = "ur10",
) -> EnvelopePart:
    """``part`` (an uploaded level one) tilted ``tilt_deg`` about the horizontal axis at
    ``azimuth_deg``: inside the mesh on a level work object (tool vertical), or level in the
    mesh on a tilted work object (tool normal to the plate). Either way its lowest corner rests
    on the table."""
    axis = np.array([math.cos(math.radians(azimuth_deg)), math.sin(math.radians(azimuth_deg)), 0])
    R = Rotation.from_rotvec(axis * math.radians(tilt_deg))
    lift = -float((part.mesh_mm.vertices @ R.as_matrix().T)[:, 2].min())
    name = f"{part.name}_tilt{tilt_deg:.0f}_{how}"
    what = (
        f"{part.description}, tilted {tilt_deg:.1f} deg about {azimuth_deg:.0f} deg "
        f"{'in the mesh, tool vertical' if how == 'mesh' else 'by the work object, tool normal'}"
    )
    if how == "mesh":
        T = np.eye(4)
        T[:3, :3] = R.as_matrix()
        T[2, 3] = lift
        return replace(part, name=name, T_wobj_part=T, tool_axis="vertical", description=what)
    x, y, z = default_T_base_wobj(robot)[:3, 3] * 1e3
    rx, ry, rz = R.as_euler("xyz", degrees=True)
    return replace(
        part,
        name=name,
        wobj_mm_deg=(x, y, z + lift, rx, ry, rz),
        tool_axis="normal",
        description=what,
    )


PARTS = {
    "water_pump": water_pump,
    "block": block,
    "s_groove": s_groove,
    "tboss": t_boss,
    "grooved_plate": grooved_plate,
    "boss_plate": boss_plate,
    "stepped_groove": stepped_groove,
    "s_slot": s_slot,
    "narrow_groove": narrow_groove,
    "cam_groove": cam_groove,
}
