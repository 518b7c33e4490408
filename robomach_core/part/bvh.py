"""coal's bounding-volume hierarchy of a triangle mesh: the part as contact, clearance and the
mesh checks query it."""

from __future__ import annotations

import coal
import numpy as np


def bvh_from_mesh(vertices: np.ndarray, faces: np.ndarray) -> coal.BVHModelOBBRSS:
    """A coal BVH of the triangles ``faces`` (indices into ``vertices``), in their order, with
    only the vertices they use."""
    used, local = np.unique(faces, return_inverse=True)
    bvh = coal.BVHModelOBBRSS()
    bvh.beginModel(len(faces), len(used))
    bvh.addVertices(np.ascontiguousarray(vertices[used], dtype=float))
    bvh.addTriangles(np.ascontiguousarray(local.reshape(-1, 3), dtype=np.int32))
    bvh.endModel()
    return bvh
