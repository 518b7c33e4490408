"""Parts generated for the tests of teaching by pointing: meshes in mm, as a user uploads them.

Each maker returns the mesh (mm, its origin at the work object) and, per wall the tests pick,
a point on it (mm, work-object frame) and a shapely outline of that wall (mm) to score against.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
import shapely.geometry
import trimesh


@dataclass(frozen=True)
class GeneratedPart:
    """A generated part.

    Attributes:
        name: File stem.
        mesh: The mesh in mm.
        picks: Wall name -> a point on that wall (mm, work-object frame).
        walls: Wall name -> its outline in x-y (mm): the ring or line the tool must follow.
        open_walls: Names of the walls that end (learned open).
    """

    name: str
    mesh: trimesh.Trimesh
    picks: dict[str, tuple[float, float, float]]
    walls: dict[str, shapely.geometry.base.BaseGeometry]
    open_walls: tuple[str, ...] = ()

    def stl_bytes(self) -> bytes:
        return self.mesh.export(file_type="stl")


def _extrude(polygon: shapely.geometry.Polygon, z0: float, height: float) -> trimesh.Trimesh:
    mesh = trimesh.creation.extrude_polygon(polygon, height)
    mesh.apply_translation([0.0, 0.0, z0])
    return mesh


def grooved_plate() -> GeneratedPart:
    """A 160 x 110 x 20 mm plate with a 6 mm wide, 6 mm deep groove round a rounded
    rectangle (outer wall 110 x 70 mm, 10 mm corner radius): two walls, outer and island."""
    outer = shapely.geometry.box(-55, -35, 55, 35).buffer(0).buffer(-10).buffer(10, quad_segs=24)
    island = outer.buffer(-6, quad_segs=24)
    plate = shapely.geometry.box(-80, -55, 80, 55)
    mesh = trimesh.util.concatenate(
        [
            trimesh.creation.box(extents=(160, 110, 14), transform=_at(0, 0, 7)),
            _extrude(plate.difference(outer), 14, 6),
            _extrude(island, 14, 6),
        ]
    )
    return GeneratedPart(
        "grooved_plate",
        mesh,
        picks={"outer": (0.0, -35.0, 17.0), "island": (0.0, -29.0, 18.0)},
        walls={"outer": outer.exterior, "island": island.exterior},
    )


def cam_plate() -> GeneratedPart:
    """A 300 x 180 x 20 mm plate with a 6 mm wide, 6 mm deep groove round a cam: a rounded
    rectangle 220 x 110 mm (25 mm corner radius) with a 30 mm lobe on one long side; two walls,
    outer and island. Its cell holds it turned: placed at (790, 150, 0) mm, 25 deg about z."""
    body = shapely.geometry.box(-110, -55, 110, 55).buffer(-25).buffer(25, quad_segs=24)
    lobe = shapely.geometry.Point(40, 55).buffer(30, quad_segs=24)
    outer = body.union(lobe).buffer(-8).buffer(8, quad_segs=24)
    island = outer.buffer(-6, quad_segs=24)
    plate = shapely.geometry.box(-150, -90, 150, 90)
    mesh = trimesh.util.concatenate(
        [
            trimesh.creation.box(extents=(300, 180, 14), transform=_at(0, 0, 7)),
            _extrude(plate.difference(outer), 14, 6),
            _extrude(island, 14, 6),
        ]
    )
    return GeneratedPart(
        "cam_plate",
        mesh,
        picks={"outer": (0.0, -55.0, 17.0), "island": (0.0, -49.0, 18.0)},
        walls={"outer": outer.exterior, "island": island.exterior},
    )


def l_block() -> GeneratedPart:
    """An L-shaped block, 100 x 70 x 30 mm with a 50 x 35 mm notch: sharp outside corners and
    one inside corner, on the table (an outside edge: no floor but the table)."""
    outline = shapely.geometry.Polygon([(-50, -35), (50, -35), (50, 0), (0, 0), (0, 35), (-50, 35)])
    return GeneratedPart(
        "l_block",
        _extrude(outline, 0, 30),
        picks={"outline": (20.0, -35.0, 20.0)},
        walls={"outline": outline.exterior},
    )


def slotted_plate() -> GeneratedPart:
    """A 160 x 80 x 20 mm plate with an open-ended... closed-ended straight-and-bent slot,
    8 mm wide, 6 mm deep, round ends: one side wall is an open wall."""
    centre = shapely.geometry.LineString([(-55, -10), (0, -10), (40, 15)])
    slot = centre.buffer(4, quad_segs=24)
    plate = shapely.geometry.box(-80, -40, 80, 40)
    mesh = trimesh.util.concatenate(
        [
            trimesh.creation.box(extents=(160, 80, 14), transform=_at(0, 0, 7)),
            _extrude(plate.difference(slot), 14, 6),
        ]
    )
    right = centre.offset_curve(-4)  # the side on the right of travel along the centre line
    return GeneratedPart(
        "slotted_plate",
        mesh,
        picks={"right side": (-30.0, -14.0, 17.0)},
        walls={"right side": right},
        open_walls=("right side",),
    )


def _at(x: float, y: float, z: float) -> np.ndarray:
    T = np.eye(4)
    T[:3, 3] = (x, y, z)
    return T


PARTS = {"grooved_plate": grooved_plate, "l_block": l_block, "slotted_plate": slotted_plate}


# --- parts drawn from a seed: tilted and stepped plates (SI units, for property tests) ---------


@dataclass(frozen=True)
class DrawnPlate:
    """A plate drawn from a seed, metres, for the planner's properties.

    Attributes:
        mesh: The part in its mesh (work-object) frame; tilted when ``T_mesh_plate`` is.
        T_mesh_plate: 4x4 the plate's own frame (level, its bottom at z = 0) in the mesh.
        walls: Wall name -> its outline in the plate's x-y plane (metres).
        floor_z: (x, y) in the plate frame -> the floor's height under it there (the plate's
            bottom beside an outside edge).
        top_z_m: The walls' top (plate frame).
        kind: "groove" (round an island: walls "outer" and "island"), "stepped" (the same,
            the groove's floor a step higher for x < 0) or "edge" (an outside edge: "outline").
        width_m: The groove's width (inf for an edge).
    """

    mesh: trimesh.Trimesh
    T_mesh_plate: np.ndarray
    walls: dict[str, shapely.geometry.base.BaseGeometry]
    floor_z: object
    top_z_m: float
    kind: str
    width_m: float

    def pick(self, wall: str, along: float, height_m: float) -> tuple[np.ndarray, np.ndarray]:
        """(point, normal) in the mesh frame: on ``wall`` at ``along`` (0-1 of its length),
        ``height_m`` above the floor beside it; the normal out of the material."""
        line = self.walls[wall]
        s = min(along * line.length, line.length - 2e-5)
        p = np.array(line.interpolate(s).coords[0])
        t = np.array(line.interpolate(s + 1e-5).coords[0]) - p
        t /= np.linalg.norm(t)
        free = np.array([-t[1], t[0]])
        inward = shapely.contains_xy(shapely.Polygon(line), *(p + free * 1e-4))
        free = free if inward == (wall == "outer") else -free  # the groove: inside the outer
        beside = p + free * 1e-3
        z = self.floor_z(*beside) + height_m
        R, o = self.T_mesh_plate[:3, :3], self.T_mesh_plate[:3, 3]
        return R @ [p[0], p[1], z] + o, R @ [free[0], free[1], 0.0]

    def in_plate(self, points_mesh: np.ndarray) -> np.ndarray:
        """(k, 3) mesh-frame points in the plate frame."""
        R, o = self.T_mesh_plate[:3, :3], self.T_mesh_plate[:3, 3]
        return (np.atleast_2d(points_mesh) - o) @ R


def drawn_plate(
    seed: int, kind: str, tilt_deg: float = 0.0, *, width_m: float | None = None
) -> DrawnPlate:
    """A plate drawn from ``seed``: a rounded rectangle 60-130 x 40-80 mm (corners 4-12 mm),
    as a 5-8 mm wide (or ``width_m``), 6 mm deep groove round an island in a 20 mm plate,
    the same with the groove's floor 2 mm higher for x < 0, or standing free 12-20 mm thick
    (its outside edge); tilted ``tilt_deg`` about a horizontal axis drawn from the seed."""
    rng = np.random.default_rng(seed)
    a, b, r = rng.uniform(0.030, 0.065), rng.uniform(0.020, 0.040), rng.uniform(0.004, 0.012)
    outer = shapely.geometry.box(-a, -b, a, b).buffer(-r).buffer(r, quad_segs=16)
    if kind == "edge":
        thick = rng.uniform(0.012, 0.020)
        mesh = _extrude(outer, 0.0, thick)
        walls = {"outline": outer.exterior}
        floor, top, width = (lambda x, y: 0.0), thick, math.inf
    else:
        width = rng.uniform(0.005, 0.008) if width_m is None else width_m
        island = outer.buffer(-width, quad_segs=16)
        plate = shapely.geometry.box(-a - 0.02, -b - 0.02, a + 0.02, b + 0.02)
        base = _at(0.0, 0.0, 0.006)
        parts = [
            trimesh.creation.box(extents=(2 * a + 0.04, 2 * b + 0.04, 0.012), transform=base),
            _extrude(plate.difference(outer), 0.012, 0.008),
            _extrude(island, 0.012, 0.008),
        ]  # fmt: skip
        step = 0.002 if kind == "stepped" else 0.0
        if kind == "stepped":
            ring = outer.difference(island).intersection(
                shapely.geometry.box(-a - 1, -b - 1, 0, b + 1)
            )
            parts.append(_extrude(ring, 0.012, step))
        else:  # the groove's floor at 14 mm, as the grooved plate's
            parts.append(_extrude(outer.difference(island), 0.012, 0.002))
        from robomach_core.part.workpiece import solid_mesh

        mesh = solid_mesh(trimesh.util.concatenate(parts))
        walls = {"outer": outer.exterior, "island": island.exterior}
        floor = (
            (lambda x, y: 0.014) if kind == "groove" else (lambda x, y: 0.014 if x < 0 else 0.012)
        )
        top = 0.020
    T = np.eye(4)
    if tilt_deg:
        axis_angle = rng.uniform(0.0, 2 * math.pi)
        axis = np.array([math.cos(axis_angle), math.sin(axis_angle), 0.0])
        T[:3, :3] = trimesh.transformations.rotation_matrix(math.radians(tilt_deg), axis)[:3, :3]
        T[2, 3] = -(mesh.vertices @ T[:3, :3].T)[:, 2].min()  # standing on the table
        mesh = mesh.copy()
        mesh.apply_transform(T)
    return DrawnPlate(mesh, T, walls, floor, top, kind, width)
