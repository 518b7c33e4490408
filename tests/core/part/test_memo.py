"""The part's slow steps are done once per input (``robomach_core.part.memo``): a file read
again (a cell change that keeps the part) and a hull placed again (the supervisor after the
isolated check) give what computing them afresh gives, and the store stays within its bounds."""

from __future__ import annotations

import numpy as np
import pytest
import trimesh
from hypothesis import given, settings
from hypothesis import strategies as st

from robomach_core.errors import MeshFileError
from robomach_core.part import PartDeviation, builtin_workpiece, mesh_from_bytes, real_workpiece
from robomach_core.part import workpiece as workpiece_module
from robomach_core.part.bvh import (
    convex_hull_of,
    hull_corner_indices,
    placed_convex_hull,
    remember_hull_corners,
)
from robomach_core.part.memo import Memo, digest
from robomach_core.part.workpiece import parse_mesh_file
from robomach_core.transforms import make_transform


def _parts() -> dict[str, np.ndarray]:
    parts = {name: builtin_workpiece(name).mesh.vertices for name in ("block", "water_pump")}
    casting = real_workpiece(builtin_workpiece("s_groove"), PartDeviation.realistic(3))
    parts["casting"] = casting.mesh.vertices
    parts["sphere"] = trimesh.creation.icosphere(subdivisions=3, radius=0.04).vertices
    return {name: np.asarray(v, dtype=float) for name, v in parts.items()}


PARTS = _parts()


def _hull_points(hull) -> np.ndarray:
    return np.asarray(hull.points())


def test_the_memo_keeps_the_most_recent_values_within_its_bounds():
    memo = Memo(max_entries=2, max_bytes=100)
    memo.put(b"a", "A", 10)
    memo.put(b"b", "B", 10)
    assert memo.get(b"a") == "A"  # now the most recent: "b" goes first
    memo.put(b"c", "C", 10)
    assert (memo.get(b"a"), memo.get(b"b"), memo.get(b"c")) == ("A", None, "C")
    memo.put(b"d", "D", 95)  # over the bytes with "a" or "c" beside it
    assert len(memo) == 1 and memo.get(b"d") == "D"
    memo.put(b"e", "E", 101)  # larger than the whole store: not kept
    assert memo.get(b"e") is None and memo.get(b"d") == "D"


def test_a_digest_tells_arrays_by_their_dtype_and_shape_and_parts_apart():
    a = np.arange(6, dtype=np.int64)
    assert digest(a) == digest(a.copy())
    assert digest(a) != digest(a.reshape(2, 3))
    assert digest(a) != digest(a.astype(np.float64))
    assert digest(b"ab", b"c") != digest(b"a", b"bc")
    assert digest("1") != digest(1)


def _outside_m(points: np.ndarray, hull_of: np.ndarray) -> float:
    """How far the farthest of ``points`` lies outside the convex hull of ``hull_of`` (m)."""
    from scipy.spatial import ConvexHull

    planes = ConvexHull(hull_of).equations
    return float((points @ planes[:, :3].T + planes[:, 3]).max())


@settings(max_examples=12, deadline=None)
@given(
    name=st.sampled_from(sorted(PARTS)),
    position_m=st.tuples(*[st.floats(-1.0, 1.0)] * 3),
    angles_deg=st.tuples(*[st.floats(-180.0, 180.0)] * 3),
)
def test_a_placed_hull_is_the_hull_of_the_placed_vertices(name, position_m, angles_deg):
    """qhull's corners found on the part's own vertices, placed, are rows of the placed
    vertices that bound the same hull, to rounding, as the corners qhull finds on the placed
    vertices. (Not always the same rows: a point within 2e-16 m of a face may count as a
    corner in one frame only; such a point was found on a casting tilted by 1 deg.)"""
    from scipy.spatial.transform import Rotation

    vertices = PARTS[name]
    R = Rotation.from_euler("xyz", angles_deg, degrees=True).as_matrix()
    T = make_transform(R, np.array(position_m))
    placed = vertices @ T[:3, :3].T + T[:3, 3]
    hull, corners = placed_convex_hull(vertices, placed)
    _, own_corners, _ = convex_hull_of(vertices)
    expected_hull, expected_corners, _ = convex_hull_of(placed)
    assert len(corners) == len(own_corners)
    assert all((placed == c).all(axis=1).any() for c in corners)  # rows of the placed part
    assert _outside_m(corners, expected_corners) < 1e-12
    assert _outside_m(expected_corners, corners) < 1e-12
    assert _outside_m(_hull_points(hull), _hull_points(expected_hull)) < 1e-12
    assert _outside_m(_hull_points(expected_hull), _hull_points(hull)) < 1e-12


