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
          along its thinnest principal axis (flat, a line, a point); faces repeated in the same
          turning order are dropped and a mesh of more than ``MAX_MESH_BODIES`` separate bodies
          is refused before anything splits it (issue 32). Then the native steps run once in an
          isolated process (``isolation``, task ``mesh``): a crash there refuses the mesh
          instead of killing the caller, and the hull's volume it measured is checked.
SOLUTION  ``check_mesh_bytes`` before parsing, ``check_mesh(mesh, name)`` after (metres), called
          by ``workpiece.parse_mesh_file`` (in an isolated process, with a time limit) for
          every mesh that enters: uploads, stock meshes, project files and stored projects.
          Watertightness is not required: the contact model and the clearance probe work on
          triangles, the supervisor on the convex hull, and a watertight part written as STL
          (float32, touching solids) is often not watertight when read back (the built-in
          water pump is not).
"""

from __future__ import annotations

import numpy as np
import trimesh

from ..errors import MeshFileError

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
# Separate bodies a workpiece may have (a part and its bosses, a few loose pieces): above it,
# joining them (``workpiece.solid_mesh``: split, then a boolean union) is the expensive step
# (100,000 loose tetrahedra: 81 s and 1.7 GB) for a file that is no part.
MAX_MESH_BODIES = 500


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


def check_mesh(mesh: trimesh.Trimesh, name: str, *, native: bool | str = True) -> trimesh.Trimesh:
    """``mesh`` (metres) without its degenerate faces when the cell can use it, else
    ``MeshFileError`` naming what is wrong.

    Args:
        mesh: A parsed mesh, already scaled to metres (changed in place: degenerate faces and
            the vertices no face uses are dropped).
        name: The file's name for messages.
        native: Also run the native steps once in an isolated process (``isolation``);
            ``"here"``: in this process, which is such a process already.
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
    drop_duplicate_faces(mesh)
    bodies = count_bodies(np.asarray(mesh.faces), len(mesh.vertices))
    if bodies > MAX_MESH_BODIES:
        raise MeshFileError(
            f"{name}: the mesh is {bodies} separate bodies, more than {MAX_MESH_BODIES}: a "
            "workpiece is one part (join its bodies, or leave out the loose ones)"
        )
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
        _check_native(mesh, name, here=native == "here")
    return mesh


def drop_duplicate_faces(mesh: trimesh.Trimesh) -> int:
    """Drop the faces that repeat another with the same vertices in the same turning order
    (changed in place); returns how many went. One face written 500,000 times was split
    into as many bodies (96-126 s, 2.2 GB). A face and its reverse both stay (two bodies
    touching there)."""
    faces = np.asarray(mesh.faces)
    turn = (np.argmin(faces, axis=1)[:, None] + np.arange(3)) % 3
    canonical = np.take_along_axis(faces, turn, axis=1)
    _, first = np.unique(canonical, axis=0, return_index=True)
    dropped = len(faces) - len(first)
    if dropped:
        keep = np.zeros(len(faces), dtype=bool)
        keep[first] = True
        mesh.update_faces(keep)
        mesh.remove_unreferenced_vertices()
    return dropped


def count_bodies(faces: np.ndarray, n_vertices: int) -> int:
    """Separate bodies of a mesh: sets of faces joined through shared vertices (linear
    time; ``trimesh.split`` builds a mesh per body)."""
    from scipy.sparse import coo_matrix
    from scipy.sparse.csgraph import connected_components

    f = np.asarray(faces, dtype=np.int64)
    if len(f) == 0:
        return 0
    rows = np.concatenate([f[:, 0], f[:, 1]])
    cols = np.concatenate([f[:, 1], f[:, 2]])
    graph = coo_matrix((np.ones(len(rows), dtype=bool), (rows, cols)), (n_vertices, n_vertices))
    _, labels = connected_components(graph, directed=False)
    return int(len(np.unique(labels[f[:, 0]])))


def _check_native(mesh: trimesh.Trimesh, name: str, *, here: bool = False) -> None:
    """The convex hull, BVH and a distance query, built once in an isolated process (``here``:
    this process is one already, ``workpiece.parse_mesh_file``)."""
    from ..isolation import TASKS, IsolatedError, run_isolated

    payload = {"vertices": np.asarray(mesh.vertices, dtype=float),
               "faces": np.asarray(mesh.faces, dtype=np.int64)}  # fmt: skip
    try:
        if here:
            try:
                answer = TASKS["mesh"](payload)
            except (RuntimeError, ValueError) as exc:  # coal, qhull: refused, not a crash
                raise IsolatedError(f"{exc.__class__.__name__}: {exc}") from None
        else:
            answer = run_isolated(
                "mesh",
                payload,
                memory_bytes=NATIVE_CHECK_MEMORY_BYTES,
                timeout_s=NATIVE_CHECK_TIMEOUT_S,
            )
    except IsolatedError as exc:
        raise MeshFileError(f"{name}: the geometry library cannot use this mesh ({exc})") from None
    volume = float(answer.get("hull_volume_m3", 0.0))
    if not volume >= MIN_HULL_VOLUME_M3:
        raise MeshFileError(
            f"{name}: the part's convex hull holds {volume * 1e9:.3g} mm^3; a workpiece holds "
            f"at least {MIN_HULL_VOLUME_M3 * 1e9:g} mm^3"
        )
