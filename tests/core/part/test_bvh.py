"""The one coal BVH of a part (robomach_core.part.bvh) and the clearance probe that queries it."""

from __future__ import annotations

import coal
import numpy as np
import trimesh

from robomach_core.cell import ClearanceProbe, Tool
from robomach_core.part import bvh_from_mesh
from robomach_core.part.workpiece import block


def _point_distance(bvh: coal.BVHModelOBBRSS, point: np.ndarray) -> float:
    request, result = coal.DistanceRequest(), coal.DistanceResult()
    probe = coal.Sphere(1e-9)
    return float(
        coal.distance(
            bvh, coal.Transform3s(), probe, coal.Transform3s(np.eye(3), point), request, result
        )
    )


def test_bvh_keeps_only_the_used_vertices_and_measures_like_trimesh():
    box = trimesh.creation.box(extents=(0.10, 0.06, 0.04))
    rng = np.random.default_rng(7)
    # Stray vertices far away that no face uses: the BVH must not see them.
    stray = rng.uniform(1.0, 2.0, size=(5, 3))
    vertices = np.vstack([stray, box.vertices])
    faces = box.faces + len(stray)
    bvh = bvh_from_mesh(vertices, faces)
    assert bvh.num_vertices == len(box.vertices)
    assert bvh.num_tris == len(box.faces)
    points = rng.uniform(-0.2, 0.2, size=(20, 3))
    points = points[~box.contains(points)]
    _, expected, _ = trimesh.proximity.closest_point(box, points)
    measured = [_point_distance(bvh, p) for p in points]
    np.testing.assert_allclose(measured, expected, atol=1e-6)


def test_clearance_gap_of_a_ball_is_its_distance_to_the_wall_less_its_radius():
    part = block()
    tool = Tool(radius_m=0.002)
    probe = ClearanceProbe(tool, part)
    mesh = part.mesh_in_base()
    top = mesh.bounds[1][2]
    centre = mesh.bounds.mean(axis=0)
    for height_m in (0.003, 0.010, 0.050):
        T = np.eye(4)
        T[:3, 3] = [centre[0], centre[1], top + height_m]
        gap = probe.gap(T)
        np.testing.assert_allclose(gap.distance_m, height_m - tool.radius_m, atol=1e-6)
        np.testing.assert_allclose(gap.normal, [0.0, 0.0, 1.0], atol=1e-6)
        np.testing.assert_allclose(gap.point_m[2], top, atol=1e-6)
