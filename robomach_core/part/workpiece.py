"""Workpieces: the built-in water-pump groove and aluminium block, and user mesh files.

A workpiece is a triangle mesh in its work-object frame, placed in the robot base frame by
``T_base_wobj`` (the RAPID wobjdata uframe). Built-in ones also carry their true wall contour, so
a learned path can be scored against the real geometry.
"""

from __future__ import annotations

import functools
from dataclasses import dataclass, replace

import numpy as np
import shapely.geometry
import trimesh

from ..errors import InvalidInputError, MeshFileError, UnknownNameError
from ..limits import MAX_MESH_BYTES as MAX_MESH_BYTES
from ..limits import MAX_MESH_TRIANGLES as MAX_MESH_TRIANGLES
from ..robots import registry
from ..transforms import make_transform
from .bvh import hull_corner_indices, remember_hull_corners
from .contour import Contour, filleted_polygon
from .memo import Memo, digest
from .mesh_check import check_mesh, check_mesh_bytes
from .s_groove import S_GROOVE_DEPTH_M, S_GROOVE_PLATE_SIZE_M, s_groove_mesh, s_groove_wall

WORKPIECE_NAMES = ("water_pump", "block", "s_groove")
MESH_SUFFIXES = (".stl", ".obj", ".ply")
# Reading a mesh file (``parse_mesh_file``, in an isolated process): memory it may take above
# the helper's own, and time (a good 500k-triangle part reads in about 8 s).
PARSE_MEMORY_BYTES = 2 << 30
PARSE_TIMEOUT_S = 60.0
# What the last files read came to (``mesh_from_bytes``): a cell change rebuilds the cell from
# the project's mesh bytes, which were read already (1.1 s for 80k triangles). Two files: the
# part and a stock; 64 MiB holds two answers of 500k triangles (18 MB each).
PARSED_MEMO = Memo(max_entries=2, max_bytes=64 << 20)
# Contact stiffness measured in the papers (Cibatool 85 N/mm, aluminium 143 N/mm).
CONTACT_STIFFNESS_N_M = {"cast_iron": 100e3, "aluminium": 143e3, "cibatool": 85e3}
# The water-pump plate sits on the table in front of a UR10 (metres, base frame).
DEFAULT_T_BASE_WOBJ = make_transform(np.eye(3), np.array([0.80, 0.16, 0.0]))
# Water-pump geometry: plate, groove and the bolt-boss bumps of the groove's outer wall.
PUMP_PLATE_SIZE_M = (0.250, 0.180, 0.020)
PUMP_GROOVE_WIDTH_M = 0.005
PUMP_GROOVE_DEPTH_M = 0.006
PUMP_WALL_SPACING_M = 0.0004  # facet length of the wall in the mesh


