"""ABB arms: published kinematics, ABB's axis conventions, confdata, placement and stiffness."""

from __future__ import annotations

import math

import numpy as np
import pinocchio as pin
import pytest
import yourdfpy
from hypothesis import given, settings
from hypothesis import strategies as st

from robomach_core.cell import (
    ROBOT_URDFS,
    TOOL_DOWN,
    Cell,
    CellConfig,
    Robot,
    Supervisor,
    Tool,
    program_language,
    true_joint_compliance,
)
from robomach_core.cell.robot import robot_urdf_path
from robomach_core.errors import UnreachableTargetError
from robomach_core.export.rapid import abb_cfx, abb_wrist_centre_in_arm_plane, confdata_from_joints
from robomach_core.part import builtin_workpiece, default_T_base_wobj
from robomach_core.robots import ABB_ARMS, IRB4400, IRB6640, controller_axes_deg, urdf_text
from robomach_core.transforms import rotation_about

ABB = sorted(ABB_ARMS)


@pytest.fixture(scope="module", params=ABB)
def arm(request) -> Robot:
    return Robot(request.param, Tool().T_flange_tcp)


def test_every_arm_is_selectable_and_speaks_its_language():
    assert {"ur10", "ur5", "ur3", "irb4400", "irb6640"} <= set(ROBOT_URDFS)
    assert all(program_language(name) for name in ROBOT_URDFS)
    assert program_language("IRB4400") == "rapid"
    assert program_language("ur10") == "urscript"


@pytest.mark.parametrize("name", ABB)
def test_urdf_file_loads_in_yourdfpy_with_the_published_limits(name):
    path = robot_urdf_path(name)
    assert path.is_file() and path.read_text() == urdf_text(ABB_ARMS[name])
    urdf = yourdfpy.URDF.load(str(path))
    assert urdf.actuated_joint_names == [f"joint_{i}" for i in range(1, 7)]
    spec = ABB_ARMS[name]
    for i, joint in enumerate(urdf.actuated_joint_names):
        limit = urdf.joint_map[joint].limit
        assert math.degrees(limit.lower) == pytest.approx(spec.lower_deg[i], abs=1e-4)
        assert math.degrees(limit.upper) == pytest.approx(spec.upper_deg[i], abs=1e-4)
    # Every link but the flange frame has simple geometry to draw and to collide with.
    assert all(urdf.link_map[f"link_{i}"].visuals for i in range(1, 7))
    assert all(urdf.link_map[f"link_{i}"].collisions for i in range(1, 7))


@pytest.mark.parametrize(
    ("spec", "flange_m"),
    [(IRB4400, (1.220, 0.0, 1.720)), (IRB6640, (1.912, 0.0, 2.055))],
)
def test_zero_pose_is_abbs_calibration_position(spec, flange_m):
    """ABB's axis zeros: upper arm up, forearm ahead; tool0 z forward and x down."""
    robot = Robot(spec.name)
    T = robot.flange_pose(np.zeros(6))
    np.testing.assert_allclose(T[:3, 3], flange_m, atol=1e-9)
    np.testing.assert_allclose(T[:3, 2], (1, 0, 0), atol=1e-9)
    np.testing.assert_allclose(T[:3, 0], (0, 0, -1), atol=1e-9)


def test_positive_axes_turn_as_abb_defines_them():
    """Axis 1 anticlockwise from above, axis 2 leans forward, axis 3 lowers the forearm,
    axis 5 tilts the flange down."""
    robot = Robot("irb4400")
    p0 = robot.flange_pose(np.zeros(6))[:3, 3].copy()
    step = np.radians(5.0)
    assert robot.flange_pose(np.array([step, 0, 0, 0, 0, 0]))[1, 3] > p0[1]
    assert robot.flange_pose(np.array([0, step, 0, 0, 0, 0]))[0, 3] > p0[0]
    assert robot.flange_pose(np.array([0, 0, step, 0, 0, 0]))[2, 3] < p0[2]
    assert robot.flange_pose(np.array([0, 0, 0, 0, step, 0]))[2, 2] < 0.0


def test_parallel_bar_axis_3_is_measured_from_the_horizontal():
    q = np.radians([10.0, 20.0, 30.0, 40.0, 50.0, 60.0])
    np.testing.assert_allclose(controller_axes_deg("irb4400", q), [10, 20, 50, 40, 50, 60])
    np.testing.assert_allclose(controller_axes_deg("irb6640", q), [10, 20, 30, 40, 50, 60])


