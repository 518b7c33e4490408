"""The part in the cell is not its CAD: a fixture error and casting deviations.

PROBLEM   In the simulated cell the part is exactly its mesh, so a program planned from the mesh
          alone would be perfect and path learning (chapter section 3) would look like a detour.
          A real casting differs from its CAD by tenths of a millimetre (the wall offset varies
          along the contour; burrs stand off it), and its fixture places it a few millimetres
          and a degree or two off.
STRATEGY  A seeded ``PartDeviation`` (one value of the cell settings) turns the CAD mesh into
          the real one, expressed in the nominal work-object frame (the frame the program is
          written in, so its error is the part's):
            - casting: a smooth in-plane warp p -> p + A(x, y), a few random Fourier modes of
              40-160 mm wavelength scaled so that |A| <= ``wall_offset_mm`` over the part; a
              wall then moves by A . n, varying smoothly along the contour. Wall edges longer
              than ``REFINE_EDGE_M`` (across) are split first, so straight walls bend too;
            - burrs: gaussian bumps (``burr_height_mm`` high, ~3 mm wide) standing off the wall
              at seeded places, over the wall's whole height;
            - fixture: a rigid motion, a translation mostly in the table plane and a rotation
              about the vertical through the work-object origin.
SOLUTION  ``real_workpiece(cad, deviation) -> Workpiece``: ``mesh`` is what the cutter touches
          (with burrs), ``reference_mesh`` the casting without its burrs (the wall a program is
          scored against), ``wall`` the real contour of a built-in part (a polyline), and
          ``nominal`` the CAD it came from. The ``Cell`` is built with it; teaching, the checks
          and the scene use ``workpiece.cad()``.
"""

from __future__ import annotations

import hashlib
import math
import threading
import weakref
from dataclasses import asdict, dataclass, replace

import numpy as np
import trimesh

from ..errors import InvalidInputError
from ..limits import (
    BURR_COUNT,
    BURR_HEIGHT_MM,
    FIXTURE_ROTATION_DEG,
    FIXTURE_SHIFT_MM,
    SEED,
    WALL_OFFSET_MM,
)
from ..transforms import make_transform, rotation_about
from .contour import Arc, Contour, Line
from .workpiece import Workpiece

REFINE_EDGE_M = 0.0005  # wall edges longer than this across (x-y) are split before the warp
WALL_NORMAL_Z_MAX = 0.5  # a face whose normal has |z| below this is a wall
WARP_MODES = 6
WARP_WAVELENGTH_M = (0.040, 0.160)
BURR_SIGMA_M = 0.0012  # gaussian width of a burr along the wall (about 3 mm at half height)
FIXTURE_Z_FRACTION = 0.1  # the vertical shift is this fraction of the in-plane one at most
CONTOUR_SPACING_M = 1e-4  # the real contour of a built-in part: a polyline this fine


@dataclass(frozen=True)
class PartDeviation:
    """How the real part differs from its CAD (mm and degrees at this boundary).

    The defaults are the documented ``realistic`` preset; a cell without deviation has None.

    Attributes:
        seed: Seed of every draw below.
        fixture_shift_mm: Largest in-plane translation of the fixture error; the drawn one is
            between half of it and all of it, in a seeded direction (plus a tenth of it at
            most vertically).
        fixture_rotation_deg: Largest rotation about the vertical (through the work-object
            origin); the drawn one is between half of it and all of it, either way.
        wall_offset_mm: Largest casting offset of a wall (the smooth warp's amplitude).
        burrs: Number of burrs on the part's walls.
        burr_height_mm: Height of each burr off the wall.
    """

    seed: int = 0
    fixture_shift_mm: float = 4.0
    fixture_rotation_deg: float = 2.0
    wall_offset_mm: float = 0.5
    burrs: int = 6
    burr_height_mm: float = 0.1

    def __post_init__(self) -> None:
        SEED.check(self.seed)
        FIXTURE_SHIFT_MM.check(self.fixture_shift_mm)
        FIXTURE_ROTATION_DEG.check(self.fixture_rotation_deg)
        WALL_OFFSET_MM.check(self.wall_offset_mm)
        BURR_COUNT.check(self.burrs)
        BURR_HEIGHT_MM.check(self.burr_height_mm)

    @classmethod
    def realistic(cls, seed: int = 0) -> PartDeviation:
        """The ``realistic`` preset: a fixture error of 2-4 mm and 1-2 deg (a casting in its
        fixture), walls within +-0.5 mm of the CAD, six 0.1 mm burrs. Points taught on the CAD
        at its placement land on the rim of the water pump's 5 mm groove: the work object is
        measured on the part first (``registration``: touches of the real part, the CAD
        registered to them), as on a real cell."""
        return cls(seed=int(seed))

    @classmethod
    def from_value(cls, value: object) -> PartDeviation | None:
        """A deviation from itself, a dict (a saved document) or None."""
        if value is None or isinstance(value, PartDeviation):
            return value
        if isinstance(value, dict):
            known = set(cls.__dataclass_fields__)
            unknown = set(value) - known
            if unknown:
                raise InvalidInputError(f"unknown part deviation fields {sorted(unknown)}")
            return cls(**value)
        raise InvalidInputError("a part deviation is a dict of its fields, or null")

    def as_dict(self) -> dict:
        return asdict(self)


