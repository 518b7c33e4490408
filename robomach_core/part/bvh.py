"""coal's geometry of a triangle mesh: its bounding-volume hierarchy (the part as contact,
clearance and the mesh checks query it) and its convex hull (the supervision obstacle).

The hull's corners are found by qhull once per part: ``convex_hull_of`` (run by the isolated
mesh check, ``isolation``) remembers which of the part's vertices they are, by a digest of
those vertices (``memo``), and ``placed_convex_hull`` (the supervisor, at every cell change)
takes them from there, placed, instead of running qhull on the same vertices again: 0.4 s of
an 80k-triangle upload's cell.
"""

from __future__ import annotations

import coal
import numpy as np

from .memo import Memo, digest

# Corner indices of the last few parts' hulls (int64: 0.3 MB for a hull of 40k corners).
HULL_MEMO = Memo(max_entries=8, max_bytes=16 << 20)
_MIN_HULL_CORNERS = 4  # a hull that holds volume


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
    casting's: "Too many neighbors", a corner with over 255 neighbours.) Which vertices the
    corners are is remembered (``hull_corner_indices``)."""
    corners, volume_m3, _ = _qhull_corners(np.asarray(vertices, dtype=float))
    return _coal_hull(corners), corners, volume_m3


def placed_convex_hull(vertices: np.ndarray, placed: np.ndarray) -> tuple[coal.Convex, np.ndarray]:
    """coal's convex hull of ``placed`` and its corners (m, 3), as ``convex_hull_of`` builds
    them, where ``placed`` (n, 3) are the rows of ``vertices`` (n, 3) moved by one rigid
    transform: qhull's corners are those it finds among ``vertices`` (remembered, so that a
    part checked or placed before needs no qhull), taken from ``placed``. A rigid motion
    keeps which points are corners, to rounding: a point within 2e-16 m of a hull face may
    count as a corner in one frame only (a casting tilted by 1 deg had six), so the hull is
    the one qhull finds on ``placed`` to 1e-15 m, and no longer depends on the placement."""
    v = np.asarray(vertices, dtype=float)
    p = np.asarray(placed, dtype=float)
    if v.shape != p.shape:
        raise ValueError(f"placed vertices {p.shape} do not match the vertices {v.shape}")
    indices = hull_corner_indices(v)
    if indices is None:
        indices = _qhull_corners(v)[2]
        if indices is None:  # trimesh gave other points than the input's: take its own hull
            hull, placed_corners, _ = convex_hull_of(p)
            return hull, placed_corners
    corners = p[indices]
    return _coal_hull(corners), corners


def hull_corner_indices(vertices: np.ndarray) -> np.ndarray | None:
    """Which rows of ``vertices`` are the corners of their hull, in ``convex_hull_of``'s
    order, when remembered (shape (m,), read-only), else None."""
    return HULL_MEMO.get(_vertices_key(vertices))


def remember_hull_corners(vertices: np.ndarray, indices: np.ndarray) -> bool:
    """Remember ``indices`` (m,) as the rows of ``vertices`` that are their hull's corners
    (another process's answer: ``workpiece.mesh_from_bytes``); False when they cannot be
    (not a vector of row indices, fewer than four)."""
    n = len(vertices)
    idx = np.asarray(indices)
    if idx.ndim != 1 or idx.dtype.kind not in "iu" or len(idx) < _MIN_HULL_CORNERS:
        return False
    if idx.min() < 0 or idx.max() >= n:
        return False
    kept = np.array(idx, dtype=np.int64)
    kept.flags.writeable = False
    HULL_MEMO.put(_vertices_key(vertices), kept, kept.nbytes)
    return True


def _vertices_key(vertices: np.ndarray) -> bytes:
    return digest("hull corners", np.asarray(vertices, dtype=float))


def _qhull_corners(vertices: np.ndarray) -> tuple[np.ndarray, float, np.ndarray | None]:
    """qhull's corners (m, 3) of ``vertices`` (trimesh's ``convex_hull``), the hull's volume
    and which rows of ``vertices`` the corners are (remembered; None when one is not)."""
    import trimesh

    hull_mesh = trimesh.convex.convex_hull(vertices)
    corners = np.asarray(hull_mesh.vertices, dtype=float)
    indices = _row_indices(corners, vertices)
    if indices is not None:
        remember_hull_corners(vertices, indices)
    return corners, float(hull_mesh.volume), indices


def _coal_hull(corners: np.ndarray) -> coal.Convex:
    points = coal.StdVec_Vec3s()
    for p in corners:
        points.append(p)
    return coal.Convex.convexHull(points, False, None)


def _row_indices(rows: np.ndarray, vertices: np.ndarray) -> np.ndarray | None:
    """The index in ``vertices`` (n, 3) of each of ``rows`` (m, 3), which are copies of some
    of them (the first of equal vertices); None when one is not."""
    v = np.ascontiguousarray(vertices, dtype=float)
    r = np.ascontiguousarray(rows, dtype=float)
    if len(v) == 0 or r.ndim != 2 or r.shape[1:] != v.shape[1:]:
        return None
    row = np.dtype((np.void, v.dtype.itemsize * v.shape[1]))
    keys, wanted = v.view(row).ravel(), r.view(row).ravel()
    order = np.argsort(keys, kind="stable")
    at = np.minimum(np.searchsorted(keys[order], wanted), len(order) - 1)
    found = order[at]
    return found if bool(np.all(keys[found] == wanted)) else None