def test_home_pose_points_the_tool_down_above_the_part(arm):
    cell = Cell(CellConfig(robot=arm.name))
    state = cell.initial_state()
    np.testing.assert_allclose(state.q_motor, arm.home_rad)
    wobj = default_T_base_wobj(arm.name)
    np.testing.assert_allclose(cell.workpiece.T_base_wobj, wobj)
    T = state.T_base_tcp
    np.testing.assert_allclose(T[:3, :3], TOOL_DOWN, atol=0.02)
    assert np.linalg.norm(T[:2, 3] - wobj[:2, 3]) < 0.05
    assert 0.05 < T[2, 3] - (wobj[2, 3] + cell.workpiece.surface_z_m) < 0.2


def test_whole_pump_wall_is_reachable_well_inside_the_limits(arm):
    """The built-in placement: every point of the groove's wall with the tool down is reached
    with >= 15 deg to every axis limit (the IRB 4400's axis 3 counted as ABB measures it)."""
    pump = builtin_workpiece("water_pump", robot=arm.name)
    spec = ABB_ARMS[arm.name]
    z = pump.wall_z_m[1] - 0.003
    q = arm.home_rad
    for xy in pump.wall.offset(0.001).sample(0.02)[::2]:
        T = np.eye(4)
        T[:3, :3] = TOOL_DOWN
        T[:3, 3] = pump.T_base_wobj[:3, :3] @ np.array([xy[0], xy[1], z]) + pump.T_base_wobj[:3, 3]
        q = arm.ik(T, q)
        deg = controller_axes_deg(arm.name, q)
        assert np.all(deg - np.array(spec.lower_deg) > 15.0)
        assert np.all(np.array(spec.upper_deg) - deg > 15.0)
        assert arm.singular_value_min(q) > 0.1


def test_cartesian_stiffness_at_the_work_pose_is_a_big_arms(arm):
    """1-3.5 N/um in the softest translation direction (the issue: ~1-3 N/um)."""
    pump = builtin_workpiece("water_pump", robot=arm.name)
    T = np.eye(4)
    T[:3, :3] = TOOL_DOWN
    T[:3, 3] = pump.T_base_wobj[:3, 3] + (0, 0, pump.surface_z_m - 0.003)
    q = arm.ik(T)
    _, J = arm.fk_and_jacobian(q)
    C = true_joint_compliance(arm.name).cartesian_compliance(J)[:3, :3]
    softest_N_um = 1.0 / np.linalg.eigvalsh(C).max() / 1e6
    assert 1.0 < softest_N_um < 3.5


# -------------------------------------------------------------------------------------------------
# confdata


@pytest.mark.parametrize(
    ("name", "joints_deg", "expected"),
    [
        # calibration position: quadrant 0 everywhere, wrist in front of both, axis 5 >= 0
        ("irb4400", (0, 0, 0, 0, 0, 0), (0, 0, 0, 0)),
        # ABB's quadrants: -90..0 -> -1, 90..180 -> 1, 180..270 -> 2, -450..-360 -> -5
        ("irb4400", (-10, 20, 10, 190, 30, -400), (-1, 2, -5, 0)),
        ("irb4400", (100, 20, 10, -100, -30, 45), (1, -2, 0, 1)),
        # the IRB 6640 bent back over its head: wrist behind axis 1 and the lower arm
        ("irb6640", (0, 0, -150, 0, 30, 0), (0, 0, 0, 6)),
        ("irb6640", (0, 0, -150, 0, -30, 0), (0, 0, 0, 7)),
        # leaning back with the forearm level: behind axis 1, still in front of the lower arm
        ("irb6640", (0, -60, 60, 0, 0, 0), (0, 0, 0, 0)),
    ],
)
def test_confdata_known_cases(name, joints_deg, expected):
    assert confdata_from_joints(np.radians(joints_deg), arm=name) == expected


def test_confdata_behind_axis_1_only():
    """IRB 6640 leaning back 60 deg with the forearm pointing straight up and back."""
    q = np.radians([0, -60, -60, 0, 0, 0])
    x, _ = abb_wrist_centre_in_arm_plane(q, IRB6640)
    assert x < 0
    assert confdata_from_joints(q, arm="irb6640")[3] == 4


def test_ur_arms_keep_their_rule():
    q = np.radians([10, -90, 90, 10, 30, 10])
    assert confdata_from_joints(q) == confdata_from_joints(q, arm="ur10") == (0, 0, 0, 4)


