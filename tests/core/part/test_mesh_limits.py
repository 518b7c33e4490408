"""Mesh uploads are refused by their triangle count before trimesh parses them (issue 10,
failure 3: a 49 MB OBJ with 6.1 M faces cost 1.3 GB before its 422).

``count_mesh_triangles`` counts from the raw bytes as trimesh will read them; these tests
check it against trimesh's own count on real files of every format, and that a huge OBJ is
refused fast and in little memory.
"""

from __future__ import annotations

import io
import tracemalloc

import numpy as np
import pytest
import trimesh
from hypothesis import given, settings
from hypothesis import strategies as st

from robomach_core.errors import MeshFileError
from robomach_core.part import count_mesh_triangles, mesh_from_bytes

LIMIT = 1000


def exported(mesh: trimesh.Trimesh, file_type: str) -> bytes:
    out = mesh.export(file_type=file_type)
    return out.encode() if isinstance(out, str) else out


def trimesh_faces(data: bytes, kind: str) -> int:
    """Triangles trimesh reads from the file (no merging, so nothing is dropped)."""
    loaded = trimesh.load(io.BytesIO(data), file_type=kind, force="mesh", process=False)
    return len(loaded.faces)


@pytest.fixture(scope="module")
def sphere() -> trimesh.Trimesh:
    return trimesh.creation.icosphere(subdivisions=3, radius=40.0)  # 1280 triangles, mm


@pytest.mark.parametrize("file_type", ["stl", "stl_ascii", "obj", "ply"])
def test_the_count_is_trimesh_s_on_exported_files(sphere, file_type):
    kind = file_type.split("_")[0]
    data = exported(sphere, file_type)
    assert count_mesh_triangles(data, kind) == (1280, True)
    assert trimesh_faces(data, kind) == 1280


@pytest.mark.parametrize("file_type", ["stl", "stl_ascii", "obj", "ply"])
def test_a_mesh_over_the_limit_is_refused_with_its_count(sphere, file_type):
    kind = file_type.split("_")[0]
    with pytest.raises(MeshFileError, match=r"1280 triangles exceed the limit of 1000"):
        mesh_from_bytes(exported(sphere, file_type), f".{kind}", max_triangles=LIMIT)
    small = trimesh.creation.box(extents=(50.0, 40.0, 30.0))
    assert len(mesh_from_bytes(exported(small, file_type), f".{kind}").mesh.faces) == 12


def test_ascii_stl_keywords_count_in_any_case(sphere):
    data = exported(sphere, "stl_ascii").upper()
    assert count_mesh_triangles(data, ".stl") == (1280, True)
    assert trimesh_faces(data, "stl") == 1280


def test_a_binary_stl_is_counted_by_its_header_only_when_the_size_agrees():
    n = 600_000  # 30 MB of zero triangles: refused without reading them
    data = bytes(80) + n.to_bytes(4, "little") + bytes(50 * n)
    assert count_mesh_triangles(data, "stl") == (n, True)
    with pytest.raises(MeshFileError, match="600000 triangles exceed the limit of 500000"):
        mesh_from_bytes(data, ".stl", max_triangles=500_000)
    # A header that lies about the size is not binary for trimesh either: read as ASCII.
    assert count_mesh_triangles(data[:-50], "stl") == (0, True)


def test_obj_polygons_count_as_fans_of_k_minus_2_triangles():
    text = (
        b"# a quad (CRLF), a pentagon with texture and normal indices, a triangle at the end\r\n"
        b"v 0 0 0\nv 10 0 0\nv 10 10 0\nv 0 10 0\nv 5 15 0\n"
        b"vt 0 0\nvn 0 0 1\n"
        b"f 1 2 3 4\r\n"
        b"f 1/1/1 2/1/1 3/1/1 5/1/1 4/1/1\n"
        b"f 1 2 3"
    )
    assert count_mesh_triangles(text, ".obj") == (2 + 3 + 1, True)
    assert trimesh_faces(text, "obj") == 6


@settings(max_examples=40, deadline=None)
@given(st.lists(st.integers(3, 9), min_size=1, max_size=60))
def test_obj_count_matches_trimesh_on_random_polygons(sizes):
    rng = np.random.default_rng(len(sizes))
    n_vertices = max(sizes)
    lines = [f"v {x:.3f} {y:.3f} {z:.3f}" for x, y, z in rng.uniform(0, 50, (n_vertices, 3))]
    lines += ["f " + " ".join(str(i + 1) for i in range(k)) for k in sizes]
    data = "\n".join(lines).encode()
    assert count_mesh_triangles(data, "obj") == (sum(k - 2 for k in sizes), True)
    assert trimesh_faces(data, "obj") == sum(k - 2 for k in sizes)


def test_obj_of_few_big_polygons_is_refused_by_its_triangles():
    # 40 face lines (under the limit of 1000) of 30-gons: 40 * 28 = 1120 triangles.
    ring = np.column_stack([np.cos(np.arange(30)), np.sin(np.arange(30)), np.zeros(30)]) * 20
    lines = [f"v {x:.4f} {y:.4f} {z:.4f}" for x, y, z in ring]
    lines += ["f " + " ".join(str(i + 1) for i in range(30))] * 40
    with pytest.raises(MeshFileError, match="1120 triangles exceed the limit of 1000"):
        mesh_from_bytes("\n".join(lines).encode(), ".obj", max_triangles=LIMIT)


def test_ply_faces_come_from_its_header(sphere):
    data = exported(sphere, "ply")
    header = data[: data.index(b"end_header")]
    assert b"element face 1280" in header
    assert count_mesh_triangles(data, ".ply") == (1280, True)


def test_a_6m_face_obj_is_refused_fast_and_without_parsing_it():
    # 48 MB, the audit's 6.1 M faces: trimesh would build ~1.3 GB of arrays first.
    data = b"v 0 0 0\nv 10 0 0\nv 0 10 0\n" + b"f 1 2 3\n" * 6_000_000
    # Not parsed: its arrays would take ~1.3 GB. How fast: benchmarks/bench_answer_times.py.
    tracemalloc.start()
    try:
        with pytest.raises(MeshFileError, match="exceed the limit of 500000"):
            mesh_from_bytes(data, ".obj", max_triangles=500_000)
        _, peak_bytes = tracemalloc.get_traced_memory()
    finally:
        tracemalloc.stop()
    assert peak_bytes < 50e6, f"{peak_bytes / 1e6:.0f} MB"


def test_the_exact_obj_count_scans_in_bounded_memory():
    # Under the limit by face lines, so every chunk is counted exactly.
    data = b"v 0 0 0\nv 10 0 0\nv 0 10 0\nv 10 10 0\n" + b"f 1 2 3 4\n" * 2_000_000  # 20 MB
    tracemalloc.start()
    try:
        count = count_mesh_triangles(data, "obj", stop_above=5_000_000)
        _, peak_bytes = tracemalloc.get_traced_memory()
    finally:
        tracemalloc.stop()
    assert count == (4_000_000, True)
    assert peak_bytes < 50e6, f"{peak_bytes / 1e6:.0f} MB"