@dataclass(frozen=True)
class Workpiece:
    """A workpiece mesh placed in the cell.

    Attributes:
        name: Built-in name or the file stem.
        mesh: Triangle mesh in the work-object frame, metres.
        T_base_wobj: 4x4 pose of the work-object frame in the robot base frame.
        material: Key of ``CONTACT_STIFFNESS_N_M``.
        contact_stiffness_N_m: Penalty stiffness of tool/part contact.
        friction_coefficient: Coulomb friction along the motion.
        wall: True wall contour in the wobj x-y plane (built-ins only), travelled so that the
            material of the wall is on the right.
        wall_z_m: (low, high) z range of the wall in the wobj frame.
        surface_z_m: z of the top surface (wobj frame).
        reference_mesh: The surface programs are scored against when it differs from
            ``mesh`` (a real casting without its burrs, ``real_part``); None: ``mesh``.
        nominal: The CAD this part deviates from (``real_part.real_workpiece``); None when
            the part is its CAD. Teaching, checks and the scene use ``cad()``.
        deviation_note: How the part deviates from its CAD, for people ("" when it does not).
        unregistered: The CAD where it stood before a work-object calibration moved it to
            ``cad()`` (``registration.registered_workpiece``); None when not calibrated.
    """

    name: str
    mesh: trimesh.Trimesh
    T_base_wobj: np.ndarray
    material: str = "cast_iron"
    contact_stiffness_N_m: float = 100e3
    friction_coefficient: float = 0.15
    wall: Contour | None = None
    wall_z_m: tuple[float, float] = (0.0, 0.0)
    surface_z_m: float = 0.0
    reference_mesh: trimesh.Trimesh | None = None
    nominal: Workpiece | None = None
    deviation_note: str = ""
    unregistered: Workpiece | None = None

    def cad(self) -> Workpiece:
        """The part as its CAD: what the user sees and teaches on (itself when it has no
        deviation)."""
        return self if self.nominal is None else self.nominal

    def scoring_mesh(self) -> trimesh.Trimesh:
        """The surface a program is scored against (``reference_mesh`` or ``mesh``)."""
        return self.mesh if self.reference_mesh is None else self.reference_mesh

    def __getstate__(self) -> dict:
        """Pickled without trimesh's caches: a cached triangle tree (rtree) comes back empty
        from a pickle, and every later distance query on the mesh then fails."""
        state = dict(self.__dict__)
        state["mesh"] = trimesh.Trimesh(self.mesh.vertices, self.mesh.faces, process=False)
        if self.reference_mesh is not None:
            ref = self.reference_mesh
            state["reference_mesh"] = trimesh.Trimesh(ref.vertices, ref.faces, process=False)
        return state

    def __setstate__(self, state: dict) -> None:
        self.__dict__.update(state)

    def mesh_in_base(self) -> trimesh.Trimesh:
        """A copy of the mesh in the robot base frame (metres)."""
        mesh = self.mesh.copy()
        mesh.apply_transform(self.T_base_wobj)
        return mesh

    def placed(self, T_base_wobj: np.ndarray) -> Workpiece:
        """The same workpiece at another work-object pose."""
        T = np.asarray(T_base_wobj, dtype=float)
        if T.shape != (4, 4) or not np.all(np.isfinite(T)):
            raise InvalidInputError("work-object pose must be a finite 4x4 transform")
        if not np.allclose(T[:3, :3] @ T[:3, :3].T, np.eye(3), atol=1e-6):
            raise InvalidInputError("work-object rotation is not orthonormal")
        if self.unregistered is not None:  # a new placement drops the calibration
            base = self.unregistered
            nominal = None if base.mesh is self.mesh else base.placed(T)
            return replace(self, T_base_wobj=T, nominal=nominal, unregistered=None)
        nominal = None if self.nominal is None else self.nominal.placed(T)
        return replace(self, T_base_wobj=T, nominal=nominal)


def water_pump_wall() -> Contour:
    """The outer wall of the water-pump groove: a 200 x 130 mm loop with 14 bolt-boss bumps.

    A filleted polygon (lines + arcs, G1): 6 mm corners, 3 mm fillets at the bumps' feet and
    heads (sharp curvature, where the force spikes) and long straight runs (gentle). Travelled
    counter-clockwise; the wall material (outside of the loop) is on the right.
    """
    half_w, half_h = 0.100, 0.065
    bump_width, bump_height, taper = 0.014, 0.008, 0.005
    corner_r, foot_r, head_r = 0.006, 0.003, 0.003
    corners: list[np.ndarray] = []
    radii: list[float] = []
    sides = [
        ((-half_w, -half_h), (half_w, -half_h), 4),
        ((half_w, -half_h), (half_w, half_h), 3),
        ((half_w, half_h), (-half_w, half_h), 4),
        ((-half_w, half_h), (-half_w, -half_h), 3),
    ]
    for start, end, bumps in sides:
        a, b = np.asarray(start), np.asarray(end)
        d = (b - a) / np.linalg.norm(b - a)
        out = np.array([d[1], -d[0]])  # right of travel = outside of the loop
        corners.append(a)
        radii.append(corner_r)
        for k in range(bumps):
            c = a + (b - a) * (k + 1) / (bumps + 1)
            corners += [
                c - d * (bump_width / 2 + taper),
                c - d * bump_width / 2 + out * bump_height,
                c + d * bump_width / 2 + out * bump_height,
                c + d * (bump_width / 2 + taper),
            ]
            radii += [foot_r, head_r, head_r, foot_r]
    return filleted_polygon(np.array(corners), np.array(radii))


