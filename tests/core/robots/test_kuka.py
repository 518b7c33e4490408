"""The KUKA KR 270: published kinematics in KUKA's axis conventions, Status and Turn, the
compliance paper's stiffness, placement and the IRB 2400 beside it."""

from __future__ import annotations

import math

import numpy as np
import pytest
import yourdfpy
from hypothesis import assume, given, settings
from hypothesis import strategies as st

from robomach_core.cell import (
    TOOL_DOWN,
    Cell,
    CellConfig,
    Robot,
    Tool,
    program_language,
    true_joint_compliance,
)
from robomach_core.cell.robot import robot_urdf_path
from robomach_core.export.krl import status_turn
from robomach_core.part import builtin_workpiece, default_T_base_wobj
from robomach_core.robots import KR270, controller_axes_deg
from robomach_core.robots.kuka import status_bits, turn_bits, urdf_text, wrist_root_point_a1

TABLE1_DEG = (90.0, -50.0, 120.0, 180.0, 25.0, 180.0)


@pytest.fixture(scope="module")
def kr270() -> Robot:
    return Robot("kr270")


def test_urdf_has_the_published_joints_limits_and_speeds():
    path = robot_urdf_path("kr270")
    assert path.read_text() == urdf_text(KR270)
    urdf = yourdfpy.URDF.load(str(path))
    assert urdf.actuated_joint_names == [f"joint_a{i}" for i in range(1, 7)]
    for i, name in enumerate(urdf.actuated_joint_names):
        limit = urdf.joint_map[name].limit
        assert math.degrees(limit.lower) == pytest.approx(KR270.lower_deg[i], abs=1e-4)
        assert math.degrees(limit.upper) == pytest.approx(KR270.upper_deg[i], abs=1e-4)
        assert math.degrees(limit.velocity) == pytest.approx(KR270.velocity_deg_s[i], abs=1e-3)
    # kuka_kr270_support's axes: A1, A4 and A6 turn about the negative axes
    axes = [tuple(urdf.joint_map[n].axis) for n in urdf.actuated_joint_names]
    assert axes == [(0, 0, -1), (0, 1, 0), (0, 1, 0), (-1, 0, 0), (0, 1, 0), (-1, 0, 0)]
    assert program_language("KR270") == "krl"


def test_kukas_axis_zeros_and_directions(kr270):
    """All axes at 0: the rocker (upper arm) horizontal and the forearm straight ahead of it,
    $FLANGE x down and z ahead; KUKA's home (A2 -90, A3 +90): upper arm up, forearm level."""
    T = kr270.flange_pose(np.zeros(6))
    np.testing.assert_allclose(T[:3, 3], (0.35 + 1.15 + 1.2 + 0.24, 0.0, 0.675 - 0.041), atol=1e-9)
    np.testing.assert_allclose(T[:3, 2], (1, 0, 0), atol=1e-9)
    np.testing.assert_allclose(T[:3, 0], (0, 0, -1), atol=1e-9)
    home = kr270.flange_pose(np.radians([0, -90, 90, 0, 0, 0]))
    np.testing.assert_allclose(home[:3, 3], (0.35 + 1.2 + 0.24, 0.0, 0.675 + 1.15 - 0.041))
    np.testing.assert_allclose(home[:3, 2], (1, 0, 0), atol=1e-9)
    # positive A1 turns the arm clockwise seen from above: its tool moves to -y
    turned = kr270.flange_pose(np.radians([10, -90, 90, 0, 0, 0]))
    assert turned[1, 3] < -0.1
    # the controller shows the model's joints (KUKA's A1-A6), in degrees
    q = np.radians(TABLE1_DEG)
    np.testing.assert_allclose(controller_axes_deg("kr270", q), TABLE1_DEG)


def test_stiffness_is_the_compliance_papers_table_1():
    compliance = true_joint_compliance("kr270").compliance_rad_Nm * 1e6
    np.testing.assert_allclose(compliance, (0.26, 0.15, 0.26, 1.79, 1.52, 2.13), rtol=1e-12)


def test_table_1_pose_is_in_the_workspace_with_the_tool_inclined(kr270):
    """The paper's starting pose: within every limit, the wrist 1.46 m out to the right of the
    robot, 0.41 m up, the flange pointing 45 deg down."""
    q = np.radians(TABLE1_DEG)
    assert kr270.within_limits(q)
    wrist = wrist_root_point_a1(KR270, q)
    assert wrist == pytest.approx((1.4611, 0.4143), abs=1e-3)
    z_tool = kr270.flange_pose(q)[:3, 2]
    assert math.degrees(math.asin(-z_tool[2])) == pytest.approx(45.0, abs=1e-6)
    assert status_bits(KR270, q) == 2 and turn_bits(q) == 2  # basic area, A3 >= phi; A2 < 0