def test_the_checked_corners_are_remembered_and_wrong_ones_refused():
    vertices = PARTS["casting"] + 0.5  # vertices no other test has seen
    assert hull_corner_indices(vertices) is None
    _, corners, _ = convex_hull_of(vertices)
    indices = hull_corner_indices(vertices)
    assert indices is not None
    np.testing.assert_array_equal(vertices[indices], corners)
    assert not remember_hull_corners(vertices, np.array([0, 1, 2, len(vertices)]))
    assert not remember_hull_corners(vertices, np.array([0.0, 1.0, 2.0, 3.0]))
    assert not remember_hull_corners(vertices, np.array([0, 1]))


def _sphere_stl(z_mm: float) -> bytes:
    mesh = trimesh.creation.icosphere(subdivisions=3, radius=30.0)
    mesh.apply_translation([0.0, 0.0, z_mm])
    return mesh.export(file_type="stl")


def test_a_file_read_again_is_not_parsed_again_and_reads_the_same(monkeypatch):
    data = _sphere_stl(31.234)
    first = mesh_from_bytes(data, ".stl", name="again")

    def refuse(*args, **kwargs):
        raise AssertionError("parsed again")

    monkeypatch.setattr("robomach_core.isolation.run_isolated", refuse)
    again = mesh_from_bytes(data, ".stl", name="again")
    np.testing.assert_array_equal(again.mesh.vertices, first.mesh.vertices)
    np.testing.assert_array_equal(again.mesh.faces, first.mesh.faces)
    assert (again.surface_z_m, again.wall_z_m) == (first.surface_z_m, first.wall_z_m)
    assert again.mesh is not first.mesh
    assert not np.shares_memory(again.mesh.vertices, first.mesh.vertices)
    with pytest.raises(AssertionError, match="parsed again"):  # another name is another read
        mesh_from_bytes(data, ".stl", name="other")


def test_a_refused_file_is_refused_again():
    flat = trimesh.Trimesh([[0, 0, 0], [100, 0, 0], [0, 100, 0]], [[0, 1, 2]]).export(
        file_type="stl"
    )
    for _ in range(2):
        with pytest.raises(MeshFileError, match="thick"):
            mesh_from_bytes(flat, ".stl", name="flat")
    assert len(workpiece_module.PARSED_MEMO) <= workpiece_module.PARSED_MEMO.max_entries


def test_the_read_carries_the_checked_corners_unless_the_solid_differs():
    one = parse_mesh_file({"data": _sphere_stl(40.0), "kind": "stl", "name": "one",
                           "scale": 1e-3, "max_triangles": 10_000})  # fmt: skip
    vertices = one["arrays"]["vertices"]
    _, corners, _ = convex_hull_of(vertices)
    np.testing.assert_array_equal(vertices[one["arrays"]["hull_corner_indices"]], corners)
    a = trimesh.creation.box(extents=(20.0, 20.0, 20.0))
    b = trimesh.creation.box(extents=(20.0, 20.0, 20.0))
    b.apply_translation([10.0, 10.0, 10.0])  # overlapping bodies: solid_mesh joins them
    two = trimesh.util.concatenate([a, b]).export(file_type="stl")
    joined = parse_mesh_file({"data": two, "kind": "stl", "name": "two", "scale": 1e-3,
                              "max_triangles": 10_000})  # fmt: skip
    assert "hull_corner_indices" not in joined["arrays"]
