"""Checks of a mesh before native code sees it: what the cell can use, or a clear refusal.

PROBLEM   A workpiece or stock mesh goes to qhull (its convex hull, a supervision obstacle), to
          coal (the hull, the contact BVH) and to trimesh's triangle tree. A 184-byte STL of
          two coplanar triangles crashed the server in coal's hull (issue 19, R1); a box 1e9 mm
          from its origin did the same, float32 having collapsed it; a one-triangle STL and a
          500,000-face OBJ failed later as server errors.
STRATEGY  Refuse from the file's bytes what would cost memory to parse (``workpiece`` counts
          the triangles; here the vertices), then from the parsed mesh what the cell cannot
          use: non-finite coordinates, a mesh far from its own origin (where float32 files
          lose the part), a size outside 1-2000 mm, a part thinner than ``MIN_THICKNESS_M``
          along its thinnest principal axis (flat, a line, a point). Then the native steps run
          once in an isolated process (``isolation``, task ``mesh``): a crash there refuses the
          mesh instead of killing the caller, and the hull's volume it measured is checked.
SOLUTION  ``check_mesh_bytes`` before parsing, ``check_mesh(mesh, name)`` after (metres), called
          by ``workpiece.mesh_from_bytes`` for every mesh that enters: uploads, stock meshes,
          project files and stored projects. Watertightness is not required: the contact model
          and the clearance probe work on triangles, the supervisor on the convex hull, and a
          watertight part written as STL (float32, touching solids) is often not watertight
          when read back (the built-in water pump is not).
"""

from __future__ import annotations

import numpy as np
import trimesh

from .errors import MeshFileError

# The part's size after scaling (the workbench's parts are 1-2000 mm across).
MIN_EXTENT_M = 1e-3
MAX_EXTENT_M = 2.0
# Thinnest along the thinnest principal axis: 0.1 mm (a sheet; flat meshes have 0).
MIN_THICKNESS_M = 1e-4
# Smallest convex-hull volume: 1 mm^3.
MIN_HULL_VOLUME_M3 = 1e-9
# Largest coordinate: 10 m from the mesh's origin, beyond every arm's reach (3 m) and where a
# float32 STL still resolves 1 um (1e9 mm collapses a 100 mm box to a 64 mm grid).
MAX_COORDINATE_M = 10.0
# An OBJ/PLY may hold vertices no face uses: at most this many per allowed triangle.
VERTICES_PER_TRIANGLE = 3
# What the isolated native check may allocate, and how long it may take.
NATIVE_CHECK_MEMORY_BYTES = 1 << 30
NATIVE_CHECK_TIMEOUT_S = 60.0


def _obj_vertex_lines(data: bytes) -> int:
    return data.count(b"\nv ") + data.count(b"\nv\t") + data.startswith((b"v ", b"v\t"))


def _ply_declared_vertices(data: bytes) -> int:
    header_end = data.find(b"end_header", 0, 1 << 20)
    for line in data[: max(header_end, 0)].splitlines():
        words = line.split()
        if words[:2] == [b"element", b"vertex"] and len(words) == 3 and words[2].isdigit():
            return int(words[2])
    return 0


def check_mesh_bytes(data: bytes, kind: str, name: str, *, max_triangles: int) -> None:
    """Refuse a file declaring more vertices than ``VERTICES_PER_TRIANGLE * max_triangles``
    (OBJ ``v`` lines, the PLY header's ``element vertex``) before it is parsed: trimesh
    would build them all. (Triangles are counted by ``workpiece.count_mesh_triangles``.)"""
    kind = kind.lower().lstrip(".")
    if kind == "obj":
        vertices = _obj_vertex_lines(data)
    elif kind == "ply":
        vertices = _ply_declared_vertices(data)
    else:
        return  # an STL has three vertices per triangle
    limit = VERTICES_PER_TRIANGLE * max_triangles
    if vertices > limit:
        raise MeshFileError(
            f"{name}: {vertices} vertices exceed the limit of {limit} (3 per allowed triangle; "
            "simplify the mesh)"
        )


