"""Parts generated for the tests of teaching by pointing: meshes in mm, as a user uploads them.

Each maker returns the mesh (mm, its origin at the work object) and, per wall the tests pick,
a point on it (mm, work-object frame) and a shapely outline of that wall (mm) to score against.
"""

from __future__ import annotations

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
