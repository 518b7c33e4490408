from __future__ import annotations

import math

import numpy as np
import pytest

from robomach_core.cell import Cell, ComplianceSelection, LeadThrough
from robomach_core.errors import InvalidInputError, NoContactError
from robomach_core.transforms import rotation_log


@pytest.fixture(scope="module")
def cell() -> Cell:
    return Cell()


@pytest.fixture()
def started(cell):
    lt = LeadThrough(cell)
    return lt, lt.start(cell.initial_state())


XYZ = ComplianceSelection(frozenset({"x", "y", "z"}), "base")


def test_no_push_and_no_contact_does_not_drift(started):
    lt, state = started
    p0 = state.cell.T_base_tcp[:3, 3].copy()
    state = lt.push(state, np.zeros(6), XYZ, 2.0)
    assert np.linalg.norm(state.cell.T_base_tcp[:3, 3] - p0) < 1e-5  # the deadband holds it


def test_push_moves_only_along_compliant_axes(started):
    lt, state = started
    p0 = state.cell.T_base_tcp[:3, 3].copy()
    only_x = ComplianceSelection(frozenset({"x"}), "base")
    state = lt.push(state, np.array([10.0, 10.0, 10.0, 0, 0, 0]), only_x, 0.5)
    d = state.cell.T_base_tcp[:3, 3] - p0
    assert d[0] > 0.005  # ~10 N / 500 N s/m * 0.5 s = 10 mm
    assert abs(d[1]) < 1e-4 and abs(d[2]) < 1e-4


def test_pushing_into_the_part_is_safe(cell):
    """The wall pushes back: a 15 N push into the groove wall ends near 15 N, not more."""
    lt = LeadThrough(cell)
    wp = cell.workpiece
    state = lt.start(cell.initial_state())
    over = wp.T_base_wobj[:3, 3] + np.array([0.0, -0.0625, wp.surface_z_m + 0.005])
    from robomach_core.teaching.operator import push_to

    state = push_to(lt, state, over, XYZ)
    state = push_to(lt, state, over - np.array([0, 0, 0.008]), XYZ)
    state = lt.push(state, np.array([0.0, -15.0, 0.0, 0, 0, 0]), XYZ, 2.0)
    f = lt.measured_wrench(state.cell)[:3]
    assert state.cell.in_contact
    assert f[1] == pytest.approx(15.0, abs=1.5)
    assert np.linalg.norm(f) < 20.0


def test_orientation_jog_turns_about_the_tool_axis(started):
    lt, state = started
    R0 = state.cell.T_base_tcp[:3, :3].copy()
    state = lt.jog(state, "rz", math.radians(5.0), ComplianceSelection(frozenset(), "tool"))
    rot = rotation_log(R0.T @ state.cell.T_base_tcp[:3, :3])
    np.testing.assert_allclose(rot, [0, 0, math.radians(5.0)], atol=2e-4)


def test_guide_point_records_pose_joints_and_time(started):
    lt, state = started
    state = lt.push(state, np.zeros(6), XYZ, 0.1)
    g = lt.record(state)
    np.testing.assert_allclose(g.T_base_tcp, state.cell.T_base_tcp)
    np.testing.assert_allclose(g.joints_rad, state.cell.q_motor)
    assert g.time_s == state.cell.time_s


def test_bad_axes_and_jogs_are_refused(started):
    lt, state = started
    with pytest.raises(InvalidInputError, match="unknown compliance axes"):
        ComplianceSelection(frozenset({"q"}), "base")
    with pytest.raises(InvalidInputError):
        lt.jog(state, "rx", math.radians(90), XYZ)


def test_touch_off_stops_in_contact_at_the_set_force(cell):
    """One action per guide point: from the middle of the groove, -y until the wall pushes back."""
    from robomach_core.teaching.operator import push_to

    lt = LeadThrough(cell)
    wp = cell.workpiece
    state = lt.start(cell.initial_state())
    over = wp.T_base_wobj[:3, 3] + np.array([0.0, -0.0625, wp.surface_z_m + 0.005])
    state = push_to(lt, state, over, XYZ)
    state = push_to(lt, state, over - np.array([0, 0, 0.008]), XYZ)
    y0 = state.cell.T_base_tcp[1, 3]
    state = lt.touch_off(state, "y", -1, 10.0, XYZ, 0.01)
    f = lt.measured_wrench(state.cell)[:3]
    assert state.cell.in_contact
    assert f[1] == pytest.approx(10.0, abs=1.5)  # the wall pushes back with the set force
    assert np.linalg.norm(state.velocity[:3]) < 0.0005  # and the tool has stopped there
    assert 0.0005 < y0 - state.cell.T_base_tcp[1, 3] < 0.003  # it travelled to the wall


def test_touch_off_in_free_air_says_so(started):
    lt, state = started
    y0 = state.cell.T_base_tcp[1, 3]
    with pytest.raises(NoContactError, match="no contact within 5.0 mm") as info:
        lt.touch_off(state, "y", 1, 10.0, XYZ, 0.005)
    travelled = info.value.state.cell.T_base_tcp[1, 3] - y0
    assert 0.005 < travelled < 0.006
    with pytest.raises(InvalidInputError):
        lt.touch_off(state, "q", 1, 10.0, XYZ, 0.005)
    with pytest.raises(InvalidInputError):
        lt.touch_off(state, "x", 1, 500.0, XYZ, 0.005)
