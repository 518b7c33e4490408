"""Depth of cut along the path: the paper's steps, random burrs, and the product's own profile
computed from a stock mesh (the part with burrs) against the nominal part along a learned path.

PROBLEM: the cutting force depends on how much material is in front of the tool, which changes
along the path and is unknown to the controller. STRATEGY: a depth profile is a piecewise-linear
function of arc length s [m]; the simulator reads it at the tool's current position, so a slower
feed reaches a burr later, as on the real cell. SOLUTION: ``PathProfile`` plus builders.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from ..transforms import arc_length_m
from .errors import CmrrSettingsError, MeshDepthError

MM = 1e-3


@dataclass(frozen=True, eq=False)
class PathProfile:
    """A quantity along the path, linear between samples and constant beyond the ends.

    ``positions_m`` shape (n,), non-decreasing arc length [m]; ``values`` shape (n,).
    """

    positions_m: np.ndarray
    values: np.ndarray

    def __post_init__(self) -> None:
        s = np.asarray(self.positions_m, dtype=float)
        v = np.asarray(self.values, dtype=float)
        if s.ndim != 1 or s.shape != v.shape or s.size < 2:
            raise CmrrSettingsError("a path profile needs two or more (position, value) pairs")
        if np.any(np.diff(s) < 0.0) or not np.all(np.isfinite(s)) or not np.all(np.isfinite(v)):
            raise CmrrSettingsError("profile positions must be finite and non-decreasing")
        object.__setattr__(self, "positions_m", s)
        object.__setattr__(self, "values", v)

    @property
    def length_m(self) -> float:
        """Arc length covered by the profile [m]."""
        return float(self.positions_m[-1] - self.positions_m[0])

    def __call__(self, position_m: float | np.ndarray) -> float | np.ndarray:
        """Value at arc length ``position_m``."""
        out = np.interp(position_m, self.positions_m, self.values)
        return float(out) if np.ndim(out) == 0 else out

    def max(self) -> float:
        """Largest value along the path."""
        return float(np.max(self.values))


def step_depth_profile(
    depths_m: Sequence[float] = (1.0 * MM, 2.0 * MM, 3.0 * MM),
    segment_length_m: float = 0.09,
    *,
    transition_m: float = 5.0 * MM,
) -> PathProfile:
    """Depth steps, one segment each (the paper's 1 -> 2 -> 3 mm end-milling test).

    The depth ramps over ``transition_m`` at each step: an end mill engages a step gradually
    over its radius.
    """
    if len(depths_m) == 0 or min(depths_m) < 0.0:
        raise CmrrSettingsError("step profile needs one or more non-negative depths")
    if not 0.0 < transition_m < segment_length_m:
        raise CmrrSettingsError("step transition must be shorter than a segment")
    s: list[float] = [0.0]
    v: list[float] = [depths_m[0]]
    for i, d in enumerate(depths_m[1:], start=1):
        edge = i * segment_length_m
        s += [edge - 0.5 * transition_m, edge + 0.5 * transition_m]
        v += [depths_m[i - 1], d]
    s.append(len(depths_m) * segment_length_m)
    v.append(depths_m[-1])
    return PathProfile(np.array(s), np.array(v))


def segment_bounds(depths_m: Sequence[float], segment_length_m: float) -> list[tuple[float, float]]:
    """(start, end) arc length [m] of each segment of a step profile."""
    return [(i * segment_length_m, (i + 1) * segment_length_m) for i in range(len(depths_m))]


@dataclass(frozen=True)
class Burr:
    """A burr: raised-cosine bump of ``height_m`` over ``width_m`` centred at ``center_m``."""

    center_m: float
    height_m: float
    width_m: float

    def __post_init__(self) -> None:
        if self.height_m < 0.0 or not self.width_m > 0.0:
            raise CmrrSettingsError("a burr needs a non-negative height and a positive width")

    def height_at(self, s: np.ndarray) -> np.ndarray:
        """Burr height [m] at arc lengths ``s``."""
        u = (np.asarray(s) - self.center_m) / (0.5 * self.width_m)
        return np.where(np.abs(u) < 1.0, 0.5 * self.height_m * (1.0 + np.cos(np.pi * u)), 0.0)


def burr_depth_profile(
    burrs: Sequence[Burr],
    length_m: float,
    *,
    base_depth_m: float = 0.0,
    resolution_m: float = 0.5 * MM,
) -> PathProfile:
    """Base depth (stock allowance) plus burrs, sampled every ``resolution_m``."""
    if not length_m > 0.0 or not resolution_m > 0.0:
        raise CmrrSettingsError("burr profile needs a positive length and resolution")
    s = np.linspace(0.0, length_m, max(int(np.ceil(length_m / resolution_m)) + 1, 2))
    d = np.full_like(s, base_depth_m)
    for burr in burrs:
        d += burr.height_at(s)
    return PathProfile(s, d)


def random_burrs(
    rng: np.random.Generator,
    count: int,
    length_m: float,
    *,
    height_range_m: tuple[float, float] = (0.5 * MM, 2.5 * MM),
    width_range_m: tuple[float, float] = (15.0 * MM, 40.0 * MM),
    margin_m: float = 30.0 * MM,
) -> list[Burr]:
    """``count`` non-overlapping burrs of random size and place, sorted along the path."""
    if count < 0:
        raise CmrrSettingsError("burr count must not be negative")
    burrs: list[Burr] = []
    for _ in range(1000 * max(count, 1)):
        if len(burrs) == count:
            break
        width = rng.uniform(*width_range_m)
        lo, hi = margin_m + 0.5 * width, length_m - margin_m - 0.5 * width
        if hi <= lo:
            raise CmrrSettingsError("path too short for burrs of this width and margin")
        center = rng.uniform(lo, hi)
        if all(abs(center - b.center_m) > 0.5 * (width + b.width_m) for b in burrs):
            burrs.append(Burr(center, rng.uniform(*height_range_m), width))
    if len(burrs) < count:
        raise CmrrSettingsError(f"cannot place {count} non-overlapping burrs on this path")
    return sorted(burrs, key=lambda b: b.center_m)


def depth_along_path(
    path_points_m: np.ndarray,
    nominal_mesh: object,
    stock_mesh: object,
    tool_axis: np.ndarray | Sequence[float],
    *,
    max_depth_m: float = 20.0 * MM,
) -> np.ndarray:
    """Depth of cut [m] at each path point: stock surface minus nominal surface along the tool axis.

    Args:
        path_points_m: shape (n, 3), the learned path (TCP or contact points) [m].
        nominal_mesh: ``trimesh.Trimesh`` of the finished part.
        stock_mesh: ``trimesh.Trimesh`` of the part as cast (with burrs and allowance).
        tool_axis: shape (3,) or (n, 3), unit vectors from the workpiece towards the spindle.
        max_depth_m: rays start this far above each point; deeper stock is not supported.

    Returns:
        Shape (n,), depth >= 0 [m]; zero where the stock is not above the nominal surface.

    A ray is cast from ``p + max_depth * axis`` along ``-axis``; its first hit on each mesh gives
    that surface's height along the axis, and the depth is their difference. Both surfaces are
    measured on the same ray, so an offset of the path along the axis (a ball-end TCP above the
    surface) does not change the depth.
    """
    pts = np.asarray(path_points_m, dtype=float)
    if pts.ndim != 2 or pts.shape[1] != 3 or pts.shape[0] < 1:
        raise MeshDepthError("path points must have shape (n, 3)")
    axis = np.broadcast_to(np.asarray(tool_axis, dtype=float), pts.shape).copy()
    norms = np.linalg.norm(axis, axis=1)
    if np.any(norms < 1e-9):
        raise MeshDepthError("tool axis must be a non-zero vector")
    axis /= norms[:, None]
    origins = pts + axis * max_depth_m
    t_nominal = _first_hit_distance(nominal_mesh, origins, -axis)
    if np.any(~np.isfinite(t_nominal)):
        bad = int(np.flatnonzero(~np.isfinite(t_nominal))[0])
        raise MeshDepthError(f"path point {bad} is not above the nominal part along the tool axis")
    t_stock = _first_hit_distance(stock_mesh, origins, -axis)
    t_stock = np.where(np.isfinite(t_stock), t_stock, t_nominal)
    return np.clip(t_nominal - t_stock, 0.0, None)


def _first_hit_distance(mesh: object, origins: np.ndarray, directions: np.ndarray) -> np.ndarray:
    """Distance along each ray to its first hit on ``mesh``; inf where it misses. Shape (n,)."""
    try:
        locations, index_ray, _ = mesh.ray.intersects_location(  # type: ignore[attr-defined]
            origins, directions, multiple_hits=True
        )
    except AttributeError as exc:
        raise MeshDepthError("meshes must be trimesh.Trimesh objects") from exc
    dist = np.full(origins.shape[0], np.inf)
    if len(index_ray):
        t = np.einsum("ij,ij->i", locations - origins[index_ray], directions[index_ray])
        ok = t >= 0.0
        np.minimum.at(dist, index_ray[ok], t[ok])
    return dist


def path_depth_profile(
    path_points_m: np.ndarray,
    nominal_mesh: object,
    stock_mesh: object,
    tool_axis: np.ndarray | Sequence[float],
    *,
    max_depth_m: float = 20.0 * MM,
) -> PathProfile:
    """``depth_along_path`` as a profile over the path's arc length."""
    depth = depth_along_path(
        path_points_m, nominal_mesh, stock_mesh, tool_axis, max_depth_m=max_depth_m
    )
    s = arc_length_m(path_points_m)
    if s[-1] <= 0.0:
        raise MeshDepthError("the path has zero length")
    return PathProfile(s, depth)


def synthetic_burr_block(
    burrs: Sequence[Burr],
    *,
    length_m: float = 0.2,
    width_m: float = 0.04,
    height_m: float = 0.03,
    allowance_m: float = 0.5 * MM,
    path_points: int = 401,
) -> tuple[object, object, np.ndarray, np.ndarray]:
    """A straight block whose top edge carries burrs: (nominal, stock, path (n, 3), tool axis).

    The nominal part is a ``length x width x height`` box from the origin; the stock is the same
    box with ``allowance_m`` more on top plus the burrs (raised-cosine bumps along x). The path
    runs along the top face's centre line at the nominal height, 1 mm short of each end; the
    tool axis is +z.
    """
    import shapely.geometry
    import trimesh

    if not (length_m > 0.0 and width_m > 0.0 and height_m > 0.0):
        raise CmrrSettingsError("block dimensions must be positive")
    nominal = trimesh.creation.box(
        extents=(length_m, width_m, height_m),
        transform=trimesh.transformations.translation_matrix(
            (0.5 * length_m, 0.5 * width_m, 0.5 * height_m)
        ),
    )
    x = np.linspace(0.0, length_m, 801)
    top = height_m + allowance_m + sum((b.height_at(x) for b in burrs), np.zeros_like(x))
    outline = [(0.0, 0.0), (length_m, 0.0)] + list(zip(x[::-1], top[::-1], strict=True))
    stock = trimesh.creation.extrude_polygon(shapely.geometry.Polygon(outline), width_m)
    # Profile drawn in (x, z) and extruded along +z; rotate so the extrusion runs along +y.
    rotate = trimesh.transformations.rotation_matrix(np.pi / 2.0, (1.0, 0.0, 0.0))
    stock.apply_transform(rotate)
    stock.apply_translation((0.0, width_m, 0.0))
    # Stop short of the block's end faces: rays along an edge may miss it.
    end = min(1.0 * MM, 0.01 * length_m)
    px = np.linspace(end, length_m - end, path_points)
    path = np.column_stack([px, np.full_like(px, 0.5 * width_m), np.full_like(px, height_m)])
    return nominal, stock, path, np.array([0.0, 0.0, 1.0])
