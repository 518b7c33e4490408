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


def convex_hull_of(vertices: np.ndarray) -> tuple[coal.Convex, np.ndarray, float]:
    """coal's convex hull of ``vertices`` (n, 3), its corners (m, 3) and its volume: qhull
    (trimesh's ``convex_hull``) finds the corners, and coal's hull is built from them without
    its triangles. (coal's own hull of every vertex with its triangles kept refuses a
    casting's: "Too many neighbors", a corner with over 255 neighbours.)"""
    import trimesh

    hull_mesh = trimesh.convex.convex_hull(np.asarray(vertices, dtype=float))
    corners = np.asarray(hull_mesh.vertices, dtype=float)
    points = coal.StdVec_Vec3s()
    for p in corners:
        points.append(p)
    return coal.Convex.convexHull(points, False, None), corners, float(hull_mesh.volume)
