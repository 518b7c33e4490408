"""The reference nearest distance to a mesh: every triangle tried in turn (Ericson's closest
point on a triangle, the contact kernel's), the smallest kept. Exact where tree queries may not
be: trimesh's missed the nearest face of points near the pump's wall by up to 26 um."""

from __future__ import annotations

import numba
import numpy as np

from robomach_core._kernels import _closest_on_triangle


@numba.njit(cache=True)
def distance_to_every_face(points: np.ndarray, triangles: np.ndarray) -> np.ndarray:
    """(k,) distance of each of ``points`` (k, 3) to the nearest of ``triangles`` (F, 3, 3)."""
    out = np.empty(len(points))
    for i in range(len(points)):
        px, py, pz = points[i, 0], points[i, 1], points[i, 2]
        best = np.inf
        for f in range(len(triangles)):
            cx, cy, cz = _closest_on_triangle(px, py, pz, triangles[f])
            best = min(best, (cx - px) ** 2 + (cy - py) ** 2 + (cz - pz) ** 2)
        out[i] = np.sqrt(best)
    return out
