"""A built-in open contour: an S-shaped slot in a plate (the cam-groove case of issue 11).

The slot is 6 mm wide and 6 mm deep; its centre line runs along x, bends left round a 20 mm
radius, right round another, and runs along x again. The taught wall is the slot's right-hand
side (material on the right of travel, as for the pump); it ends where the slot ends, so a
closed path-learning run would add a leg back to the start across the slot, cutting into the
other wall: learn it with ``closed=False`` (``robomach demo --workpiece s_groove --open``).
"""

from __future__ import annotations

import math

import numpy as np
import shapely.geometry
import trimesh

from ..transforms import make_transform
from .contour import Arc, Contour, Line

S_GROOVE_PLATE_SIZE_M = (0.180, 0.110, 0.020)
S_GROOVE_WIDTH_M = 0.006
S_GROOVE_DEPTH_M = 0.006
S_GROOVE_BEND_RADIUS_M = 0.020
S_GROOVE_SPACING_M = 0.0004  # facet length of the walls in the mesh


def s_groove_centre_line() -> Contour:
    """Centre line of the slot (wobj x-y plane): line, left bend, right bend, line."""
    r = S_GROOVE_BEND_RADIUS_M
    return Contour(
        (
            Line((-0.070, -r), (-0.030, -r)),
            Arc((-0.030, 0.0), r, -math.pi / 2, math.pi / 2),  # left, ends at (-0.01, 0) going +y
            Arc((0.010, 0.0), r, math.pi, -math.pi / 2),  # right, ends at (0.01, r) going +x
            Line((0.010, r), (0.050, r)),
        ),
        closed=False,
    )


def s_groove_wall() -> Contour:
    """The taught wall: the slot's right-hand side, travelled with the material on its right."""
    return s_groove_centre_line().offset(-S_GROOVE_WIDTH_M / 2)


def s_groove_mesh() -> trimesh.Trimesh:
    """The cast-iron plate with the open S-slot, wobj frame (the plate's base at z = 0): a
    block below the slot's floor and the extruded rim around the slot."""
    sx, sy, sz = S_GROOVE_PLATE_SIZE_M
    floor_z = sz - S_GROOVE_DEPTH_M
    centre = s_groove_centre_line().sample(S_GROOVE_SPACING_M)
    slot = shapely.geometry.LineString(centre).buffer(
        S_GROOVE_WIDTH_M / 2, cap_style="flat", quad_segs=32
    )
    rim = shapely.geometry.box(-sx / 2, -sy / 2, sx / 2, sy / 2).difference(slot)
    top = trimesh.creation.extrude_polygon(rim, S_GROOVE_DEPTH_M)
    top.apply_translation([0.0, 0.0, floor_z])
    base = trimesh.creation.box(
        extents=(sx, sy, floor_z),
        transform=make_transform(np.eye(3), np.array([0.0, 0.0, floor_z / 2])),
    )
    # trimesh types concatenate's result as any Geometry; of meshes it is a Trimesh.
    return trimesh.util.concatenate([base, top])  # type: ignore[return-value]