@given(st.sampled_from(ABB), st.lists(st.floats(-1.0, 1.0), min_size=6, max_size=6))
@settings(max_examples=60, deadline=None)
def test_cfx_geometry_matches_the_urdf_model(name, unit):
    """The planar wrist centre of ``abb_cfx`` is pinocchio's axis-5 origin, and the cfx bits
    follow from it as ABB defines them."""
    spec = ABB_ARMS[name]
    lo, hi = np.radians(spec.lower_deg), np.radians(spec.upper_deg)
    q = lo + (np.asarray(unit) + 1.0) / 2.0 * (hi - lo)
    model = pin.buildModelFromXML(urdf_text(spec))
    data = model.createData()
    pin.forwardKinematics(model, data, q)
    wrist = data.oMi[5].translation
    heading = np.array([math.cos(q[0]), math.sin(q[0]), 0.0])
    np.testing.assert_allclose(
        abb_wrist_centre_in_arm_plane(q, spec), [wrist @ heading, wrist[2]], atol=1e-9
    )
    shoulder, elbow = data.oMi[2].translation, data.oMi[3].translation
    lower_arm = elbow - shoulder
    side = np.cross(lower_arm, wrist - shoulder) @ np.array([-heading[1], heading[0], 0.0])
    b = wrist @ heading < 0
    e = side < 0  # the wrist on the other side of the lower arm than the front at q2 = 0
    assert abb_cfx(q, spec) == 4 * b + 2 * e + (q[4] < 0)


@given(
    st.sampled_from(ABB),
    st.tuples(st.floats(-0.2, 0.2), st.floats(-0.2, 0.2), st.floats(-0.1, 0.2)),
    st.floats(-0.3, 0.3),
)
@settings(max_examples=25, deadline=None)
def test_fk_of_ik_is_the_target_around_the_work_pose(name, offset, tilt):
    robot = Robot(name, Tool().T_flange_tcp)
    T = np.eye(4)
    T[:3, :3] = rotation_about("y", tilt) @ TOOL_DOWN
    T[:3, 3] = default_T_base_wobj(name)[:3, 3] + np.array([0.0, 0.0, 0.05]) + offset
    q = robot.ik(T)
    assert robot.within_limits(q)
    np.testing.assert_allclose(robot.fk(q), T, atol=1e-5)


# -------------------------------------------------------------------------------------------------
# The parallel-bar arms' combined axis-2/3 limit (ABB's axis 3 = q2 + q3 in its range)


@pytest.mark.parametrize("name", ["irb4400", "irb2400"])
def test_combined_axis_2_3_limit_holds_at_the_limit_and_refuses_beyond(name):
    """At the limit the joints are allowed; a hair beyond, refused, though each joint is inside
    its own range; the clamp brings them back onto the limit."""
    robot = Robot(name, Tool().T_flange_tcp)
    (coupling,) = robot.couplings
    hi = math.degrees(coupling.upper_rad)
    assert hi == pytest.approx(ABB_ARMS[name].axis3_from_horizontal_deg[1])
    at_limit = np.radians([0.0, 40.0, hi - 40.0, 0.0, 40.0, 0.0])
    beyond = np.radians([0.0, 40.0, hi - 40.0 + 0.5, 0.0, 40.0, 0.0])
    assert np.all(beyond >= robot.lower_rad) and np.all(beyond <= robot.upper_rad)
    assert robot.within_limits(at_limit)
    assert not robot.within_limits(beyond)
    assert controller_axes_deg(name, beyond)[2] == pytest.approx(hi + 0.5)
    clamped = robot.clamp(beyond)
    assert robot.within_limits(clamped)
    assert math.degrees(clamped[1] + clamped[2]) == pytest.approx(hi)
    # a pose that needs axis 3 past its range from the horizontal is out of reach
    T = robot.fk(beyond)
    with pytest.raises(UnreachableTargetError):
        robot.ik(T, beyond)
    assert robot.within_limits(robot.ik(robot.fk(at_limit), at_limit))


def test_supervision_stops_a_step_past_the_combined_limit_and_lets_the_arm_back():
    robot = Robot("irb4400", Tool().T_flange_tcp)
    supervisor = Supervisor(robot)
    near = np.radians([0.0, 40.0, 23.3, 0.0, 40.0, 0.0])  # axis 3 at 63.3 of 65 deg
    further = np.radians([0.0, 40.0, 23.6, 0.0, 40.0, 0.0])
    stop = supervisor.check(near, further)
    assert stop is not None and stop.cause == "joint limit" and stop.axis == 3
    assert "axis 3 from the horizontal" in stop.message and "65 deg" in stop.message
    assert supervisor.check(further, near) is None  # moving away is never refused
    assert supervisor.speed_scale(np.radians([0, 40, 20, 0, 40, 0]), near) < 1.0  # slow zone
    assert supervisor.describe(near)["joint_limit_deg"] == pytest.approx(1.7, abs=1e-6)
    # the IRB 6640 has no parallel bar: no combined limit
    assert Robot("irb6640").couplings == ()
