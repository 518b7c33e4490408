"""coal's geometry of a triangle mesh: its bounding-volume hierarchy (the part as contact,
clearance and the mesh checks query it) and its convex hull (the supervision obstacle)."""

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


def convex_hull_of(vertices: np.ndarray) -> coal.Convex:
    """coal's convex hull of ``vertices`` (n, 3), with its triangles: one qhull run gives the
    hull's corners (``points()``, the corners among ``vertices``) and its volume
    (``computeVolume()``). (trimesh's ``convex_hull`` first and coal's hull of its corners
    after ran qhull twice: 0.4 s more for an 80k-triangle part.)"""
    points = coal.StdVec_Vec3s()
    for p in np.asarray(vertices, dtype=float):
        points.append(p)
    return coal.Convex.convexHull(points, True, None)
