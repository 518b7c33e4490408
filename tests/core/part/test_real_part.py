"""The real part is not its CAD: fixture error, casting warp and burrs from a seed."""

from __future__ import annotations

import math
from dataclasses import asdict

import numpy as np
import pytest

from robomach_core.errors import InvalidInputError
from robomach_core.learning.walls import section_loops
from robomach_core.part import PartDeviation, real_workpiece
from robomach_core.part.real_part import fixture_error, refine_walls
from robomach_core.part.workpiece import block, water_pump
from robomach_core.project import CellSettings, Project
from robomach_core.project._stages import build_cell_workpiece

MACHINING_Z_M = 0.017


@pytest.fixture(scope="module")
def pump():
    return water_pump()


@pytest.fixture(scope="module")
def real_pump(pump):
    return real_workpiece(pump, PartDeviation.realistic(0))


def test_no_deviation_is_the_cad_itself(pump):
    assert real_workpiece(pump, None) is pump
    assert pump.cad() is pump and pump.scoring_mesh() is pump.mesh


def test_the_fixture_error_is_inside_the_preset_and_mostly_in_the_table_plane():
    for seed in range(20):
        d = PartDeviation.realistic(seed)
        fx = fixture_error(d)
        in_plane = math.hypot(*fx.shift_m[:2]) * 1e3
        assert 0.5 * d.fixture_shift_mm - 1e-9 <= in_plane <= d.fixture_shift_mm + 1e-9
        assert abs(fx.shift_m[2]) * 1e3 <= 0.1 * d.fixture_shift_mm + 1e-9
        rotation = abs(math.degrees(fx.rotation_rad))
        assert 0.5 * d.fixture_rotation_deg - 1e-9 <= rotation <= d.fixture_rotation_deg + 1e-9


def test_the_real_wall_differs_from_the_cad_by_the_fixture_and_a_varying_casting_offset(
    pump, real_pump
):
    cad_outer = section_loops(pump.mesh, MACHINING_Z_M)[1]
    real_outer = section_loops(real_pump.scoring_mesh(), MACHINING_Z_M)[1]
    assert cad_outer.closed and real_outer.closed
    fx = fixture_error(PartDeviation.realistic(0)).transform
    # Undo the fixture: what is left is the casting's offset, within 0.5 mm and not constant.
    _, pts = real_outer.sample(0.002)
    back = (np.column_stack([pts, np.zeros(len(pts))]) - fx[:3, 3]) @ fx[:3, :3]
    offset = cad_outer.signed_distance(back[:, :2])
    assert np.abs(offset).max() <= 0.5e-3 + 2e-5
    assert np.ptp(offset) > 0.3e-3  # it varies along the contour
    # With the fixture error, the real wall is about a millimetre off the CAD somewhere.
    assert np.abs(cad_outer.signed_distance(pts)).max() > 0.8e-3
    # The built-in part's real contour is the same wall (scores use it).
    assert real_pump.wall.distance(pts).max() < 2e-5


def test_burrs_stand_off_the_casting_by_their_height(real_pump):
    d = PartDeviation.realistic(0)
    casting = section_loops(real_pump.scoring_mesh(), MACHINING_Z_M)[1]
    with_burrs = section_loops(real_pump.mesh, MACHINING_Z_M)[1]
    _, pts = with_burrs.sample(1e-4)
    stand_off = casting.signed_distance(pts)
    assert stand_off.max() == pytest.approx(d.burr_height_mm * 1e-3, rel=0.15)
    assert stand_off.min() > -1e-5  # burrs only add material
    assert np.mean(stand_off > 0.5 * d.burr_height_mm * 1e-3) < 0.1  # local bumps


def test_the_real_part_is_deterministic_per_seed_and_differs_between_seeds(pump):
    a = real_workpiece(water_pump(), PartDeviation.realistic(4))
    b = real_workpiece(pump, PartDeviation.realistic(4))
    c = real_workpiece(pump, PartDeviation.realistic(5))
    assert np.array_equal(a.mesh.vertices, b.mesh.vertices)
    assert not np.allclose(b.mesh.vertices, c.mesh.vertices)
    assert b.nominal is pump or np.array_equal(b.nominal.mesh.vertices, pump.mesh.vertices)


def test_refining_splits_long_walls_without_changing_the_surface():
    cad = block()
    v, f = refine_walls(cad.mesh.vertices, cad.mesh.faces)
    import trimesh

    refined = trimesh.Trimesh(v, f, process=False)
    assert refined.area == pytest.approx(cad.mesh.area, rel=1e-9)
    assert len(f) > 100 * len(cad.mesh.faces)
    loops = section_loops(refined, 0.02)
    assert len(loops) == 1 and loops[0].closed
    assert loops[0].length_m == pytest.approx(0.4, abs=1e-6)


def test_the_cell_setting_is_one_value_saved_with_the_project():
    cell = CellSettings(part_deviation=PartDeviation.realistic(2))
    again = CellSettings(**asdict(cell))  # as the store and the project file read it back
    assert again == cell
    assert Project(cell=cell).cell_key != Project(cell=CellSettings()).cell_key
    wp = build_cell_workpiece(cell, None)
    assert wp.nominal is not None and "fixture error" in wp.deviation_note
    assert build_cell_workpiece(CellSettings(), None).nominal is None


@pytest.mark.parametrize(
    "field, value",
    [("fixture_shift_mm", -1.0), ("fixture_rotation_deg", 5.0), ("burrs", 2.5), ("seed", -1)],
)
def test_out_of_range_deviations_are_refused(field, value):
    with pytest.raises(InvalidInputError, match=field.split("_")[0]):
        PartDeviation(**{field: value})
    with pytest.raises(InvalidInputError, match="unknown"):
        PartDeviation.from_value({"fixture_shift": 1.0})
