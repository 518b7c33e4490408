from __future__ import annotations

import math
import typing

import numpy as np
import pinocchio as pin
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from robomach_core.cell import (
    HOME_JOINTS_RAD,
    TOOL_DOWN,
    Cell,
    ComplianceSelection,
    GuidePoint,
    LeadThrough,
    Supervisor,
    cell_supervisor,
)
from robomach_core.cell.supervision import FixtureBox, SupervisionCause, SupervisionLimits
from robomach_core.errors import InvalidInputError, SupervisionError
from robomach_core.learning.route import plan_route
from robomach_core.learning.run import learn_path
from robomach_core.learning.settings import PathLearningSettings
from robomach_core.transforms import make_transform

CAUSES = set(typing.get_args(SupervisionCause))
XYZ = ComplianceSelection(frozenset({"x", "y", "z"}), "base")
MAX_JUMP_DEG = 5.0


@pytest.fixture(scope="module")
def cell() -> Cell:
    return Cell()


@pytest.fixture(scope="module")
def supervisor(cell) -> Supervisor:
    return cell_supervisor(cell)


def _home_with(**joints_deg: float) -> np.ndarray:
    q = HOME_JOINTS_RAD.copy()
    for name, deg in joints_deg.items():
        q[int(name[1:]) - 1] = math.radians(deg)
    return q


def _assert_named(error: SupervisionError) -> None:
    assert error.cause in CAUSES
    assert str(error).startswith(error.cause)
    assert error.state is not None


# --- the acceptance: random pushes, +Z until refused, down to the table ----------------------


