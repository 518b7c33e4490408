from __future__ import annotations

import numpy as np
import pytest

from robomach_core.cell import Tool
from robomach_core.cell.contact import ContactModel
from robomach_core.errors import MeshFileError, UnknownNameError
from robomach_core.part import Arc, builtin_workpiece, mesh_from_bytes
from robomach_core.part.contour import filleted_polygon
from robomach_core.part.workpiece import block, water_pump
from robomach_core.pipeline import read_mesh_file

TOOL_DOWN = np.diag([1.0, -1.0, -1.0])


@pytest.fixture(scope="module")
def pump():
    return water_pump()


def test_pump_wall_has_sharp_and_gentle_curvature_and_a_5mm_groove(pump):
    radii = [p.radius for p in pump.wall.pieces if isinstance(p, Arc)]
    assert min(radii) <= 0.003 and max(radii) >= 0.006
    lines = [p.length for p in pump.wall.pieces if not hasattr(p, "radius")]
    assert max(lines) > 0.015  # gentle (straight) runs between the bumps
    assert pump.wall.length == pytest.approx(0.758, abs=0.01)


def test_groove_is_5mm_wide_and_6mm_deep(pump):
    contact = ContactModel(Tool(radius_m=0.0005), pump)
    z_mid = pump.surface_z_m - 0.003
    # Across the bottom run (wall at y = -65 mm): air for 5 mm, then the island.
    assert not contact.evaluate(
        _tool_at(pump, (0.0, -0.0625), z_mid), np.zeros(3), 0, 0.004
    ).in_contact
    assert not contact.evaluate(
        _tool_at(pump, (0.0, -0.0606), z_mid), np.zeros(3), 0, 0.004
    ).in_contact
    assert contact.evaluate(_tool_at(pump, (0.0, -0.0598), z_mid), np.zeros(3), 0, 0.004).in_contact
    floor = pump.surface_z_m - 0.006
    assert contact.evaluate(
        _tool_at(pump, (0.0, -0.0625), floor + 0.0004), np.zeros(3), 0, 0.004
    ).in_contact


def test_contour_offset_is_exact_for_lines_and_arcs():
    c = filleted_polygon(np.array([[0, 0], [0.1, 0], [0.1, 0.05], [0, 0.05]]), np.full(4, 0.01))
    inner = c.offset(0.002)
    pts = inner.sample(0.001)
    np.testing.assert_allclose(c.distance(pts), 0.002, atol=1e-12)


def _tool_at(wp, xy_wobj, z_wobj):
    T = np.eye(4)
    T[:3, :3] = TOOL_DOWN
    T[:3, 3] = wp.T_base_wobj[:3, :3] @ np.array([*xy_wobj, z_wobj]) + wp.T_base_wobj[:3, 3]
    return T


@pytest.mark.parametrize("shape", ["ball", "cylinder"])
def test_penalty_force_is_stiffness_times_depth_and_pushes_out_of_the_wall(pump, shape):
    tool = Tool(shape=shape)
    contact = ContactModel(tool, pump)
    # The bottom run of the wall is y = -65 mm (wobj); the groove is inside (y > -65).
    free = contact.evaluate(_tool_at(pump, (0.0, -0.0635), 0.017), np.zeros(3), 0.0, 0.004)
    assert not free.in_contact
    depth = 0.0001
    hit = contact.evaluate(
        _tool_at(pump, (0.0, -0.065 + tool.radius_m - depth), 0.017), np.zeros(3), depth, 0.004
    )
    assert hit.in_contact
    assert hit.depth_m == pytest.approx(depth, rel=1e-3)
    np.testing.assert_allclose(
        hit.wrench[:3], [0.0, pump.contact_stiffness_N_m * depth, 0.0], atol=1e-3
    )


def test_friction_opposes_sliding(pump):
    contact = ContactModel(Tool(), pump)
    T = _tool_at(pump, (0.0, -0.065 + 0.0009), 0.017)
    r = contact.evaluate(T, np.array([0.005, 0.0, 0.0]), 0.0001, 0.004)
    f_n = r.wrench[1]
    assert r.wrench[0] == pytest.approx(-pump.friction_coefficient * f_n, rel=0.05)


def test_contact_stiffness_is_in_the_papers_range():
    for wp in (water_pump(), block()):
        assert 85e3 <= wp.contact_stiffness_N_m <= 143e3


def test_block_is_150_by_50_mm():
    b = block()
    np.testing.assert_allclose(b.mesh.extents[:2], [0.150, 0.050])


def test_unknown_workpiece_names_the_choices():
    with pytest.raises(UnknownNameError, match="water_pump, block"):
        builtin_workpiece("gearbox")


def test_mesh_files_load_and_bad_files_give_clear_errors(tmp_path):
    good = tmp_path / "part.stl"
    block().mesh.copy().apply_scale(1000.0).export(good)  # mm on disk
    filename, data = read_mesh_file(good)  # what the CLI's --workpiece FILE does
    assert filename == "part.stl"
    wp = mesh_from_bytes(data, ".stl", name="part")
    np.testing.assert_allclose(wp.mesh.extents[:2], [0.150, 0.050], atol=1e-9)
    bad = tmp_path / "notes.stl"
    bad.write_text("this is not a mesh")
    with pytest.raises(MeshFileError):
        mesh_from_bytes(bad.read_bytes(), ".stl", name="notes")
    with pytest.raises(MeshFileError, match="not a mesh file"):
        read_mesh_file(tmp_path / "x.txt")
    with pytest.raises(MeshFileError, match="no such file"):
        read_mesh_file(tmp_path / "missing.stl")
    with pytest.raises(MeshFileError, match="exceed the limit"):
        mesh_from_bytes(good.read_bytes(), ".stl", max_triangles=4)