def solid_mesh(mesh: trimesh.Trimesh) -> trimesh.Trimesh:
    """The mesh as one solid: its closed bodies joined by a boolean union (manifold3d).

    A part modelled as stacked or overlapping bodies (a plate and the rim extruded on it) has
    faces inside the material, coincident with real ones and facing the other way: a point
    above the floor but inside the rim is nearest both the floor (facing up) and the rim's
    bottom (facing down), and the side of the part it is on cannot be told from the nearest
    face. A mesh that is one body, or that the union refuses (open bodies), is returned as is.
    """
    bodies = mesh.split(only_watertight=False)
    if len(bodies) < 2 or not all(b.is_watertight for b in bodies):
        return mesh
    try:
        joined = trimesh.boolean.union(bodies, engine="manifold")
    except Exception:  # noqa: BLE001 - the union is an improvement, not a requirement
        return mesh
    return joined if joined.is_watertight and len(joined.faces) else mesh


def _extrude(polygon: shapely.geometry.Polygon, z0: float, height: float) -> trimesh.Trimesh:
    mesh = trimesh.creation.extrude_polygon(polygon, height)
    mesh.apply_translation([0.0, 0.0, z0])
    return mesh


@functools.cache
def _water_pump_mesh() -> trimesh.Trimesh:
    """The pump's solid mesh, built once per process: its union of extrusions took three
    quarters of a new project's 0.15 s. Callers get a copy (``water_pump``)."""
    wall = water_pump_wall()
    sx, sy, sz = PUMP_PLATE_SIZE_M
    floor_z = sz - PUMP_GROOVE_DEPTH_M
    outer = shapely.geometry.Polygon(wall.sample(PUMP_WALL_SPACING_M))
    island = outer.buffer(-PUMP_GROOVE_WIDTH_M, join_style="round", quad_segs=16)
    plate = shapely.geometry.box(-sx / 2, -sy / 2, sx / 2, sy / 2)
    rim = plate.difference(outer)
    # trimesh types concatenate's result as any Geometry; of meshes it is a Trimesh.
    return solid_mesh(
        trimesh.util.concatenate(  # type: ignore[arg-type]
            [
                trimesh.creation.box(
                    extents=(sx, sy, floor_z),
                    transform=make_transform(np.eye(3), np.array([0.0, 0.0, floor_z / 2])),
                ),
                _extrude(rim, floor_z, PUMP_GROOVE_DEPTH_M),
                _extrude(island, floor_z, PUMP_GROOVE_DEPTH_M),
            ]
        )
    )


def water_pump(T_base_wobj: np.ndarray | None = None) -> Workpiece:
    """The water-pump housing: a plate with a 5 mm wide, 6 mm deep contoured groove."""
    wall = water_pump_wall()
    sz = PUMP_PLATE_SIZE_M[2]
    floor_z = sz - PUMP_GROOVE_DEPTH_M
    mesh = _water_pump_mesh().copy()
    return Workpiece(
        name="water_pump",
        mesh=mesh,
        T_base_wobj=DEFAULT_T_BASE_WOBJ.copy() if T_base_wobj is None else T_base_wobj,
        material="cast_iron",
        contact_stiffness_N_m=CONTACT_STIFFNESS_N_M["cast_iron"],
        wall=wall,
        wall_z_m=(floor_z, sz),
        surface_z_m=sz,
    )


def block_wall() -> Contour:
    """Outline of the 150 x 50 mm block (0.2 mm edge radius), anticlockwise seen from above.

    Travelled clockwise the block's material is on the right; the contour is stored in that
    direction so that, as for the pump, the wall is on the right of travel.
    """
    half_l, half_w = 0.075, 0.025
    corners = np.array([[-half_l, -half_w], [-half_l, half_w], [half_l, half_w], [half_l, -half_w]])
    return filleted_polygon(corners, np.full(4, 0.0002))


def block(T_base_wobj: np.ndarray | None = None) -> Workpiece:
    """A 150 x 50 x 40 mm 6063 aluminium block (the chapter's end-milling test piece)."""
    height = 0.040
    mesh = trimesh.creation.box(
        extents=(0.150, 0.050, height),
        transform=make_transform(np.eye(3), np.array([0.0, 0.0, height / 2])),
    )
    return Workpiece(
        name="block",
        mesh=mesh,
        T_base_wobj=DEFAULT_T_BASE_WOBJ.copy() if T_base_wobj is None else T_base_wobj,
        material="aluminium",
        contact_stiffness_N_m=CONTACT_STIFFNESS_N_M["aluminium"],
        wall=block_wall(),
        wall_z_m=(0.0, height),
        surface_z_m=height,
    )


