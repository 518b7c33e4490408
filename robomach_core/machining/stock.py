"""The stock: the part before machining, as an allowance beyond the nominal wall along the path.

The allowance a(s) [m] is the thickness of material the cut must remove, measured from the
nominal wall along its normal (towards the tool) at arc length s of the program's TCP path.
Castings carry a smoothly varying allowance (here 0.3 to 3 mm) plus burrs: short lumps of
extra material a few millimetres long. A stock is built three ways:

- ``builtin_stock``: generated from a seed (smooth allowance + raised-cosine burrs);
- ``stock_from_profile``: a user profile [(s_mm, allowance_mm), ...], linear in between;
- ``stock_from_mesh``: a stock mesh paired with the nominal part; the allowance is where a ray
  from just inside the nominal wall, along the normal, leaves the stock.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
import trimesh

from ..cell import Tool
from ..transforms import arc_length_m
from .errors import StockError
from .path import check_normals, check_path, wall_normals_from_path

MM = 1e-3
# Built-in stock: smooth allowance range, burr heights and lengths [m], burrs per metre of path.
ALLOWANCE_RANGE_M = (0.3 * MM, 3.0 * MM)
BURR_HEIGHT_RANGE_M = (0.5 * MM, 2.0 * MM)
BURR_LENGTH_RANGE_M = (4.0 * MM, 8.0 * MM)
BURRS_PER_M = 10.0
# Wavelengths of the smooth allowance variation [m] (a casting's slow wander).
ALLOWANCE_WAVELENGTHS_M = (0.09, 0.17, 0.31, 0.53)
# The built-in stock's allowance rises from zero over this much path at the start [m].
LEAD_IN_M = 5.0 * MM
# Resolution of the allowance profile [m]; burrs are resolved by ~20 points.
PROFILE_SPACING_M = 0.1 * MM
# A user allowance beyond this is not an allowance but a different part [m].
MAX_ALLOWANCE_M = 20.0 * MM
# A user profile: at most this many points, along at most this much path [mm].
MAX_PROFILE_POINTS = 100_000
MAX_PROFILE_S_MM = 100_000.0
# Ray casting of a stock mesh: start this far inside the nominal wall, search this far out [m].
RAY_INSET_M = 0.05 * MM
RAY_RANGE_M = MAX_ALLOWANCE_M
# Display: height of the stock ribbon across the path (the groove depth of the water pump) [m].
RIBBON_HEIGHT_M = 6.0 * MM


@dataclass(frozen=True)
class Burr:
    """A raised-cosine lump of extra material centred at ``center_m`` along the path."""

    center_m: float
    length_m: float
    height_m: float

    def profile(self, s_m: np.ndarray) -> np.ndarray:
        """Extra allowance [m] at ``s_m``: h (1 + cos(2 pi (s - c) / L)) / 2 within L of c."""
        x = (np.asarray(s_m, dtype=float) - self.center_m) / self.length_m
        return np.where(np.abs(x) < 0.5, 0.5 * self.height_m * (1.0 + np.cos(2 * np.pi * x)), 0.0)


@dataclass(frozen=True, eq=False)
class Stock:
    """The part before machining along a path.

    Attributes:
        path_points_m: (n, 3) the program's TCP path (base frame).
        wall_normals_m: (n, 3) unit wall normals at the path points, pointing at the tool.
        tool_radius_m: The cutter radius; the nominal wall is the path moved back by it.
        profile_s_m: (k,) arc lengths of the allowance profile, increasing, from 0.
        profile_allowance_m: (k,) allowance at ``profile_s_m`` (burrs included).
        burrs: The burrs of a built-in stock (empty for profiles and meshes).
        source: ``"builtin"``, ``"profile"`` or ``"mesh"``.
        material_factor: The casting's material coefficient relative to the nominal one: it
            scales the process gain K of the cut (1.0: the material the process was fitted on).
    """

    path_points_m: np.ndarray
    wall_normals_m: np.ndarray
    tool_radius_m: float
    profile_s_m: np.ndarray
    profile_allowance_m: np.ndarray
    burrs: tuple[Burr, ...] = ()
    source: str = "builtin"
    material_factor: float = 1.0

    @property
    def path_s_m(self) -> np.ndarray:
        """(n,) arc length of the path points [m]."""
        return arc_length_m(self.path_points_m)

    @property
    def path_length_m(self) -> float:
        """Length of the path [m]."""
        return float(arc_length_m(self.path_points_m)[-1])

    @property
    def max_allowance_m(self) -> float:
        """The deepest cut the stock asks for [m] (burrs included)."""
        return float(np.max(self.profile_allowance_m))

    def allowance_m(self, s_m: np.ndarray | float) -> np.ndarray:
        """Allowance [m] at arc lengths ``s_m`` (linear between profile points, flat beyond)."""
        return np.interp(s_m, self.profile_s_m, self.profile_allowance_m)

    def wall_points_m(self) -> np.ndarray:
        """(n, 3) points of the nominal wall: the path moved back along the normal by r."""
        return self.path_points_m - self.tool_radius_m * self.wall_normals_m

    def surface_points_m(self, spacing_m: float = 0.5 * MM) -> np.ndarray:
        """(m, 3) points of the stock surface (nominal wall + allowance), every ~``spacing_m``.

        Between path points the wall and its normal are interpolated linearly along the path.
        """
        s_path = arc_length_m(self.path_points_m)
        s = np.linspace(0.0, s_path[-1], max(2, int(np.ceil(s_path[-1] / spacing_m)) + 1))
        wall = self.wall_points_m()
        w = np.stack([np.interp(s, s_path, wall[:, i]) for i in range(3)], axis=1)
        n = np.stack([np.interp(s, s_path, self.wall_normals_m[:, i]) for i in range(3)], axis=1)
        n /= np.linalg.norm(n, axis=1, keepdims=True)
        return w + self.allowance_m(s)[:, None] * n

    def ribbon_mesh(
        self,
        *,
        spacing_m: float = 0.5 * MM,
        height_m: float = RIBBON_HEIGHT_M,
        up: tuple[float, float, float] = (0.0, 0.0, 1.0),
    ) -> tuple[np.ndarray, np.ndarray]:
        """A thin band on the stock surface for the 3D scene: (vertices (2m, 3), faces (f, 3)).

        The band spans ``height_m`` along ``up`` centred on the path height; face indices are
        int32 into the vertices, two triangles per step along the path.
        """
        top = self.surface_points_m(spacing_m)
        half = 0.5 * height_m * np.asarray(up, dtype=float)
        vertices = np.vstack([top - half, top + half])
        m = len(top)
        i = np.arange(m - 1)
        faces = np.vstack(
            [np.stack([i, i + 1, m + i], axis=1), np.stack([i + 1, m + i + 1, m + i], axis=1)]
        )
        return vertices, faces.astype(np.int32)


def _path_and_normals(
    path_points_m: np.ndarray, wall_normals_m: np.ndarray | None
) -> tuple[np.ndarray, np.ndarray]:
    p = check_path(path_points_m)
    n = (
        wall_normals_from_path(p)
        if wall_normals_m is None
        else check_normals(wall_normals_m, len(p))
    )
    return p, n


def _check_radius(tool_radius_m: float) -> float:
    if not (0.0 < tool_radius_m < 0.05):
        raise StockError(f"tool radius must be in (0, 50) mm, got {tool_radius_m / MM:g} mm")
    return float(tool_radius_m)


def builtin_stock(
    path_points_m: np.ndarray,
    seed: int,
    *,
    wall_normals_m: np.ndarray | None = None,
    tool_radius_m: float = Tool().radius_m,
    allowance_range_m: tuple[float, float] = ALLOWANCE_RANGE_M,
    burrs_per_m: float = BURRS_PER_M,
) -> Stock:
    """A casting's stock along the path, generated from ``seed``.

    The smooth allowance is a sum of four sinusoids of random phase (wavelengths 90-530 mm),
    scaled to span ``allowance_range_m``; ``round(burrs_per_m * length)`` burrs (at least one),
    2-6 mm long and 0.5-2 mm high, sit at random places clear of each other and of the path
    ends. The allowance rises from zero over the first ``LEAD_IN_M`` (the lead-in).
    """
    p, n = _path_and_normals(path_points_m, wall_normals_m)
    lo, hi = allowance_range_m
    if not (0.0 <= lo < hi <= MAX_ALLOWANCE_M):
        raise StockError(
            f"allowance range must satisfy 0 <= low < high <= {MAX_ALLOWANCE_M / MM:g} mm"
        )
    rng = np.random.default_rng(seed)
    length = float(arc_length_m(p)[-1])
    s = np.linspace(0.0, length, max(2, int(np.ceil(length / PROFILE_SPACING_M)) + 1))
    wave = sum(
        (
            np.sin(2 * np.pi * s / lam + rng.uniform(0.0, 2 * np.pi))
            for lam in ALLOWANCE_WAVELENGTHS_M
        ),
        np.zeros_like(s),
    )
    wave = (wave - wave.min()) / max(float(np.ptp(wave)), 1e-12)
    allowance = lo + (hi - lo) * wave
    count = max(1, int(round(burrs_per_m * length)))
    burrs: list[Burr] = []
    for _ in range(50 * count):
        if len(burrs) == count:
            break
        blen = rng.uniform(*BURR_LENGTH_RANGE_M)
        centre = rng.uniform(LEAD_IN_M + blen, max(length - blen, LEAD_IN_M + blen))
        height = rng.uniform(*BURR_HEIGHT_RANGE_M)
        # Burrs do not overlap: a lump is 0.5-2 mm, not the sum of two.
        if all(abs(centre - b.center_m) > blen + b.length_m for b in burrs):
            burrs.append(Burr(float(centre), float(blen), float(height)))
    burrs.sort(key=lambda b: b.center_m)
    for burr in burrs:
        allowance = allowance + burr.profile(s)
    # Lead-in: the learned path starts where the operator touched a clean wall, so the cutter
    # enters the allowance over the first few millimetres instead of starting buried in it.
    ramp = np.clip(s / LEAD_IN_M, 0.0, 1.0)
    allowance = allowance * 0.5 * (1.0 - np.cos(np.pi * ramp))
    return Stock(p, n, _check_radius(tool_radius_m), s, allowance, tuple(burrs), "builtin")


def stock_from_profile(
    path_points_m: np.ndarray,
    profile_mm: Sequence[tuple[float, float]],
    *,
    wall_normals_m: np.ndarray | None = None,
    tool_radius_m: float = Tool().radius_m,
) -> Stock:
    """A stock from a user allowance profile [(s_mm, allowance_mm), ...].

    Arc lengths must increase strictly and lie on the path; allowances in [0, 20] mm. Linear
    between the points, flat before the first and after the last.
    """
    p, n = _path_and_normals(path_points_m, wall_normals_m)
    table = np.asarray(check_profile_mm(profile_mm), dtype=float)
    s, a = table[:, 0] * MM, table[:, 1] * MM
    length = float(arc_length_m(p)[-1])
    if s[-1] > length + 1e-9:
        raise StockError(
            f"the allowance profile's s_mm must lie in [0, {length / MM:.1f}] mm (the path "
            f"length), got {s[-1] / MM:g} mm"
        )
    grid = np.linspace(0.0, length, max(2, int(np.ceil(length / PROFILE_SPACING_M)) + 1))
    grid = np.union1d(grid, s)
    return Stock(p, n, _check_radius(tool_radius_m), grid, np.interp(grid, s, a), (), "profile")


def check_profile_mm(profile_mm: Sequence[tuple[float, float]]) -> tuple[tuple[float, float], ...]:
    """The allowance profile as ((s_mm, allowance_mm), ...), or ``StockError`` naming what is
    wrong: pairs of finite numbers, at most ``MAX_PROFILE_POINTS``, s_mm from 0 up to
    ``MAX_PROFILE_S_MM`` and strictly increasing, allowances within 0-20 mm. (Whether the
    profile fits the program's path is checked when the stock is built on it.)"""
    try:
        table = np.asarray(profile_mm, dtype=float)
    except (TypeError, ValueError):
        raise StockError("the allowance profile must be pairs (s_mm, allowance_mm)") from None
    if table.ndim != 2 or table.shape[1] != 2 or len(table) == 0:
        raise StockError("the allowance profile must be one or more pairs (s_mm, allowance_mm)")
    if len(table) > MAX_PROFILE_POINTS:
        raise StockError(
            f"the allowance profile has {len(table)} points, more than {MAX_PROFILE_POINTS}"
        )
    bad = ~np.isfinite(table)
    if np.any(bad):
        row = int(np.argmax(bad.any(axis=1)))
        raise StockError(
            f"the allowance profile's point {row + 1} is not finite: {table[row].tolist()}"
        )
    s, a = table[:, 0], table[:, 1]
    if s[0] < 0.0 or s[-1] > MAX_PROFILE_S_MM:
        raise StockError(
            f"the allowance profile's s_mm must lie within 0-{MAX_PROFILE_S_MM:g} mm along the path"
        )
    if np.any(np.diff(s) <= 0.0):
        raise StockError("the allowance profile's s_mm must increase strictly")
    if np.any(a < 0.0) or np.any(a > MAX_ALLOWANCE_M / MM):
        row = int(np.argmax((a < 0.0) | (a > MAX_ALLOWANCE_M / MM)))
        raise StockError(
            f"allowances must be within 0-{MAX_ALLOWANCE_M / MM:g} mm, got {a[row]:g} mm at "
            f"s = {s[row]:g} mm"
        )
    return tuple((float(x), float(y)) for x, y in table)


def stock_from_mesh(
    stock_mesh: trimesh.Trimesh,
    path_points_m: np.ndarray,
    wall_normals: np.ndarray,
    *,
    tool_radius_m: float = Tool().radius_m,
    spacing_m: float = 0.5 * MM,
) -> Stock:
    """The allowance of a stock mesh (base frame, metres) over the nominal wall along the path.

    At every ~``spacing_m`` along the path a ray starts ``RAY_INSET_M`` inside the nominal wall
    (path - r n) and runs along n; the allowance is where it first leaves the stock, minus the
    inset. A ray that meets no stock surface within 20 mm means the stock does not cover the
    wall there.
    """
    if not isinstance(stock_mesh, trimesh.Trimesh) or len(stock_mesh.faces) == 0:
        raise StockError("the stock mesh must be a non-empty trimesh.Trimesh")
    p, n = _path_and_normals(path_points_m, wall_normals)
    r = _check_radius(tool_radius_m)
    s_path = arc_length_m(p)
    s = np.linspace(0.0, s_path[-1], max(2, int(np.ceil(s_path[-1] / spacing_m)) + 1))
    wall = p - r * n
    w = np.stack([np.interp(s, s_path, wall[:, i]) for i in range(3)], axis=1)
    d = np.stack([np.interp(s, s_path, n[:, i]) for i in range(3)], axis=1)
    d /= np.linalg.norm(d, axis=1, keepdims=True)
    origins = w - RAY_INSET_M * d
    locations, index_ray, _ = stock_mesh.ray.intersects_location(origins, d, multiple_hits=True)
    hit = np.full(len(s), np.inf)
    if len(index_ray):
        dist = np.einsum("ij,ij->i", locations - origins[index_ray], d[index_ray])
        ok = dist > 0.0
        np.minimum.at(hit, index_ray[ok], dist[ok])
    missing = ~np.isfinite(hit) | (hit > RAY_RANGE_M)
    if np.any(missing):
        first = float(s[np.argmax(missing)])
        raise StockError(
            f"the stock mesh does not cover the wall at {int(missing.sum())} of {len(s)} "
            f"stations (first at {first / MM:.1f} mm along the path); is it placed on the part?"
        )
    allowance = np.maximum(hit - RAY_INSET_M, 0.0)
    return Stock(p, n, r, s, allowance, (), "mesh")
