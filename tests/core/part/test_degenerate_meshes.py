"""Degenerate meshes within the size limits are refused or bounded before the expensive step,
in the isolated process that reads them, within a time limit (issue 32, point 6).

A tetrahedron whose four faces are each written 125,000 times (a 4 MB OBJ) took 107 s and
2.4 GB to read, most of it splitting the faces into bodies; 100,000 loose tetrahedra took 81 s
and 1.7 GB. Now repeated faces are dropped and a mesh of more than ``MAX_MESH_BODIES`` bodies
is refused before anything splits it, and the reading runs in the isolation helper's child:
this process only sends the bytes and receives the mesh.
"""

from __future__ import annotations

import tracemalloc

import numpy as np
import pytest
import trimesh

from robomach_core.errors import MeshFileError
from robomach_core.part import mesh_from_bytes, workpiece
from robomach_core.part.mesh_check import MAX_MESH_BODIES, count_bodies, drop_duplicate_faces

CALLER_MEMORY_BOUND_BYTES = 100e6


def _traced_peak(fn) -> tuple[object, float]:
    tracemalloc.start()
    try:
        out = fn()
        return out, tracemalloc.get_traced_memory()[1]
    finally:
        tracemalloc.stop()


def _obj(vertices: np.ndarray, faces: np.ndarray) -> bytes:
    lines = [f"v {x:.4f} {y:.4f} {z:.4f}" for x, y, z in vertices]
    lines += [f"f {a + 1} {b + 1} {c + 1}" for a, b, c in faces]
    return ("\n".join(lines) + "\n").encode()


@pytest.mark.slow  # half a million faces parsed
def test_faces_written_many_times_are_read_once() -> None:
    data = b"v 0 0 0\nv 10 0 0\nv 0 10 0\nv 0 0 10\n" + (
        b"f 1 3 2\nf 1 2 4\nf 1 4 3\nf 2 3 4\n" * 125_000
    )
    assert len(data) > 4_000_000
    part, peak = _traced_peak(lambda: mesh_from_bytes(data, ".obj", name="repeated"))
    assert len(part.mesh.faces) == 4 and part.mesh.is_watertight
    assert peak < CALLER_MEMORY_BOUND_BYTES, f"{peak / 1e6:.0f} MB"


def test_one_face_written_500000_times_is_refused_as_flat() -> None:
    data = b"v 0 0 0\nv 10 0 0\nv 0 10 0\n" + b"f 1 2 3\n" * 500_000
    with pytest.raises(MeshFileError, match="thick along its thinnest axis"):
        mesh_from_bytes(data, ".obj", name="one face")


@pytest.mark.slow  # 400,000 faces written and parsed
def test_100000_loose_tetrahedra_are_refused_before_any_split() -> None:
    n = 100_000
    rng = np.random.default_rng()
    corners = np.array([[0, 0, 0], [1, 0, 0], [0, 1, 0], [0, 0, 1]], dtype=float)
    vertices = (rng.uniform(0, 400, (n, 1, 3)) + corners).reshape(-1, 3)
    faces = np.arange(n)[:, None, None] * 4 + [[0, 2, 1], [0, 1, 3], [0, 3, 2], [1, 2, 3]]
    data = _obj(vertices, faces.reshape(-1, 3))

    def read() -> None:
        with pytest.raises(MeshFileError, match=rf"{n} separate bodies, more than 500"):
            mesh_from_bytes(data, ".obj", name="loose")

    _, peak = _traced_peak(read)
    assert peak < CALLER_MEMORY_BOUND_BYTES + len(data), f"{peak / 1e6:.0f} MB"


def test_a_few_hundred_bodies_are_still_a_part() -> None:
    boxes = [trimesh.creation.box(extents=(5, 5, 5)) for _ in range(MAX_MESH_BODIES)]
    for i, box in enumerate(boxes):
        box.apply_translation([10.0 * (i % 25), 10.0 * (i // 25), 2.5])
    joined = trimesh.util.concatenate(boxes)
    part = mesh_from_bytes(joined.export(file_type="stl"), ".stl", name="pins")
    assert count_bodies(part.mesh.faces, len(part.mesh.vertices)) == MAX_MESH_BODIES


def test_reading_is_refused_when_it_overruns_its_time(monkeypatch: pytest.MonkeyPatch) -> None:
    sphere = trimesh.creation.icosphere(subdivisions=6, radius=50.0)
    monkeypatch.setattr(workpiece, "PARSE_TIMEOUT_S", 0.01)
    with pytest.raises(MeshFileError, match="took longer than 0.01 s"):
        mesh_from_bytes(sphere.export(file_type="stl"), ".stl", name="slow")


def test_dropping_repeats_keeps_every_distinct_face_and_its_turning() -> None:
    seed = np.random.SeedSequence().entropy
    rng = np.random.default_rng(seed)
    base = trimesh.creation.icosphere(subdivisions=2)
    faces = np.asarray(base.faces)
    picks = rng.integers(0, len(faces), 3 * len(faces))
    rolled = np.array([np.roll(faces[i], rng.integers(0, 3)) for i in picks])  # same turning
    reverse = faces[:5, ::-1]  # a face and its reverse are two faces
    mesh = trimesh.Trimesh(base.vertices, np.vstack([faces, rolled, reverse]), process=False)
    dropped = drop_duplicate_faces(mesh)
    assert dropped == len(rolled), f"seed {seed}"
    assert len(mesh.faces) == len(faces) + len(reverse), f"seed {seed}"