def principal_extents_m(vertices: np.ndarray) -> np.ndarray:
    """Extents of the vertices along their principal axes, largest first, shape (3,)."""
    v = np.asarray(vertices, dtype=float)
    centred = v - v.mean(axis=0)
    _, axes = np.linalg.eigh(centred.T @ centred)
    along = centred @ axes
    return np.sort(along.max(axis=0) - along.min(axis=0))[::-1]


def check_mesh(mesh: trimesh.Trimesh, name: str, *, native: bool = True) -> trimesh.Trimesh:
    """``mesh`` (metres) without its degenerate faces when the cell can use it, else
    ``MeshFileError`` naming what is wrong.

    Args:
        mesh: A parsed mesh, already scaled to metres (changed in place: degenerate faces and
            the vertices no face uses are dropped).
        name: The file's name for messages.
        native: Also run the native steps once in an isolated process (``isolation``).
    """
    vertices = np.asarray(mesh.vertices)
    if len(mesh.faces) == 0 or len(vertices) == 0:
        raise MeshFileError(f"{name}: the file holds no triangles")
    if not np.all(np.isfinite(vertices)):
        raise MeshFileError(f"{name}: the mesh has non-finite vertices (NaN or infinity)")
    far = float(np.max(np.abs(vertices)))
    if far > MAX_COORDINATE_M:
        raise MeshFileError(
            f"{name}: the mesh reaches {far * 1e3:.3g} mm from its origin, beyond "
            f"{MAX_COORDINATE_M * 1e3:.0f} mm: model the part near its origin and place it "
            "with the work-object frame (is the unit right?)"
        )
    keep = mesh.nondegenerate_faces()
    if not keep.all():
        mesh.update_faces(keep)
        mesh.remove_unreferenced_vertices()
    if len(mesh.faces) == 0:
        raise MeshFileError(f"{name}: every triangle is degenerate (zero area)")
    extent = float(np.max(mesh.extents))
    if not (MIN_EXTENT_M <= extent <= MAX_EXTENT_M):
        raise MeshFileError(
            f"{name}: mesh is {extent * 1e3:.3g} mm across after scaling; expected "
            f"{MIN_EXTENT_M * 1e3:g}-{MAX_EXTENT_M * 1e3:g} mm (is the unit right?)"
        )
    thickness = float(principal_extents_m(mesh.vertices)[2])
    if thickness < MIN_THICKNESS_M:
        raise MeshFileError(
            f"{name}: the part is {thickness * 1e3:.3g} mm thick along its thinnest axis (flat "
            f"or a line); a workpiece must be at least {MIN_THICKNESS_M * 1e3:g} mm thick"
        )
    if native:
        _check_native(mesh, name)
    return mesh


def _check_native(mesh: trimesh.Trimesh, name: str) -> None:
    """The convex hull, BVH and a distance query, built once in an isolated process."""
    from .isolation import IsolatedError, run_isolated

    try:
        answer = run_isolated(
            "mesh",
            {"vertices": np.asarray(mesh.vertices, dtype=float),
             "faces": np.asarray(mesh.faces, dtype=np.int64)},
            memory_bytes=NATIVE_CHECK_MEMORY_BYTES,
            timeout_s=NATIVE_CHECK_TIMEOUT_S,
        )  # fmt: skip
    except IsolatedError as exc:
        raise MeshFileError(f"{name}: the geometry library cannot use this mesh ({exc})") from None
    volume = float(answer.get("hull_volume_m3", 0.0))
    if not volume >= MIN_HULL_VOLUME_M3:
        raise MeshFileError(
            f"{name}: the part's convex hull holds {volume * 1e9:.3g} mm^3; a workpiece holds "
            f"at least {MIN_HULL_VOLUME_M3 * 1e9:g} mm^3"
        )