@dataclass(frozen=True)
class FixtureError:
    """The drawn fixture error: the real part = R_z(rotation) p + shift (work-object frame)."""

    shift_m: np.ndarray
    rotation_rad: float

    @property
    def transform(self) -> np.ndarray:
        """4x4 pose of the real part in the nominal work-object frame."""
        return make_transform(rotation_about("z", self.rotation_rad), self.shift_m)

    def describe(self) -> str:
        x, y, z = self.shift_m * 1e3
        return (
            f"fixture error {math.hypot(x, y):.2f} mm in the table plane "
            f"({x:+.2f}, {y:+.2f}, {z:+.2f} mm) and {math.degrees(self.rotation_rad):+.2f} deg "
            "about the vertical"
        )


def fixture_error(deviation: PartDeviation) -> FixtureError:
    """The seeded fixture error of ``deviation``."""
    rng = np.random.default_rng([deviation.seed, 1])
    shift = deviation.fixture_shift_mm * 1e-3 * rng.uniform(0.5, 1.0)
    direction = rng.uniform(0.0, 2.0 * math.pi)
    dz = deviation.fixture_shift_mm * 1e-3 * FIXTURE_Z_FRACTION * rng.uniform(-1.0, 1.0)
    angle = math.radians(deviation.fixture_rotation_deg) * rng.uniform(0.5, 1.0)
    angle *= 1.0 if rng.uniform() < 0.5 else -1.0
    return FixtureError(
        np.array([shift * math.cos(direction), shift * math.sin(direction), dz]), angle
    )


class CastingWarp:
    """The smooth in-plane warp A(x, y) of a casting (module docstring): |A| <= amplitude over
    the box ``bounds_xy`` (2, 2) the warp was scaled on."""

    def __init__(self, deviation: PartDeviation, bounds_xy: np.ndarray) -> None:
        rng = np.random.default_rng([deviation.seed, 2])
        angles = rng.uniform(0.0, 2.0 * math.pi, (WARP_MODES, 2))
        self._wave = np.stack([np.cos(angles[:, 0]), np.sin(angles[:, 0])], 1)
        self._wave /= rng.uniform(*WARP_WAVELENGTH_M, WARP_MODES)[:, None] / (2.0 * math.pi)
        self._push = np.stack([np.cos(angles[:, 1]), np.sin(angles[:, 1])], 1)
        self._phase = rng.uniform(0.0, 2.0 * math.pi, WARP_MODES)
        self._weight = rng.uniform(0.5, 1.0, WARP_MODES)
        lo, hi = np.asarray(bounds_xy, dtype=float)
        grid = np.stack(
            np.meshgrid(np.linspace(lo[0], hi[0], 60), np.linspace(lo[1], hi[1], 60)), -1
        ).reshape(-1, 2)
        peak = float(np.linalg.norm(self._raw(grid), axis=1).max())
        self._scale = deviation.wall_offset_mm * 1e-3 / peak if peak > 0 else 0.0

    def _raw(self, xy: np.ndarray) -> np.ndarray:
        s = np.sin(xy @ self._wave.T + self._phase) * self._weight
        return s @ self._push

    def __call__(self, xy: np.ndarray) -> np.ndarray:
        """(n, 2) displacement [m] at (n, 2) points [m]."""
        return self._raw(np.asarray(xy, dtype=float)) * self._scale


# --- refining the walls -------------------------------------------------------------------


