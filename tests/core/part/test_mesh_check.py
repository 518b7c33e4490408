"""Meshes the cell cannot use are refused before native code sees them (issue 19, R1).

The audit's 184-byte flat STL segfaulted coal's convex hull and killed the server; a box 1e9 mm
from its origin did the same (float32 collapsed it). These tests give ``mesh_from_bytes`` the
issue's files and their relatives (one triangle, a line, a needle, NaN, a vertex flood) and
check each is refused with a message naming what is wrong, while real thin parts pass; and
that a mesh which would crash coal, given to the isolated native check directly, is refused
rather than crashing this process.
"""

from __future__ import annotations

import struct

import numpy as np
import pytest
import trimesh

from robomach_core.errors import MeshFileError
from robomach_core.part import mesh_from_bytes
from robomach_core.part.mesh_check import (
    MIN_THICKNESS_M,
    _check_native,
    check_mesh,
    principal_extents_m,
)


def binary_stl(triangles: list[tuple[float, ...]]) -> bytes:
    """A binary STL of (x1, y1, z1, x2, ..., z3) triangles, zero normals (the issue's form)."""
    body = b"".join(struct.pack("<12f", 0, 0, 0, *t) + b"\0\0" for t in triangles)
    return bytes(80) + struct.pack("<I", len(triangles)) + body


FLAT_STL = binary_stl([(0, 0, 0, 100, 0, 0, 100, 100, 0), (0, 0, 0, 100, 100, 0, 0, 100, 0)])


def stl_of(mesh: trimesh.Trimesh) -> bytes:
    return mesh.export(file_type="stl")


def test_the_issue_s_184_byte_flat_stl_is_refused_as_flat():
    assert len(FLAT_STL) == 184
    with pytest.raises(MeshFileError, match=r"flat: .*0 mm thick.*at least 0.1 mm"):
        mesh_from_bytes(FLAT_STL, ".stl", name="flat")


def test_a_box_1e9_mm_away_is_refused_by_its_distance_not_collapsed():
    box = trimesh.creation.box(extents=(100.0, 100.0, 100.0))
    box.apply_translation([1e9, 0.0, 0.0])
    with pytest.raises(MeshFileError, match=r"1e\+09 mm from its origin.*work-object frame"):
        mesh_from_bytes(stl_of(box), ".stl", name="far")


@pytest.mark.parametrize(
    ("data", "needle"),
    [
        (binary_stl([(0, 0, 0, 100, 0, 0, 0, 100, 0)]), "0 mm thick"),  # one triangle
        (binary_stl([(0, 0, 0, 50, 50, 50, 100, 100, 100)]), "degenerate"),  # a line
        (stl_of(trimesh.creation.box(extents=(1.0, 0.1, 0.1))), r"0.01 mm\^3"),  # a needle
        (stl_of(trimesh.creation.box(extents=(0.5, 0.5, 0.5))), "0.5 mm across"),  # too small
        (stl_of(trimesh.creation.box(extents=(2500.0, 10, 10))), "2.5e\\+03 mm across"),
    ],
    ids=["one-triangle", "line", "needle", "tiny", "huge"],
)
def test_degenerate_parts_are_refused_naming_the_fault(data: bytes, needle: str):
    with pytest.raises(MeshFileError, match=needle):
        mesh_from_bytes(data, ".stl", name="part")


def test_a_thin_tilted_sheet_is_measured_along_its_own_axes():
    sheet = trimesh.creation.box(extents=(400.0, 300.0, 0.05))  # 0.05 mm: too thin
    sheet.apply_transform(trimesh.transformations.rotation_matrix(0.7, [1.0, 1.0, 0.0]))
    assert np.max(sheet.extents) > 100.0  # axis-aligned it looks thick
    with pytest.raises(MeshFileError, match="0.05 mm thick"):
        mesh_from_bytes(stl_of(sheet), ".stl", name="sheet")
    thick = trimesh.creation.box(extents=(400.0, 300.0, 0.5))
    thick.apply_transform(trimesh.transformations.rotation_matrix(0.7, [1.0, 1.0, 0.0]))
    part = mesh_from_bytes(stl_of(thick), ".stl", name="sheet")
    assert principal_extents_m(part.mesh.vertices)[2] == pytest.approx(0.5e-3, rel=1e-3)


def test_real_parts_pass_unchanged():
    for mesh in (
        trimesh.creation.box(extents=(150.0, 50.0, 40.0)),
        trimesh.creation.icosphere(subdivisions=2, radius=30.0),
        trimesh.creation.box(extents=(2000.0, 2000.0, 0.2)),  # a big sheet, 0.2 mm thick
    ):
        part = mesh_from_bytes(stl_of(mesh), ".stl")
        assert len(part.mesh.faces) == len(mesh.faces)
        np.testing.assert_allclose(part.mesh.extents, mesh.extents * 1e-3, rtol=1e-6)


def test_nan_vertices_are_dropped_or_refused():
    data = bytearray(stl_of(trimesh.creation.box(extents=(10.0, 10.0, 10.0))))
    data[84 + 12 : 84 + 16] = struct.pack("<f", float("nan"))  # first vertex of face 0
    part = mesh_from_bytes(bytes(data), ".stl")  # trimesh drops the face with the NaN
    assert np.all(np.isfinite(part.mesh.vertices))
    all_nan = binary_stl([(float("nan"),) * 9] * 4)
    with pytest.raises(MeshFileError):
        mesh_from_bytes(all_nan, ".stl")


def test_an_obj_with_a_flood_of_vertices_is_refused_before_parsing():
    data = b"v 0 0 0\n" * 40_000 + b"v 10 0 0\nv 0 10 0\nv 0 0 10\nf 1 2 3\n"
    with pytest.raises(MeshFileError, match="40003 vertices exceed the limit of 3000"):
        mesh_from_bytes(data, ".obj", max_triangles=1000)


def test_degenerate_faces_are_dropped_before_native_code():
    box = trimesh.creation.box(extents=(50.0, 40.0, 30.0))
    faces = np.vstack([box.faces, [[0, 0, 1], [2, 2, 2]]])  # two zero-area faces
    mesh = trimesh.Trimesh(box.vertices * 1e-3, faces, process=False)
    checked = check_mesh(mesh, "box")
    assert len(checked.faces) == 12


def test_a_mesh_that_crashes_coal_is_refused_by_the_isolated_check_not_crashing_us():
    """The thickness check catches the flat mesh first; without it, the isolated native check
    would still refuse it: coal's hull crashes in the child, not here."""
    flat = trimesh.Trimesh(
        [[0, 0, 0], [0.1, 0, 0], [0.1, 0.1, 0], [0, 0.1, 0]], [[0, 1, 2], [0, 2, 3]], process=False
    )
    assert principal_extents_m(flat.vertices)[2] < MIN_THICKNESS_M
    with pytest.raises(MeshFileError, match="geometry library cannot use this mesh"):
        _check_native(flat, "flat")