@functools.cache
def _s_groove_solid() -> trimesh.Trimesh:
    """The slot plate's solid mesh, built once per process (as ``_water_pump_mesh``)."""
    return solid_mesh(s_groove_mesh())


def s_groove(T_base_wobj: np.ndarray | None = None) -> Workpiece:
    """A cast-iron plate with the open S-slot (``s_groove``: its geometry and taught wall)."""
    sz = S_GROOVE_PLATE_SIZE_M[2]
    return Workpiece(
        name="s_groove",
        mesh=_s_groove_solid().copy(),
        T_base_wobj=DEFAULT_T_BASE_WOBJ.copy() if T_base_wobj is None else T_base_wobj,
        material="cast_iron",
        contact_stiffness_N_m=CONTACT_STIFFNESS_N_M["cast_iron"],
        wall=s_groove_wall(),
        wall_z_m=(sz - S_GROOVE_DEPTH_M, sz),
        surface_z_m=sz,
    )


def default_T_base_wobj(robot: str | None = None) -> np.ndarray:
    """The built-in placement of a part in front of ``robot`` (``registry.Arm.part_position_m``;
    the UR10's when None or the arm has none)."""
    position = registry.arm(robot).part_position_m if robot and registry.known(robot) else None
    if position is None:
        return DEFAULT_T_BASE_WOBJ.copy()
    return make_transform(np.eye(3), np.array(position))


def builtin_workpiece(
    name: str, T_base_wobj: np.ndarray | None = None, *, robot: str | None = None
) -> Workpiece:
    """A built-in workpiece by name, at ``T_base_wobj`` or the built-in placement for ``robot``."""
    if T_base_wobj is None and robot is not None:
        T_base_wobj = default_T_base_wobj(robot)
    makers = {"water_pump": water_pump, "block": block, "s_groove": s_groove}
    if name not in makers:
        raise UnknownNameError(
            f"unknown workpiece {name!r}; built-ins are {', '.join(WORKPIECE_NAMES)}, "
            "or give a path to an STL/OBJ/PLY file"
        )
    return makers[name](T_base_wobj)


# --- counting triangles before parsing ----------------------------------------------------
# PROBLEM   trimesh builds a whole mesh before its faces can be counted: a 49 MB OBJ with 6.1 M
#           faces cost 1.3 GB before it was refused; three uploads at once, ~4 GB.
# STRATEGY  Count from the raw bytes first, as trimesh will read them, in bounded memory:
#           binary STL: the header's count when the size is 84 + 50 n bytes (else trimesh
#           reads it as ASCII); ASCII STL: "vertex" keywords / 3 (trimesh is case-blind);
#           OBJ: each "f " line with k vertices is a fan of k - 2 triangles; PLY: the header's
#           ``element face N`` (a lower bound: a polygon face gives more than one).
# SOLUTION  ``count_mesh_triangles``; OBJ and ASCII STL are scanned 1 MB at a time and the
#           count stops once it passes the limit. ``mesh_from_bytes`` refuses before parsing,
#           and still checks the parsed mesh (PLY polygons, unusual OBJ lines).

STL_HEADER_BYTES = 84  # 80 header bytes + uint32 triangle count
STL_TRIANGLE_BYTES = 50  # normal, 3 vertices (12 float32) + uint16 attribute
_SCAN_CHUNK_BYTES = 1 << 20
_WHITESPACE = np.zeros(256, dtype=bool)
_WHITESPACE[[9, 10, 11, 12, 13, 32]] = True


def _line_chunks(data: bytes, size: int = _SCAN_CHUNK_BYTES):
    """(start, end) of consecutive pieces of about ``size`` bytes that end after a newline."""
    start = 0
    while start < len(data):
        end = data.find(b"\n", min(start + size, len(data)) - 1)
        end = len(data) if end < 0 else end + 1
        yield start, end
        start = end


