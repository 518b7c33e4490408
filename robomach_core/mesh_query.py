"""Queries of a part's mesh that native libraries answer, one at a time.

PROBLEM   trimesh's nearest-point query walks an rtree (libspatialindex) and its ray queries an
          embree scene, both built once per mesh and cached on it; neither is safe to query
          from two threads at once. The workbench asks from several (the REST API's workers,
          the viser GUI, jobs): two guide-point checks at once crashed the server with a
          segmentation fault inside ``rtree.index.intersection_v``.
STRATEGY  One process-wide lock around those calls (each takes milliseconds); callers that run
          a longer check on a shared mesh may hold ``LOCK`` around it (it is re-entrant).
SOLUTION  ``closest_point(mesh, points)`` and ``ray_hits(mesh, origins, directions)``, the
          trimesh calls under ``LOCK``; ``wall_faces(mesh, axis)``, a part's walls for a tool
          axis as one submesh kept per mesh and axis, so that its trees are built once.
"""

from __future__ import annotations

import math
import threading
import weakref

import numpy as np
import trimesh

LOCK = threading.RLock()
WALL_FACE_MAX_COS = math.cos(math.radians(45.0))  # |n . tool axis| below this: a wall face
_WALLS_KEPT = 16  # (mesh, axis) pairs whose wall submesh is kept
_WALLS: dict[tuple[int, tuple[float, ...]], tuple[weakref.ref, trimesh.Trimesh | None]] = {}


def wall_faces(mesh: trimesh.Trimesh, axis_wobj: np.ndarray) -> trimesh.Trimesh | None:
    """The faces of ``mesh`` that are walls for a tool along ``axis_wobj`` (|n . axis| below
    ``WALL_FACE_MAX_COS``) as one submesh, or None when there is none.

    Kept per mesh and axis (rounded to 1e-3): the submesh's triangle tree and ray scene are
    built on its first query, and a new submesh per call rebuilt them every time."""
    axis = np.asarray(axis_wobj, dtype=float)
    axis = axis / np.linalg.norm(axis)
    key = (id(mesh), tuple(np.round(axis, 3)))
    with LOCK:
        hit = _WALLS.get(key)
        if hit is not None and hit[0]() is mesh:
            return hit[1]
        with np.errstate(divide="ignore", invalid="ignore"):
            keep = np.flatnonzero(np.abs(mesh.face_normals @ axis) < WALL_FACE_MAX_COS)
        walls = mesh.submesh([keep], append=True) if len(keep) else None
        if len(_WALLS) >= _WALLS_KEPT:
            _WALLS.clear()
        _WALLS[key] = (weakref.ref(mesh), walls)
        return walls


def closest_point(
    mesh: trimesh.Trimesh, points: np.ndarray
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """``trimesh.proximity.closest_point`` (closest points, distances, triangle ids), locked."""
    with LOCK, np.errstate(divide="ignore", invalid="ignore"):
        return trimesh.proximity.closest_point(mesh, np.asarray(points, dtype=float))


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