def test_random_pushes_never_jump_and_every_refusal_is_named(cell):
    """300 pushes of 10-30 N for 0.3 s in random directions, compliant in x, y, z.

    The directions scatter around a drift that turns every 50 pushes (down, out, up, in, left,
    right), so the walk reaches the table, the part and the edge of reach instead of circling
    Home.
    """
    lt = LeadThrough(cell)
    state = lt.start(cell.initial_state())
    rng = np.random.default_rng(7)
    drifts = np.array([[0, 0, -1], [1, 0, 0], [0, 0, 1], [-1, 0, 0], [0, 1, 0], [0, -1, 0.0]])
    refusals = []
    for k in range(300):
        direction = rng.normal(size=3) * 0.5 + drifts[(k // 50) % 6]
        push = np.concatenate([direction / np.linalg.norm(direction), np.zeros(3)])
        push[:3] *= rng.uniform(10.0, 30.0)
        q_before = state.cell.q_motor.copy()
        try:
            state = lt.push(state, push, XYZ, 0.3)
        except SupervisionError as error:
            _assert_named(error)
            refusals.append(error.cause)
            state = error.state
            p_stop = state.cell.T_base_tcp[:3, 3].copy()
            state = lt.push(state, -push, XYZ, 0.3)  # the other way: moves again
            assert np.linalg.norm(state.cell.T_base_tcp[:3, 3] - p_stop) > 0.001
        q = state.cell.q_motor
        assert np.all(np.isfinite(q)) and np.all(np.isfinite(state.cell.T_base_tcp))
        assert np.degrees(np.abs(q - q_before)).max() < MAX_JUMP_DEG
    assert len(refusals) >= 2


def test_pushing_up_from_home_ends_in_a_named_refusal_without_a_flip(cell):
    """The issue's run: +Z pushes of 10 N, 0.3 s each; it used to flip after 111 pushes."""
    lt = LeadThrough(cell)
    state = lt.start(cell.initial_state())
    up = np.array([0.0, 0.0, 10.0, 0.0, 0.0, 0.0])
    for _ in range(200):
        q_before = state.cell.q_motor.copy()
        try:
            state = lt.push(state, up, XYZ, 0.3)
        except SupervisionError as error:
            _assert_named(error)
            stop = error
            state = error.state
            break
        assert np.degrees(np.abs(state.cell.q_motor - q_before)).max() < MAX_JUMP_DEG
    else:
        pytest.fail("pushing up 200 times was never refused")
    assert stop.cause == "elbow singularity" and stop.axis == 3
    assert "axis 3 at" in str(stop)
    q_deg = np.degrees(state.cell.q_motor)
    # The same branch as Home: elbow up (axis 3 > 0), wrist down (axis 5 at -90), no turns.
    assert 0.0 < q_deg[2] < 10.0
    assert q_deg[4] == pytest.approx(-90.0, abs=1.0)
    np.testing.assert_allclose(q_deg[[0, 5]], 0.0, atol=1.0)
    assert state.cell.T_base_tcp[2, 3] > 0.9  # stopped high, near the edge of reach
    # And down again: moves.
    z = state.cell.T_base_tcp[2, 3]
    state = lt.push(state, -up, XYZ, 0.3)
    assert state.cell.T_base_tcp[2, 3] < z - 0.003


def test_pushing_down_beside_the_part_stops_the_tool_at_the_table(cell, supervisor):
    lt = LeadThrough(cell)
    state = lt.start(cell.initial_state())  # Home: 77 mm in front of the part's edge
    down = np.array([0.0, 0.0, -20.0, 0.0, 0.0, 0.0])
    r = cell.tool.radius_m
    table = supervisor.table_z_m
    for _ in range(100):
        try:
            state = lt.push(state, down, XYZ, 0.3)
        except SupervisionError as error:
            _assert_named(error)
            assert str(error).startswith("collision: tool with the table")
            state = error.state
            break
        assert state.cell.T_base_tcp_true[2, 3] - r >= table
    else:
        pytest.fail("the tool was never stopped above the table")
    gap = state.cell.T_base_tcp_true[2, 3] - r - table
    assert 0.0 <= gap <= 0.001  # at the table, never below it
    # Sliding along the table is not approaching it: full speed (9 N / 500 N s/m * 0.3 s).
    p = state.cell.T_base_tcp[:3, 3].copy()
    state = lt.push(state, np.array([0.0, 10.0, 0.0, 0, 0, 0]), XYZ, 0.3)
    assert state.cell.T_base_tcp[1, 3] - p[1] > 0.005
    state = lt.push(state, -down, XYZ, 0.3)  # and up again
    assert state.cell.T_base_tcp[2, 3] - r - table > 0.005


# --- each limit on its own ----------------------------------------------------------------


def test_margins_are_the_known_angles_of_a_ur_arm(supervisor):
    """UR: the wrist margin is |axis 5|, the elbow margin |axis 3| (both from 0)."""
    for deg in (1.0, 4.0, 30.0):
        m = supervisor.margins(_home_with(q5=-deg, q3=deg))
        assert math.degrees(m[6]) == pytest.approx(deg, abs=1e-6)
        assert math.degrees(m[7]) == pytest.approx(deg, abs=1e-6)


def test_shoulder_margin_vanishes_where_the_jacobian_does(cell, supervisor):
    q2s = np.linspace(-2.2, -3.0, 81)
    shoulder = [supervisor.margins(_home_with(q2=math.degrees(a)))[8] for a in q2s]
    sigma = [cell.robot.singular_value_min(_home_with(q2=math.degrees(a))) for a in q2s]
    assert abs(int(np.argmin(shoulder)) - int(np.argmin(sigma))) <= 1
    assert min(shoulder) < 0.01


@settings(max_examples=40, deadline=None)
@given(st.lists(st.floats(-2 * math.pi, 2 * math.pi), min_size=6, max_size=6))
def test_compiled_kinematics_agree_with_pinocchio(supervisor, q):
    q = np.array(q)
    data = supervisor.robot.model.createData()
    pin.forwardKinematics(supervisor.robot.model, data, q)
    Ts = supervisor.joint_placements(q)
    for j in range(6):
        np.testing.assert_allclose(Ts[j], data.oMi[j + 1].homogeneous, atol=1e-12)


@pytest.mark.parametrize(
    ("before", "after", "cause", "text"),
    [
        ({"q5": -3.4}, {"q5": -2.9}, "wrist singularity", "wrist singularity: axis 5 at -2.9 deg"),
        ({"q3": 5.4}, {"q3": 4.8}, "elbow singularity", "axis 3 at 4.8 deg"),
        ({"q1": 357.7}, {"q1": 358.1}, "joint limit", "joint limit: axis 1 at 358.1 deg"),
        ({"q2": -146.6}, {"q2": -147.0}, "shoulder singularity", "from the axis-1 line"),
    ],
)
def test_a_step_past_a_limit_is_refused_and_a_step_back_is_not(
    supervisor, before, after, cause, text
):
    q0, q1 = _home_with(**before), _home_with(**after)
    stop = supervisor.check(q0, q1)
    assert stop is not None and stop.cause == cause and text in stop.message
    assert supervisor.check(q1, q0) is None  # back out of it
    assert supervisor.speed_scale(q0, q1) == SupervisionLimits().min_speed_scale  # slowed in
    assert supervisor.speed_scale(q1, q0) > 0.5  # and not, or less, on the way out


@settings(max_examples=60, deadline=None)
@given(
    st.lists(st.floats(-1.2, 1.2), min_size=6, max_size=6),
    st.lists(st.floats(-1.0, 1.0), min_size=6, max_size=6),
)
def test_from_a_safe_state_the_way_back_is_never_refused(supervisor, offset, direction):
    """Whatever a step runs into, stepping back to where it came from is allowed."""
    q0 = HOME_JOINTS_RAD + np.array(offset)
    margins = supervisor.margins(q0)
    stops = np.array([m.stop for m in supervisor._margin_defs])
    if np.any(margins < stops):
        return  # not a safe state to start from
    q1 = q0 + np.array(direction) * supervisor._step_bound  # within the joint-speed bound
    supervisor.check(q0, q1)  # refused or not, ...
    assert supervisor.check(q1, q0) is None  # ... the way back is open
    assert 0.0 < supervisor.speed_scale(q0, q1) <= 1.0


def test_a_joint_step_beyond_the_velocity_limit_is_refused(supervisor):
    q0 = HOME_JOINTS_RAD.copy()
    q1 = q0 + np.array([0.0, 0.0, 0.0, 0.1, 0.0, 0.0])  # 5.7 deg in 4 ms
    stop = supervisor.check(q0, q1)
    assert stop.cause == "joint speed" and stop.axis == 4
    assert supervisor.speed_scale(q0, q1) < 0.2  # or scaled down to fit
    stop = supervisor.check(q0, q0 + np.array([np.nan, 0, 0, 0, 0, 0]))
    assert stop.cause == "edge of reach"


def test_wrist_singularity_by_jogging_the_orientation(cell):
    lt = LeadThrough(cell)
    state = lt.start(cell.initial_state(_home_with(q5=-25.0)))
    stiff = ComplianceSelection(frozenset(), "tool")
    with pytest.raises(SupervisionError, match=r"wrist singularity: axis 5 at -\d\.\d deg") as info:
        for _ in range(40):
            state = lt.jog(state, "ry", math.radians(-2.0), stiff)
    state = info.value.state
    assert abs(math.degrees(state.cell.q_motor[4])) >= 2.9
    state = lt.jog(state, "ry", math.radians(2.0), stiff)  # back out
    assert abs(math.degrees(state.cell.q_motor[4])) > 4.0


def test_a_fixture_clamp_stops_the_tool(cell):
    p_home = cell.robot.fk(HOME_JOINTS_RAD)[:3, 3]
    clamp = FixtureBox(
        (0.04, 0.04, 0.02), make_transform(np.eye(3), p_home - [0, 0, 0.1]), name="clamp"
    )
    lt = LeadThrough(cell, supervisor=Supervisor(cell.robot, cell.tool, fixture=[clamp]))
    state = lt.start(cell.initial_state())
    with pytest.raises(SupervisionError, match="collision: tool with the clamp") as info:
        lt.push(state, np.array([0.0, 0.0, -20.0, 0, 0, 0]), XYZ, 5.0)
    top = p_home[2] - 0.1 + 0.01
    assert info.value.state.cell.T_base_tcp[2, 3] - cell.tool.radius_m >= top


def test_path_learning_stops_before_a_clamp_and_says_why():
    cell = Cell()
    wp = cell.workpiece
    guides = []
    for x in (-0.094, -0.078):
        T = np.eye(4)
        T[:3, :3] = TOOL_DOWN
        T[:3, 3] = wp.T_base_wobj[:3, 3] + np.array([x, -0.0625, wp.surface_z_m - 0.003])
        guides.append(GuidePoint(T, cell.robot.ik(T), 0.0))
    # A clamp on the part 25 mm past the last guide point: the spindle (30 mm radius) meets it.
    centre = wp.T_base_wobj[:3, 3] + np.array([-0.048, -0.0625, wp.surface_z_m + 0.02])
    clamp = FixtureBox((0.01, 0.08, 0.02), make_transform(np.eye(3), centre), name="clamp")
    supervisor = Supervisor(cell.robot, cell.tool, wp, fixture=[clamp])
    lt = LeadThrough(cell, supervisor=supervisor)
    state = lt.start(cell.initial_state())
    settings_ = PathLearningSettings(closed=False, wall_side="right")
    rec, _ = learn_path(
        cell,
        state.cell,
        plan_route(guides, settings_),
        settings_,
        lt.estimator,
        supervisor=supervisor,
    )
    assert not rec.completed
    assert rec.stop_reason.startswith("supervision: collision: tool (spindle) with the clamp")
    assert len(rec) > 200  # it ran, slowed, then stopped


def test_bad_limits_are_refused(cell):
    with pytest.raises(InvalidInputError):
        SupervisionLimits(wrist_stop_rad=0.3, wrist_slow_rad=0.1)
    with pytest.raises(InvalidInputError):
        FixtureBox((0.0, 0.1, 0.1))
    with pytest.raises(InvalidInputError):
        cell_supervisor(cell).margins(np.full(6, np.nan))