def _obj_chunk_triangles(a: np.ndarray) -> int:
    """Triangles of the face lines in ``a`` (uint8 bytes of whole OBJ lines): sum of k - 2."""
    ws = _WHITESPACE[a]
    line_starts = np.flatnonzero(a[:-1] == 10) + 1
    line_starts = np.concatenate(([0], line_starts))
    after = np.minimum(line_starts + 1, len(a) - 1)
    face = (a[line_starts] == ord("f")) & (a[after] == ord(" ")) & (line_starts + 1 < len(a))
    if not face.any():
        return 0
    token_start = ~ws
    token_start[1:] &= ws[:-1]
    tokens_to = np.cumsum(token_start, dtype=np.int32)  # tokens in a[:i + 1]
    line_ends = np.concatenate((line_starts[1:], [len(a)]))
    before = np.where(line_starts > 0, tokens_to[line_starts - 1], 0)
    vertices = (tokens_to[line_ends - 1] - before)[face] - 1  # minus the "f"
    return int(np.maximum(vertices - 2, 0).sum())


def count_mesh_triangles(
    data: bytes, suffix: str, *, stop_above: int | None = None
) -> tuple[int, bool]:
    """The triangles a mesh file holds, counted from its bytes without parsing it.

    Args:
        data: The file's bytes.
        suffix: ".stl", ".obj" or ".ply".
        stop_above: Stop counting once the count passes this (a partial count is returned).

    Returns:
        (count, complete): exact for STL and OBJ when complete; for PLY the faces its header
        declares (a lower bound when faces are polygons). An unrecognized layout counts 0.
    """
    kind = suffix.lower().lstrip(".")
    limit = float("inf") if stop_above is None else stop_above
    if kind == "stl":
        if len(data) >= STL_HEADER_BYTES:
            n = int.from_bytes(data[80:84], "little")
            if STL_HEADER_BYTES + STL_TRIANGLE_BYTES * n == len(data):
                return n, True
        vertices = 0
        for start, end in _line_chunks(data):
            vertices += data[start:end].lower().count(b"vertex")
            if vertices // 3 > limit:
                return vertices // 3, end == len(data)
        return vertices // 3, True
    if kind == "obj":
        face_lines = data.count(b"\nf ") + data.startswith(b"f ")
        if face_lines > limit:  # each face line is at least one triangle
            return face_lines, False
        triangles = 0
        for start, end in _line_chunks(data):
            triangles += _obj_chunk_triangles(np.frombuffer(data, np.uint8, end - start, start))
            if triangles > limit:
                return triangles, end == len(data)
        return triangles, True
    if kind == "ply":
        header_end = data.find(b"end_header", 0, _SCAN_CHUNK_BYTES)
        for line in data[: max(header_end, 0)].splitlines():
            words = line.split()
            if words[:2] == [b"element", b"face"] and len(words) == 3 and words[2].isdigit():
                return int(words[2]), True
    return 0, True


