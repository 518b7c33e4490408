"""The mesh score measures in the part's own frame: the same distances as the mesh moved into
the base frame, for any work-object pose."""

from __future__ import annotations

import numpy as np
import trimesh
from scipy.spatial.transform import Rotation

from robomach_core.mesh_score import mesh_deviation
from robomach_core.workpiece import builtin_workpiece


def test_mesh_deviation_equals_the_distance_to_the_mesh_placed_in_the_base_frame():
    rng = np.random.default_rng(7)
    T = np.eye(4)
    T[:3, :3] = Rotation.from_euler("xyz", [12.0, -7.0, 35.0], degrees=True).as_matrix()
    T[:3, 3] = [0.61, -0.22, 0.05]
    wp = builtin_workpiece("water_pump").placed(T)
    placed = wp.mesh_in_base()
    pts = placed.bounds[0] + rng.random((300, 3)) * (placed.bounds[1] - placed.bounds[0])
    _, reference, _ = trimesh.proximity.closest_point(placed, pts)
    got = mesh_deviation(wp, 0.001, pts)
    np.testing.assert_allclose(got, np.abs(reference - 0.001), atol=1e-9)


def test_a_pickled_workpiece_still_measures_distances():
    """trimesh pickles its cached triangle tree empty; the workpiece leaves its caches behind."""
    import pickle

    wp = builtin_workpiece("water_pump")
    pts = np.array([[0.5, 0.5, 0.5], [0.0, 0.1, 0.02]])
    before = mesh_deviation(wp, 0.001, pts)  # builds and caches the tree
    copy = pickle.loads(pickle.dumps(wp))
    np.testing.assert_allclose(mesh_deviation(copy, 0.001, pts), before)
    assert copy.wall is not None and np.array_equal(copy.T_base_wobj, wp.T_base_wobj)