@settings(max_examples=150, deadline=None)
@given(st.lists(st.floats(-1.0, 1.0), min_size=6, max_size=6))
def test_status_and_turn_from_the_model_agree_with_kukas_definitions(kr270, unit):
    """The writer's Status/Turn (from the pinocchio model: wrist root point, A2-A3 line) equal
    the closed form of KUKA's definitions (robots.kuka) anywhere in the working range."""
    span = np.subtract(KR270.upper_deg, KR270.lower_deg)
    q = np.radians(np.array(KR270.lower_deg) + (np.array(unit) + 1.0) / 2.0 * span)
    # Off the boundaries of the definitions (A3 = phi, wrist on the A1 line, A5 = 0, Ai = 0).
    # Hypothesis favours the ends and the middle of a range, which land on them: nudge such
    # joints off by 0.01 degree instead of discarding the example (too many were discarded).
    q = np.where(np.abs(q) > 1e-8, q, math.radians(0.01))
    if abs(math.degrees(q[2]) - KR270.status_phi_deg) <= 1e-3:
        q[2] += math.radians(0.01)
    assume(abs(wrist_root_point_a1(KR270, q)[0]) > 1e-6)
    assert status_turn(kr270, q) == (status_bits(KR270, q), turn_bits(q))


def test_status_bits_follow_each_definition():
    base = np.radians([0.0, -90.0, 90.0, 0.0, 30.0, 0.0])
    assert status_bits(KR270, base) == 2  # basic area, A3 >= phi, A5 > 0 (KUKA's typical S 2)
    flipped = base.copy()
    flipped[4] = -math.radians(30.0)
    assert status_bits(KR270, flipped) == 6  # A5 <= 0 sets bit 2
    elbow_down = base.copy()
    elbow_down[2] = math.radians(KR270.status_phi_deg - 1.0)
    assert status_bits(KR270, elbow_down) & 2 == 0  # A3 < phi clears bit 1
    overhead = np.radians([0.0, -140.0, 60.0, 0.0, 30.0, 0.0])  # leaning back: wrist x < 0
    assert wrist_root_point_a1(KR270, overhead)[0] < 0
    assert status_bits(KR270, overhead) & 1 == 1
    assert turn_bits(np.radians([-1, -1, 1, -1, 1, -1])) == 1 + 2 + 8 + 32


@pytest.mark.parametrize("name", ["kr270", "irb2400"])
def test_home_points_the_tool_down_above_the_part(name):
    cell = Cell(CellConfig(robot=name))
    state = cell.initial_state()
    wobj = default_T_base_wobj(name)
    np.testing.assert_allclose(cell.workpiece.T_base_wobj, wobj)
    T = state.T_base_tcp
    np.testing.assert_allclose(T[:3, :3], TOOL_DOWN, atol=0.02)
    assert np.linalg.norm(T[:2, 3] - wobj[:2, 3]) < 0.05
    assert 0.05 < T[2, 3] - (wobj[2, 3] + cell.workpiece.surface_z_m) < 0.2


@pytest.mark.parametrize(("name", "margin_deg"), [("kr270", 40.0), ("irb2400", 15.0)])
def test_whole_pump_wall_is_reachable_inside_every_limit(name, margin_deg):
    """Every point of the groove's wall with the tool down, reached with this margin to every
    axis limit and to the IRB 2400's combined axis-2/3 limit."""
    arm = Robot(name, Tool().T_flange_tcp)
    pump = builtin_workpiece("water_pump", robot=name)
    z = pump.wall_z_m[1] - 0.003
    q = arm.home_rad
    for xy in pump.wall.offset(0.001).sample(0.02)[::2]:
        T = np.eye(4)
        T[:3, :3] = TOOL_DOWN
        T[:3, 3] = pump.T_base_wobj[:3, :3] @ np.array([xy[0], xy[1], z]) + pump.T_base_wobj[:3, 3]
        q = arm.ik(T, q)
        margins = [np.degrees(min((q - arm.lower_rad).min(), (arm.upper_rad - q).min()))]
        margins += [np.degrees(c.margin(q)) for c in arm.couplings]
        assert min(margins) > margin_deg
        assert arm.singular_value_min(q) > 0.1