def mesh_from_bytes(
    data: bytes,
    suffix: str,
    *,
    name: str = "uploaded",
    T_base_wobj: np.ndarray | None = None,
    scale: float = 1e-3,
    max_triangles: int = MAX_MESH_TRIANGLES,
) -> Workpiece:
    """A workpiece from the bytes of a mesh file (uploads, ``robomach demo --workpiece F``). A file
    with more than ``max_triangles`` (or three times as many vertices) is refused from its
    bytes, before it is parsed (``count_mesh_triangles``, ``mesh_check.check_mesh_bytes``);
    it is then read in an isolated process within ``PARSE_MEMORY_BYTES`` and
    ``PARSE_TIMEOUT_S`` (``parse_mesh_file``: a degenerate file that costs minutes or
    gigabytes there is refused, the caller unharmed; issue 32). The answer for the same
    bytes and options is kept (``PARSED_MEMO``; a refusal is not): a cell change that keeps
    the part reads it once. The hull corners the isolated check found are remembered for the
    supervisor (``bvh.placed_convex_hull``)."""
    from ..isolation import IsolatedError, run_isolated

    kind = suffix.lower().lstrip(".")
    if f".{kind}" not in MESH_SUFFIXES:
        raise MeshFileError(f"{name}: unsupported mesh type {suffix!r}")
    counted, complete = count_mesh_triangles(data, kind, stop_above=max_triangles)
    if counted > max_triangles:
        raise MeshFileError(
            f"{name}: {'at least ' if not complete else ''}{counted} triangles exceed the "
            f"limit of {max_triangles} (simplify the mesh)"
        )
    check_mesh_bytes(data, kind, name, max_triangles=max_triangles)
    key = digest("parsed mesh", data, kind, name, float(scale), int(max_triangles))
    answer = PARSED_MEMO.get(key)
    if answer is None:
        payload = {"data": bytes(data), "kind": kind, "name": name, "scale": float(scale),
                   "max_triangles": int(max_triangles)}  # fmt: skip
        try:
            answer = run_isolated(
                parse_mesh_file,
                payload,
                memory_bytes=PARSE_MEMORY_BYTES,
                timeout_s=PARSE_TIMEOUT_S,
                name="mesh reading",
            )
        except IsolatedError as exc:
            if exc.error_type == MeshFileError.__name__:
                raise MeshFileError(exc.detail) from None
            raise MeshFileError(f"{name}: this mesh cannot be read ({exc}); simplify it") from None
        for array in answer["arrays"].values():
            array.flags.writeable = False  # kept: every caller gets copies
        PARSED_MEMO.put(key, answer, sum(a.nbytes for a in answer["arrays"].values()))
    arrays = answer["arrays"]
    vertices = arrays["vertices"].copy()
    mesh = trimesh.Trimesh(vertices, arrays["faces"].copy(), process=False)
    if "hull_corner_indices" in arrays:  # the isolated check's qhull: not run again
        remember_hull_corners(vertices, arrays["hull_corner_indices"])
    z_top = float(answer["z_top_m"])
    return Workpiece(
        name=name,
        mesh=mesh,
        T_base_wobj=DEFAULT_T_BASE_WOBJ.copy() if T_base_wobj is None else T_base_wobj,
        surface_z_m=z_top,
        wall_z_m=(float(answer["z_low_m"]), z_top),
    )


def parse_mesh_file(payload: dict) -> dict:
    """The isolated half of ``mesh_from_bytes`` (run by ``isolation.run_isolated``): parse
    the file, check it (``mesh_check.check_mesh``: duplicate faces dropped, too many bodies
    refused before any split, the native steps run here) and make it one solid. Returns
    ``z_top_m``, ``z_low_m`` and ``arrays`` (``vertices`` (n, 3) m, ``faces`` (m, 3), and
    ``hull_corner_indices`` (k,): the rows of ``vertices`` the check's qhull found as the
    hull's corners, when the solid is the mesh checked)."""
    import io

    data, kind, name = payload["data"], payload["kind"], payload["name"]
    max_triangles = payload["max_triangles"]
    try:
        loaded = trimesh.load(io.BytesIO(data), file_type=kind, force="mesh", process=True)
    except Exception as exc:  # trimesh raises many types for corrupt files
        raise MeshFileError(
            f"{name}: cannot read as {kind.upper()} ({exc.__class__.__name__})"
        ) from None
    if not isinstance(loaded, trimesh.Trimesh) or len(loaded.faces) == 0:
        raise MeshFileError(f"{name}: the file holds no triangles")
    if len(loaded.faces) > max_triangles:
        raise MeshFileError(
            f"{name}: {len(loaded.faces)} triangles exceed the limit of {max_triangles}"
        )
    if not np.all(np.isfinite(loaded.vertices)):
        raise MeshFileError(f"{name}: the mesh has non-finite vertices (NaN or infinity)")
    loaded.apply_scale(payload["scale"])
    check_mesh(loaded, name, native="here")  # size, thickness, bodies, the native steps
    z_top = float(loaded.bounds[1, 2])
    loaded = solid_mesh(loaded)
    arrays = {
        "vertices": np.asarray(loaded.vertices, dtype=np.float64),
        "faces": np.asarray(loaded.faces, dtype=np.int64),
    }
    corners = hull_corner_indices(arrays["vertices"])  # the check's, unless solid_mesh joined
    if corners is not None:
        arrays["hull_corner_indices"] = corners
    return {"z_top_m": z_top, "z_low_m": float(loaded.bounds[0, 2]), "arrays": arrays}
