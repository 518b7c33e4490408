"""The mesh score: signed against the part's walls, measured in the part's own frame (the same
as the mesh moved into the base frame, for any work-object pose)."""

from __future__ import annotations

import numpy as np
import trimesh
from scipy.spatial.transform import Rotation

from robomach_core.part import builtin_workpiece
from robomach_core.scoring import mesh_deviation
from tests.mesh_reference import distance_to_every_face


def _winding(mesh: trimesh.Trimesh, p: np.ndarray) -> float:
    """Winding number of the mesh about p (solid angles / 4 pi): the reference inside test
    (trimesh's ray test gave different answers for the same points in two frames)."""
    a, b, c = (mesh.vertices[mesh.faces[:, i]] - p for i in range(3))
    la, lb, lc = (np.linalg.norm(v, axis=1) for v in (a, b, c))
    det = np.einsum("ij,ij->i", a, np.cross(b, c))
    dot = np.einsum("ij,ij->i", a, b) * lc + np.einsum("ij,ij->i", b, c) * la
    dot += np.einsum("ij,ij->i", c, a) * lb
    return float(np.sum(2 * np.arctan2(det, la * lb * lc + dot)) / (4 * np.pi))


def test_mesh_deviation_equals_the_distance_to_the_mesh_placed_in_the_base_frame():
    rng = np.random.default_rng(7)
    T = np.eye(4)
    T[:3, :3] = Rotation.from_euler("xyz", [12.0, -7.0, 35.0], degrees=True).as_matrix()
    T[:3, 3] = [0.61, -0.22, 0.05]
    wp = builtin_workpiece("water_pump").placed(T)
    placed = wp.mesh_in_base()
    pts = placed.bounds[0] + rng.random((300, 3)) * (placed.bounds[1] - placed.bounds[0])
    # The reference, in the base frame: walls are the faces across the part's z axis; inside
    # the solid the deviation is -(distance to the surface + r).
    walls = placed.submesh(
        [np.flatnonzero(np.abs(placed.face_normals @ T[:3, 2]) < np.cos(np.radians(45)))],
        append=True,
    )
    to_wall = distance_to_every_face(pts, walls.triangles)
    to_surface = distance_to_every_face(pts, placed.triangles)
    inside = np.array([_winding(placed, p) > 0.5 for p in pts])
    reference = np.where(inside, -(to_surface + 0.001), to_wall - 0.001)
    got = mesh_deviation(wp, 0.001, pts, axis_base=-T[:3, 2])
    assert inside.any() and (~inside).any()
    np.testing.assert_allclose(got, reference, atol=1e-9)


def test_the_deviation_is_signed_and_blind_to_the_floor():
    """In the pump's groove (wall at y = -65 mm, floor at z = 14 mm, r = 1 mm): a ball resting
    on the floor 2 mm from the wall is 1 mm of air, not a perfect 0 (the floor is not the
    wall); 0.5 mm inside the wall is -1.5 mm; touching the wall is 0."""
    wp = builtin_workpiece("water_pump")
    T = wp.T_base_wobj
    wobj = np.array([[0.0, -0.063, 0.015], [0.0, -0.0655, 0.017], [0.0, -0.064, 0.017]])
    got = mesh_deviation(wp, 0.001, wobj @ T[:3, :3].T + T[:3, 3])
    np.testing.assert_allclose(got, [0.001, -0.0015, 0.0], atol=1e-8)  # the union: float32


def test_a_pickled_workpiece_still_measures_distances():
    """trimesh pickles its cached triangle tree empty; the workpiece leaves its caches behind."""
    import pickle

    wp = builtin_workpiece("water_pump")
    pts = np.array([[0.5, 0.5, 0.5], [0.0, 0.1, 0.02]])
    before = mesh_deviation(wp, 0.001, pts)  # builds and caches the tree
    copy = pickle.loads(pickle.dumps(wp))
    np.testing.assert_allclose(mesh_deviation(copy, 0.001, pts), before)
    assert copy.wall is not None and np.array_equal(copy.T_base_wobj, wp.T_base_wobj)


def test_inside_beside_edges_and_corners_is_the_winding_numbers():
    """Points within a micrometre of the pump's edges and corners, where the nearest face's
    normal cannot tell (the winding number decides, libigl's): the same side as the reference
    winding number's, in and out, over fresh points each run."""
    from robomach_core.part import mesh_query
    from robomach_core.scoring.mesh_score import _inside

    seed = int(np.random.default_rng().integers(2**32))
    rng = np.random.default_rng(seed)
    mesh = builtin_workpiece("water_pump").mesh
    edges = mesh.edges_unique[rng.choice(len(mesh.edges_unique), 150, replace=False)]
    f = rng.uniform(0.0, 1.0, (len(edges), 1))
    on_edges = (1 - f) * mesh.vertices[edges[:, 0]] + f * mesh.vertices[edges[:, 1]]
    corners = mesh.vertices[rng.choice(len(mesh.vertices), 50, replace=False)]
    pts = np.vstack([on_edges, corners]) + rng.normal(0.0, 1e-6, (200, 3))
    closest, distance, tri = mesh_query.closest_point(mesh, pts)
    got = _inside(mesh, pts, closest, np.asarray(distance), tri)
    want = np.array([_winding(mesh, p) > 0.5 for p in pts])
    assert got.any() and (~got).any(), seed
    np.testing.assert_array_equal(got, want, err_msg=f"seed {seed}")