def _wall_faces(vertices: np.ndarray, faces: np.ndarray) -> np.ndarray:
    """(f,) True for faces within 60 deg of vertical (their normal's |z| < 0.5)."""
    tri = vertices[faces]
    n = np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0])
    length = np.linalg.norm(n, axis=1)
    with np.errstate(invalid="ignore", divide="ignore"):
        nz = np.abs(n[:, 2]) / length
    return (length > 0) & (nz < WALL_NORMAL_Z_MAX)


def _slab_triangles(tri: np.ndarray, u: np.ndarray, step: float) -> np.ndarray:
    """(k, 3, 3) pieces of one triangle cut by the planes u . p = j * step (all integers j).

    With the triangle's corners sorted by s = u . p (s0 <= s1 <= s2), a slab [a, b] is the
    quadrilateral between the long edge 0-2 and the short chain 0-1-2 at a and b, plus corner 1
    when it lies inside the slab; each is cut into triangles from the long edge's point at a.
    """
    s = tri @ u
    order = np.argsort(s)
    p0, p1, p2 = tri[order]
    s0, s1, s2 = s[order]
    cuts = np.arange(math.floor(s0 / step) + 1, math.ceil(s2 / step)) * step
    sliver = 0.05 * step  # no slab thinner than this at the triangle's ends
    bounds = np.concatenate([[s0], cuts[(cuts > s0 + sliver) & (cuts < s2 - sliver)], [s2]])

    def long_edge(x: np.ndarray) -> np.ndarray:
        t = (x - s0) / (s2 - s0)
        return p0 + t[:, None] * (p2 - p0)

    def short_chain(x: np.ndarray) -> np.ndarray:
        first = (x - s0) / max(s1 - s0, 1e-15)
        second = (x - s1) / max(s2 - s1, 1e-15)
        a = p0 + np.clip(first, 0, 1)[:, None] * (p1 - p0)
        b = p1 + np.clip(second, 0, 1)[:, None] * (p2 - p1)
        return np.where((x < s1)[:, None], a, b)

    a, b = bounds[:-1], bounds[1:]
    la, lb, sa, sb = long_edge(a), long_edge(b), short_chain(a), short_chain(b)
    inside = (a < s1) & (s1 < b)
    pieces = [np.stack([la, lb, sb], 1), np.stack([la, sb, sa], 1)]
    if inside.any():  # corner 1 splits the second piece in two
        v1 = np.broadcast_to(p1, la[inside].shape)
        pieces[1][inside] = np.stack([la[inside], sb[inside], v1], 1)
        pieces.append(np.stack([la[inside], v1, sa[inside]], 1))
    out = np.concatenate(pieces)
    area = np.linalg.norm(np.cross(out[:, 1] - out[:, 0], out[:, 2] - out[:, 0]), axis=1)
    return out[area > 1e-14]


def refine_walls(
    vertices: np.ndarray, faces: np.ndarray, max_across_m: float = REFINE_EDGE_M
) -> tuple[np.ndarray, np.ndarray]:
    """Wall faces wider than ``max_across_m`` (in x-y) cut into vertical slabs that wide.

    The slabs of one wall plane are cut at the same planes (u . p = j step, u the wall's
    horizontal direction with a fixed sign), so the two triangles of a wall quad still meet
    vertex to vertex; the faces round a wall (floor, top) keep their straight edges, so the
    warp opens cracks of a few hundredths to tenths of a millimetre along the top and bottom
    of long walls, where the cutter at the machining height never goes.
    """
    v = np.asarray(vertices, dtype=float)
    f = np.asarray(faces, dtype=np.int64)
    tri = v[f]
    normal = np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0])
    wall = _wall_faces(v, f)
    # Every wall face is cut at the planes that cross it, narrow ones too: a narrow face beside
    # a wide one in the same wall then shares its cut points (no crack after the warp).
    across = np.linalg.norm(np.ptp(tri[:, :, :2], axis=1), axis=1)
    if not (wall & (across > max_across_m)).any():
        return v, f
    # u per face, then whether a plane u . p = j step crosses it (inside its slivers' margin).
    u = np.stack([-normal[:, 1], normal[:, 0], np.zeros(len(f))], axis=1)
    u /= np.maximum(np.linalg.norm(u, axis=1, keepdims=True), 1e-300)
    flip = (u[:, 0] < -1e-12) | ((np.abs(u[:, 0]) <= 1e-12) & (u[:, 1] < 0))
    u[flip] *= -1.0
    s = np.einsum("fkj,fj->fk", tri, u)
    lo = s.min(axis=1) + 0.05 * max_across_m
    hi = s.max(axis=1) - 0.05 * max_across_m
    crossed = np.floor(hi / max_across_m) >= np.ceil(lo / max_across_m)
    wide = wall & (across > 1e-9) & crossed
    if not wide.any():
        return v, f
    new = []
    for i in np.flatnonzero(wide):
        n = normal[i]
        pieces = _slab_triangles(tri[i], u[i], max_across_m)
        flip = np.cross(pieces[:, 1] - pieces[:, 0], pieces[:, 2] - pieces[:, 0]) @ n < 0
        pieces[flip] = pieces[flip][:, [0, 2, 1]]
        new.append(pieces)
    pieces = np.concatenate(new)
    merged = trimesh.Trimesh(
        np.vstack([v, pieces.reshape(-1, 3)]),
        np.vstack([f[~wide], len(v) + np.arange(3 * len(pieces)).reshape(-1, 3)]),
        process=False,
    )
    merged.merge_vertices(digits_vertex=10)
    return np.asarray(merged.vertices), np.asarray(merged.faces)


