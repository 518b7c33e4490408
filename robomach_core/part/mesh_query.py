"""Queries of a part's mesh that native libraries answer, one at a time.

PROBLEM   The scores measure the program against the part's mesh point by point, so the
          nearest point must be exact, and fast for tens of thousands of points. trimesh's
          query (rtree candidates) missed the nearest face of points within a few tenths of a
          mm of the pump's wall, up to 26 um too far, and took 75-300 us a point. Its ray
          queries use a scene built once per mesh and cached on it, not safe to query from two
          threads at once: two guide-point checks at once crashed the server with a
          segmentation fault inside a native tree.
STRATEGY  Nearest points from libigl's AABB tree (``igl.AABB``: exact point-triangle
          distances, the same as every face tried in turn), one tree kept per mesh: about
          5 us a point. Rays stay trimesh's. One process-wide lock around the native calls
          (each takes milliseconds); callers that run a longer check on a shared mesh may hold
          ``LOCK`` around it (it is re-entrant).
SOLUTION  ``closest_point(mesh, points)`` and ``ray_hits(mesh, origins, directions)`` under
          ``LOCK``; ``transformed(mesh, T)``, a mesh in another frame kept per mesh and frame;
          ``wall_faces(mesh, axis)``, a part's walls for a tool axis as one submesh
          kept per mesh and axis, so that its trees are built once.
"""

from __future__ import annotations

import math
import threading
import weakref
from collections.abc import Callable, Hashable
from typing import Any

import igl
import numpy as np
import trimesh

LOCK = threading.RLock()
WALL_FACE_MAX_COS = math.cos(math.radians(45.0))  # |n . tool axis| below this: a wall face
_KEPT = 16  # entries a table below keeps (a full table starts again)
_WALLS: dict[tuple[int, tuple[float, ...]], tuple[weakref.ref, Any]] = {}  # wall submeshes
_TREES: dict[int, tuple[weakref.ref, Any]] = {}  # nearest-point trees
_MOVED: dict[tuple[int, tuple[float, ...]], tuple[weakref.ref, Any]] = {}  # meshes in a frame


def _kept(table: dict, key: Hashable, mesh: trimesh.Trimesh, build: Callable[[], Any]) -> Any:
    """``build()`` for ``mesh`` under ``key``, made once and kept while ``mesh`` lives (a dead
    mesh's id may come back for another: its entry is rebuilt). Call under ``LOCK``."""
    hit = table.get(key)
    if hit is not None and hit[0]() is mesh:
        return hit[1]
    value = build()
    for old in [k for k, (ref, _) in table.items() if ref() is None]:
        del table[old]  # a mesh that died (the cell changed): its trees go now, not later
    if len(table) >= _KEPT:
        table.clear()
    table[key] = (weakref.ref(mesh), value)
    return value


def wall_faces(mesh: trimesh.Trimesh, axis_wobj: np.ndarray) -> trimesh.Trimesh | None:
    """The faces of ``mesh`` that are walls for a tool along ``axis_wobj`` (|n . axis| below
    ``WALL_FACE_MAX_COS``) as one submesh, or None when there is none.

    Kept per mesh and axis (rounded to 1e-3): the submesh's triangle tree and ray scene are
    built on its first query, and a new submesh per call rebuilt them every time."""
    axis = np.asarray(axis_wobj, dtype=float)
    axis = axis / np.linalg.norm(axis)

    def build() -> trimesh.Trimesh | None:
        with np.errstate(divide="ignore", invalid="ignore"):
            keep = np.flatnonzero(np.abs(mesh.face_normals @ axis) < WALL_FACE_MAX_COS)
        # trimesh types submesh's result as a list too; append=True gives one Trimesh.
        return mesh.submesh([keep], append=True) if len(keep) else None  # type: ignore[return-value]

    with LOCK:
        return _kept(_WALLS, (id(mesh), tuple(np.round(axis, 3))), mesh, build)


def transformed(mesh: trimesh.Trimesh, T: np.ndarray) -> trimesh.Trimesh:
    """``mesh`` moved by the 4x4 ``T`` (itself when ``T`` is the identity), kept per mesh and
    ``T`` (rounded to 1e-9) so that its trees and ray scene are built once."""
    T = np.asarray(T, dtype=float)
    if np.allclose(T, np.eye(4), rtol=0.0, atol=1e-12):
        return mesh

    def build() -> trimesh.Trimesh:
        moved = mesh.copy()
        moved.apply_transform(T)
        return moved

    with LOCK:
        return _kept(_MOVED, (id(mesh), tuple(np.round(T, 9).ravel())), mesh, build)


def closest_point(
    mesh: trimesh.Trimesh, points: np.ndarray
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The nearest point of ``mesh`` to each of ``points`` (k, 3): (closest points (k, 3),
    distances (k,), triangle ids (k,)), as ``trimesh.proximity.closest_point`` returns them,
    exact (module docstring), locked."""
    pts = np.ascontiguousarray(np.asarray(points, dtype=float).reshape(-1, 3))
    with LOCK:
        V, F, tree = _tree(mesh)
        squared, triangle, closest = tree.squared_distance(V, F, pts)
    return closest, np.sqrt(np.maximum(squared, 0.0)), triangle.astype(np.int64)


def _tree(mesh: trimesh.Trimesh) -> tuple[np.ndarray, np.ndarray, igl.AABB]:
    """The mesh's vertices, faces and AABB tree, built on its first query and kept (a tree
    takes a few ms to build; a one-point query on a kept tree, microseconds)."""

    def build() -> tuple[np.ndarray, np.ndarray, igl.AABB]:
        V = np.ascontiguousarray(mesh.vertices, dtype=np.float64)
        F = np.ascontiguousarray(mesh.faces, dtype=np.int64)
        tree = igl.AABB()
        tree.init(V, F)
        return V, F, tree

    return _kept(_TREES, id(mesh), mesh, build)


def ray_hits(
    mesh: trimesh.Trimesh,
    origins: np.ndarray,
    directions: np.ndarray,
    *,
    multiple_hits: bool = True,
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """``mesh.ray.intersects_location`` (locations, ray ids, triangle ids), locked."""
    with LOCK:
        return mesh.ray.intersects_location(
            np.asarray(origins, dtype=float),
            np.asarray(directions, dtype=float),
            multiple_hits=multiple_hits,
        )
