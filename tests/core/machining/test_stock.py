"""The stock: built-in allowance and burrs, user profiles, stock meshes, display geometry."""

from __future__ import annotations

import numpy as np
import pytest
import trimesh

from robomach_core.errors import InvalidInputError
from robomach_core.machining import (
    StockError,
    builtin_stock,
    stock_from_mesh,
    stock_from_profile,
    wall_normals_from_path,
)
from robomach_core.machining.stock import LEAD_IN_M

MM = 1e-3


def _straight(length_m: float = 0.2, n: int = 101) -> np.ndarray:
    x = np.linspace(0.0, length_m, n)
    return np.column_stack([x, np.zeros(n), np.full(n, 0.02)])


def test_builtin_stock_spans_the_allowance_range_with_burrs_of_the_stated_size(wall_program):
    stock = builtin_stock(wall_program.position_m, seed=0)
    s = stock.profile_s_m
    a = stock.profile_allowance_m
    burr_free = np.ones_like(s, dtype=bool)
    for b in stock.burrs:
        assert 4.0 * MM <= b.length_m <= 8.0 * MM
        assert 0.5 * MM <= b.height_m <= 2.0 * MM
        burr_free &= np.abs(s - b.center_m) > 0.5 * b.length_m
    body = burr_free & (s > LEAD_IN_M)
    assert a[body].min() >= 0.3 * MM - 1e-12 and a[body].max() <= 3.0 * MM + 1e-12
    assert a[body].max() - a[body].min() > 2.0 * MM  # it does vary along the path
    assert len(stock.burrs) == round(10.0 * stock.path_length_m)
    for a_burr, b_burr in zip(stock.burrs[:-1], stock.burrs[1:], strict=True):
        assert b_burr.center_m - a_burr.center_m > 0.5 * (a_burr.length_m + b_burr.length_m)
    assert stock.max_allowance_m <= 5.0 * MM
    assert a[0] == 0.0  # the lead-in
    # Smooth away from the burrs: no jump larger than a slope of 0.1 mm/mm allows.
    step = np.abs(np.diff(a))[body[1:] & body[:-1]]
    assert step.max() < 0.1 * (s[1] - s[0])


def test_builtin_stock_is_reproducible_from_its_seed(wall_program):
    a = builtin_stock(wall_program.position_m, seed=3)
    b = builtin_stock(wall_program.position_m, seed=3)
    c = builtin_stock(wall_program.position_m, seed=4)
    assert np.array_equal(a.profile_allowance_m, b.profile_allowance_m)
    assert not np.array_equal(a.profile_allowance_m, c.profile_allowance_m)


def test_profile_interpolates_linearly_and_is_flat_beyond_its_ends():
    stock = stock_from_profile(_straight(), [(20.0, 1.0), (120.0, 3.0)])
    got = stock.allowance_m(np.array([0.0, 20.0, 70.0, 120.0, 200.0]) * MM) / MM
    assert got == pytest.approx([1.0, 1.0, 2.0, 3.0, 3.0])


@pytest.mark.parametrize(
    ("profile", "words"),
    [
        ([(10.0, 1.0), (5.0, 1.0)], "increase"),
        ([(10.0, -1.0)], "within 0-20 mm, got -1 mm at s = 10 mm"),
        ([(10.0, 25.0)], "within 0-20 mm, got 25 mm"),
        ([(500.0, 1.0)], "path length"),
        ([], "one or more pairs"),
        ([(1.0, float("nan"))], "point 1 is not finite"),
        ([(-1.0, 1.0)], "within 0-100000 mm"),
    ],
)
def test_bad_profiles_are_refused_with_the_reason(profile, words):
    with pytest.raises(StockError, match=None) as info:
        stock_from_profile(_straight(), profile)
    assert words in str(info.value)
    assert isinstance(info.value, InvalidInputError)


def test_bad_paths_and_normals_are_refused():
    with pytest.raises(StockError, match="n >= 2"):
        builtin_stock(np.zeros((1, 3)), seed=0)
    with pytest.raises(StockError, match="zero length"):
        builtin_stock(np.zeros((5, 3)), seed=0)
    with pytest.raises(StockError, match="wall normals"):
        builtin_stock(_straight(), seed=0, wall_normals_m=np.ones((3, 3)))


def test_wall_normals_point_left_of_travel_when_the_wall_is_on_the_right():
    n = wall_normals_from_path(_straight())
    assert n == pytest.approx(np.tile([0.0, 1.0, 0.0], (len(n), 1)))
    assert wall_normals_from_path(_straight(), wall_side="left")[0] == pytest.approx([0, -1, 0])


def test_stock_mesh_allowance_is_the_distance_from_the_wall_to_the_stock_surface():
    # Nominal wall: the plane y = 0 with material at y < 0; the tool path runs at y = r.
    r = 1.0 * MM
    path = _straight() + np.array([0.0, r, 0.0])
    stock_mesh = trimesh.creation.box(extents=(0.3, 0.05, 0.04))
    stock_mesh.apply_translation([0.1, -0.025 + 1.5 * MM, 0.02])  # 1.5 mm proud of the wall
    stock = stock_from_mesh(stock_mesh, path, wall_normals_from_path(path), tool_radius_m=r)
    assert stock.profile_allowance_m == pytest.approx(np.full(stock.profile_s_m.size, 1.5 * MM))
    assert stock.source == "mesh"


def test_a_stock_mesh_that_misses_the_wall_is_refused():
    path = _straight()
    far = trimesh.creation.box(extents=(0.01, 0.01, 0.01))
    far.apply_translation([5.0, 5.0, 5.0])
    with pytest.raises(StockError, match="does not cover"):
        stock_from_mesh(far, path, wall_normals_from_path(path))


def test_display_geometry_lies_on_the_stock_surface():
    path = _straight()
    stock = stock_from_profile(path, [(0.0, 2.0)], tool_radius_m=1.0 * MM)
    pts = stock.surface_points_m()
    # Wall at y = -1 mm (path minus r along +y), stock surface 2 mm proud: y = +1 mm.
    assert pts[:, 1] == pytest.approx(np.full(len(pts), 1.0 * MM))
    vertices, faces = stock.ribbon_mesh(height_m=4 * MM)
    assert vertices.shape == (2 * len(pts), 3) and faces.shape == (2 * (len(pts) - 1), 3)
    assert faces.max() == len(vertices) - 1
    assert np.ptp(vertices[:, 2]) == pytest.approx(4 * MM)


@pytest.mark.parametrize(
    "profile",
    [[(0.0, float("nan"))], [(0.0, -0.5)], [(0.0, 1.0), (float("inf"), 2.0)], [(0.0, 21.0)],
     [(5.0, 1.0), (5.0, 2.0)], [(-3.0, 1.0)]],
)  # fmt: skip
def test_a_setup_refuses_a_bad_profile_before_it_is_stored(profile):
    """Issue 19 R12: profiles with NaN, negative or out-of-range values were stored and failed
    only at run time; the setup (what the store, the CLI and the API hold) refuses them."""
    from robomach_core.project import MachiningSetup

    with pytest.raises(StockError):
        MachiningSetup(stock_source="profile", stock_profile_mm=tuple(profile))