# --- burrs ---------------------------------------------------------------------------------


def _burr_sites(
    cad: Workpiece, vertices: np.ndarray, faces: np.ndarray, deviation: PartDeviation
) -> tuple[np.ndarray, np.ndarray]:
    """(k, 2) centres and (k, 2) free-side normals of the burrs, in the work-object x-y plane:
    along the true wall of a built-in part, else on wall faces picked by area."""
    rng = np.random.default_rng([deviation.seed, 3])
    if deviation.burrs == 0:
        return np.zeros((0, 2)), np.zeros((0, 2))
    if cad.wall is not None:
        pts = cad.wall.sample(2e-4)
        seg = np.roll(pts, -1, axis=0) - pts
        tangent = seg / np.maximum(np.linalg.norm(seg, axis=1, keepdims=True), 1e-12)
        left = np.stack([-tangent[:, 1], tangent[:, 0]], 1)  # the free side: material right
        idx = np.sort(rng.choice(len(pts) - 1, deviation.burrs, replace=False))
        return pts[idx], left[idx]
    wall = np.flatnonzero(_wall_faces(vertices, faces))
    if len(wall) == 0:
        return np.zeros((0, 2)), np.zeros((0, 2))
    tri = vertices[faces[wall]]
    normal = np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0])
    area = np.linalg.norm(normal, axis=1)
    chosen = rng.choice(len(wall), deviation.burrs, p=area / area.sum())
    centres = tri[chosen].mean(axis=1)[:, :2]
    n = normal[chosen, :2]
    return centres, n / np.maximum(np.linalg.norm(n, axis=1, keepdims=True), 1e-12)


def _burr_displacement(
    points: np.ndarray,
    point_normals: np.ndarray,
    centres: np.ndarray,
    normals: np.ndarray,
    height_m: float,
) -> np.ndarray:
    """(n, 2) in-plane displacement of wall vertices by the burrs (only vertices whose wall
    faces the burr's way: the opposite wall of a narrow groove stays where it is)."""
    out = np.zeros((len(points), 2))
    for c, n in zip(centres, normals, strict=True):
        d2 = np.sum((points - c) ** 2, axis=1)
        near = (d2 < (5 * BURR_SIGMA_M) ** 2) & (point_normals @ n > 0.5)
        out[near] += height_m * np.exp(-d2[near] / (2 * BURR_SIGMA_M**2))[:, None] * n
    return out


def _vertex_wall_normals(vertices: np.ndarray, faces: np.ndarray) -> np.ndarray:
    """(n, 2) mean x-y normal of the wall faces at each vertex (zero off the walls)."""
    wall = _wall_faces(vertices, faces)
    tri = vertices[faces[wall]]
    normal = np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0])[:, :2]
    normal /= np.maximum(np.linalg.norm(normal, axis=1, keepdims=True), 1e-12)
    out = np.zeros((len(vertices), 2))
    for k in range(3):
        np.add.at(out, faces[wall][:, k], normal)
    norm = np.linalg.norm(out, axis=1, keepdims=True)
    return np.where(norm > 1e-12, out / np.maximum(norm, 1e-12), 0.0)


# --- the real part -------------------------------------------------------------------------


def _apply_fixture(points: np.ndarray, fixture: FixtureError) -> np.ndarray:
    T = fixture.transform
    return points @ T[:3, :3].T + T[:3, 3]


