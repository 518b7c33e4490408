"""Queries of a part's mesh that native libraries answer, one at a time.

PROBLEM   trimesh's nearest-point query walks an rtree (libspatialindex) and its ray queries an
          embree scene, both built once per mesh and cached on it; neither is safe to query
          from two threads at once. The workbench asks from several (the REST API's workers,
          the viser GUI, jobs): two guide-point checks at once crashed the server with a
          segmentation fault inside ``rtree.index.intersection_v``.
STRATEGY  One process-wide lock around those calls (each takes milliseconds); callers that run
          a longer check on a shared mesh may hold ``LOCK`` around it (it is re-entrant).
SOLUTION  ``closest_point(mesh, points)`` and ``ray_hits(mesh, origins, directions)``, the
          trimesh calls under ``LOCK``.
"""

from __future__ import annotations

import threading

import numpy as np
import trimesh

LOCK = threading.RLock()


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
