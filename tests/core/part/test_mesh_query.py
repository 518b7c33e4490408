"""The part's nearest points (mesh_query.closest_point) are exact: the same as every face tried
in turn, for points on, near and far from the wall, on the built-in parts and an uploaded one."""

from __future__ import annotations

import threading

import numpy as np
import pytest
import trimesh

from robomach_core._kernels import _closest_on_triangle
from robomach_core.part import mesh_from_bytes, mesh_query
from tests.mesh_reference import distance_to_every_face
from tests.sloppy_guides import cornered_boss_stl


def _on_triangles(points: np.ndarray, triangles: np.ndarray) -> np.ndarray:
    """How far each point is from its own triangle."""
    return np.array(
        [
            np.linalg.norm(np.array(_closest_on_triangle(*p, t)) - p)
            for p, t in zip(points, triangles, strict=True)
        ]
    )


def _probe_points(mesh: trimesh.Trimesh, rng: np.random.Generator) -> np.ndarray:
    """Points on the surface, within a mm of it on both sides (where the scores look), and
    across the part's box and beyond it."""
    on, face = trimesh.sample.sample_surface(mesh, 120, seed=int(rng.integers(1 << 31)))
    near = on + mesh.face_normals[face] * rng.uniform(-1e-3, 1e-3, (len(on), 1))
    lo, hi = mesh.bounds
    spread = rng.uniform(lo - 0.02, hi + 0.02, (60, 3))
    return np.vstack([on, near, spread])


def _parts() -> list[tuple[str, trimesh.Trimesh]]:
    from robomach_core.cell import Cell, CellConfig

    parts = [(name, Cell(CellConfig(workpiece=name)).workpiece.mesh) for name in ("water_pump",)]
    stl, _ = cornered_boss_stl()
    parts.append(("uploaded boss", mesh_from_bytes(stl, ".stl", name="boss").mesh))
    return parts


@pytest.mark.parametrize("name, mesh", _parts(), ids=lambda v: v if isinstance(v, str) else "")
def test_nearest_points_are_the_nearest_of_every_face(name, mesh):
    points = _probe_points(mesh, np.random.default_rng(7))
    closest, distance, triangle = mesh_query.closest_point(mesh, points)
    assert closest.shape == points.shape and distance.shape == triangle.shape == (len(points),)
    np.testing.assert_allclose(
        distance, distance_to_every_face(points, mesh.triangles), rtol=0, atol=1e-12
    )
    # The point returned is at that distance, and on the triangle named.
    np.testing.assert_allclose(np.linalg.norm(closest - points, axis=1), distance, atol=1e-12)
    assert np.max(_on_triangles(closest, mesh.triangles[triangle])) < 1e-12


def test_no_points_and_queries_from_several_threads():
    mesh = _parts()[0][1]
    closest, distance, triangle = mesh_query.closest_point(mesh, np.zeros((0, 3)))
    assert closest.shape == (0, 3) and distance.shape == (0,) and triangle.shape == (0,)
    points = _probe_points(mesh, np.random.default_rng(3))
    expected = mesh_query.closest_point(mesh, points)[1]
    answers: list[np.ndarray] = []

    def ask() -> None:
        for _ in range(20):
            answers.append(mesh_query.closest_point(mesh, points)[1])

    threads = [threading.Thread(target=ask) for _ in range(4)]
    for t in threads:
        t.start()
    for t in threads:
        t.join()
    assert len(answers) == 80
    for a in answers:
        np.testing.assert_array_equal(a, expected)