def real_contour(contour: Contour, warp: CastingWarp, fixture: FixtureError) -> Contour:
    """The real wall of a built-in part: its contour warped and moved like the mesh, as a
    polyline (arcs sampled at a tenth of their radius, so the polyline's offset stays within
    a few micrometres of the true one)."""
    points = []
    for piece in contour.pieces:
        spacing = CONTOUR_SPACING_M
        if isinstance(piece, Arc):
            spacing = min(spacing, 0.1 * piece.radius)
        m = max(2, int(np.ceil(piece.length / spacing)) + 1)
        points.append(piece.point_at(np.linspace(0.0, piece.length, m))[:-1])
    if not contour.closed:
        last = contour.pieces[-1]
        points.append(last.point_at(np.array([last.length])))
    xy = np.vstack(points)
    xy = xy + warp(xy)
    xyz = _apply_fixture(np.column_stack([xy, np.zeros(len(xy))]), fixture)[:, :2]
    if contour.closed:
        xyz = np.vstack([xyz, xyz[:1]])
    lines = tuple(
        Line(tuple(a), tuple(b))
        for a, b in zip(xyz[:-1], xyz[1:], strict=True)
        if np.linalg.norm(b - a) > 1e-9
    )
    return Contour(lines, closed=contour.closed)


# Real parts by (CAD fingerprint, deviation), kept while something uses them (the live cell):
# a list of the last eight held eight parts' meshes, uploads of 500k triangles too (issue 32).
_CACHE: weakref.WeakValueDictionary[tuple[str, PartDeviation], Workpiece] = (
    weakref.WeakValueDictionary()
)
_CACHE_LOCK = threading.Lock()


def _real(cad: Workpiece, deviation: PartDeviation) -> Workpiece:
    vertices, faces = refine_walls(cad.mesh.vertices, cad.mesh.faces)
    bounds = np.array([vertices[:, :2].min(axis=0), vertices[:, :2].max(axis=0)])
    warp = CastingWarp(deviation, bounds)
    fixture = fixture_error(deviation)
    cast = vertices.copy()
    cast[:, :2] += warp(vertices[:, :2])
    centres, normals = _burr_sites(cad, vertices, faces, deviation)
    burred = cast.copy()
    if len(centres):
        burred[:, :2] += _burr_displacement(
            vertices[:, :2],
            _vertex_wall_normals(vertices, faces),
            centres,
            normals,
            deviation.burr_height_mm * 1e-3,
        )
    mesh = trimesh.Trimesh(_apply_fixture(burred, fixture), faces, process=False)
    reference = trimesh.Trimesh(_apply_fixture(cast, fixture), faces, process=False)
    dz = float(fixture.shift_m[2])
    return replace(
        cad,
        mesh=mesh,
        reference_mesh=reference,
        wall=None if cad.wall is None else real_contour(cad.wall, warp, fixture),
        wall_z_m=(cad.wall_z_m[0] + dz, cad.wall_z_m[1] + dz),
        surface_z_m=cad.surface_z_m + dz,
        nominal=cad,
        deviation_note=fixture.describe()
        + f"; walls within {deviation.wall_offset_mm:g} mm of the CAD, {deviation.burrs} "
        f"burrs of {deviation.burr_height_mm:g} mm",
    )


def _part_key(cad: Workpiece) -> str:
    """Fingerprint of a CAD part: its mesh, placement and wall (a cache key)."""
    h = hashlib.blake2b(digest_size=16)
    for a in (cad.mesh.vertices, cad.mesh.faces, cad.T_base_wobj):
        h.update(np.ascontiguousarray(a).tobytes())
    h.update(repr((cad.name, cad.wall is not None, cad.wall_z_m, cad.surface_z_m)).encode())
    return h.hexdigest()


def real_workpiece(cad: Workpiece, deviation: PartDeviation | None) -> Workpiece:
    """The part the cell's contact meets: ``cad`` itself without a deviation, else the real
    part (module docstring). Built once per (part, deviation) and cached."""
    if deviation is None:
        return cad
    if cad.nominal is not None:
        raise InvalidInputError("the part already deviates from its CAD")
    key = (_part_key(cad), deviation)
    with _CACHE_LOCK:
        real = _CACHE.get(key)
    if real is not None:
        return real
    real = _real(cad, deviation)
    with _CACHE_LOCK:
        _CACHE[key] = real
    return real
