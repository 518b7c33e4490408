"""Every compiled (numba) kernel of the core against its reference.

A kernel is a private copy of a public function (pinocchio's ``exp3``/``log3`` and kinematics,
the sensor and stiffness models, the supervisor's Python path) or of a documented formula,
compiled because a 4 ms loop needs it. Each is checked here against that reference (or, where
the reference is the same code interpreted, against its ``py_func``); ``KERNEL_TESTS`` names
the test of every kernel, and a kernel without one fails the contract test.
"""

from __future__ import annotations

import importlib
import math
import pkgutil

import numpy as np
import pinocchio as pin
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from numba.core.registry import CPUDispatcher

import robomach_core
from robomach_core import _kernels
from robomach_core.cell import (
    Cell,
    CellConfig,
    ForceEstimator,
    Robot,
    Tool,
    ToolGravity,
    cell_supervisor,
    compensate_gravity,
    contact_reading,
    gravity_reading,
    true_joint_compliance,
    wrench_at_tcp_in_base,
)
from robomach_core.cell.contact import ContactModel
from robomach_core.cell.supervision import _kernels as sk
from robomach_core.learning import law as cf
from robomach_core.learning.run import contour_law_parameters
from robomach_core.learning.settings import PathLearningSettings
from robomach_core.part import builtin_workpiece
from robomach_core.stiffness.model import loaded_equilibrium
from robomach_core.transforms import pose_error

vectors = st.lists(st.floats(-3.0, 3.0), min_size=3, max_size=3).map(np.array)
unit_axes = vectors.filter(lambda v: np.linalg.norm(v) > 1e-3).map(lambda v: v / np.linalg.norm(v))


@pytest.fixture(scope="module")
def ur10() -> Robot:
    return Robot("ur10", Tool().T_flange_tcp)


@pytest.fixture(scope="module")
def cell() -> Cell:
    return Cell()


def _random_rotation(rng: np.random.Generator) -> np.ndarray:
    return pin.exp3(rng.uniform(-math.pi, math.pi, 3))


# --- SO(3) and small linear algebra ----------------------------------------------------------


@given(vectors)
@settings(max_examples=200, deadline=None)
def test_exp3_is_pinocchios(w):
    np.testing.assert_allclose(_kernels.exp3(w), pin.exp3(w), atol=1e-14)
    tiny = w * 1e-14
    np.testing.assert_allclose(_kernels.exp3(tiny), pin.exp3(tiny), atol=1e-14)


@given(unit_axes, st.one_of(st.floats(0.0, math.pi), st.floats(math.pi - 0.05, math.pi - 1e-9)))
@settings(max_examples=300, deadline=None)
def test_log3_is_pinocchios_from_identity_to_pi(axis, angle):
    R = pin.exp3(axis * angle)
    np.testing.assert_allclose(_kernels.log3(R), pin.log3(R), atol=2e-7)


@given(unit_axes, st.floats(-math.pi, math.pi))
@settings(max_examples=100, deadline=None)
def test_rotate_about_is_rodrigues(axis, angle):
    R = np.empty((4, 4))
    _kernels.rotate_about(R, *axis, math.sin(angle), math.cos(angle))
    np.testing.assert_allclose(R[:3, :3], pin.exp3(axis * angle), atol=1e-14)


def test_small_products_and_the_solve_are_numpys():
    rng = np.random.default_rng(0)
    for _ in range(50):
        A, B = rng.normal(size=(4, 4)), rng.normal(size=(4, 4))
        v = rng.normal(size=6)
        np.testing.assert_allclose(_kernels.mul3(A, B), A[:3, :3] @ B[:3, :3], atol=1e-14)
        np.testing.assert_allclose(
            _kernels.mul3(A, B, False, True), A[:3, :3] @ B[:3, :3].T, atol=1e-14
        )
        np.testing.assert_allclose(_kernels.mul3(A, B, True), A[:3, :3].T @ B[:3, :3], atol=1e-14)
        np.testing.assert_allclose(_kernels.rotate(A, v, 3), A[:3, :3] @ v[3:], atol=1e-14)
        np.testing.assert_allclose(_kernels.rotate(A, v, 0, True), A[:3, :3].T @ v[:3], atol=1e-14)
        np.testing.assert_allclose(_kernels.cross(v[:3], v[3:]), np.cross(v[:3], v[3:]))
        M = rng.normal(size=(6, 6)) + 3 * np.eye(6)
        np.testing.assert_allclose(_kernels.solve(M, v), np.linalg.solve(M, v), rtol=1e-10)
        lo, hi = -np.abs(v), np.abs(v) * 0.5
        q = rng.normal(size=6)
        np.testing.assert_array_equal(_kernels.clamp(q, lo, hi), np.clip(q, lo, hi))
    assert np.isnan(_kernels.solve(np.zeros((3, 3)), np.ones(3))).all()


# --- kinematics: the IK step, the chain, the Jacobian -----------------------------------------


def _ik_step_reference(q, T, J, T_target, lower, upper, damping):
    """``Robot.ik_step``'s formula in numpy: Newton, damped least squares when the step is big."""
    e = pose_error(T, T_target)
    dq = np.linalg.solve(J, e)
    if dq @ dq > 1e-4:
        dq = J.T @ np.linalg.solve(J @ J.T + damping**2 * np.eye(6), e)
    return np.clip(q + dq, lower, upper)


@given(st.lists(st.floats(-0.5, 0.5), min_size=6, max_size=6), st.floats(1e-6, 0.2))
@settings(max_examples=60, deadline=None)
def test_ik_newton_step_is_the_damped_newton_step(ur10, dq, reach):
    q = ur10.home_rad + np.array(dq)
    T, J = ur10.fk_and_jacobian(q)
    T_target = ur10.fk(ur10.home_rad).copy()
    T_target[:3, 3] += reach * np.array([0.6, -0.64, 0.48])
    want = _ik_step_reference(q, T, J, T_target, ur10.lower_rad, ur10.upper_rad, 1e-4)
    got = _kernels.ik_newton_step(q, T, J, T_target, ur10.lower_rad, ur10.upper_rad, 1e-4)
    np.testing.assert_allclose(got, want, atol=1e-10)


@given(st.lists(st.floats(-2.0, 2.0), min_size=6, max_size=6))
@settings(max_examples=40, deadline=None)
def test_the_chains_pose_and_jacobian_are_pinocchios(cell, q):
    supervisor = cell_supervisor(cell)
    model = supervisor._model
    q = np.array(q)
    margins, T_tcp, J, _ = sk.margins_at(q, model)
    Ts = sk.chain_placements(q, supervisor._placements, supervisor._axes)
    robot = supervisor.robot
    T_pin, J_pin = robot.fk_and_jacobian(q)
    np.testing.assert_allclose(T_tcp, T_pin, atol=1e-13)
    np.testing.assert_allclose(J, J_pin, atol=1e-13)
    data = robot.model.createData()
    pin.forwardKinematics(robot.model, data, q)
    for j in range(6):
        np.testing.assert_allclose(Ts[j], data.oMi[j + 1].homogeneous, atol=1e-13)
    z = np.array([Ts[j, :3, :3] @ supervisor._axes[j] for j in range(6)])
    np.testing.assert_allclose(sk.tcp_jacobian(z, Ts[:, :3, 3].copy(), T_tcp), J_pin, atol=1e-13)
    np.testing.assert_array_equal(margins[:6], np.minimum(q - robot.lower_rad, robot.upper_rad - q))


# --- the arm's deflection and the sensor ------------------------------------------------------


@given(st.lists(st.floats(-300.0, 300.0), min_size=6, max_size=6))
@settings(max_examples=40, deadline=None)
def test_arm_side_pose_is_the_linear_stiffness_model(ur10, wrench):
    W = np.array(wrench) * np.array([1, 1, 1, 0.01, 0.01, 0.01])
    q = ur10.home_rad + 0.2
    truth = true_joint_compliance("ur10")
    T, J = ur10.fk_and_jacobian(q)
    p_before = T[:3, 3] - 1e-5
    T_arm, dq, velocity = _kernels.arm_side_pose(T, J, W, truth.compliance_rad_Nm, p_before, 0.004)
    linear = loaded_equilibrium(ur10, q, W, truth, mode="linear")
    np.testing.assert_allclose(T_arm, linear.T_base_tcp, atol=1e-15)
    np.testing.assert_allclose(dq, linear.joints_arm_rad - q, atol=1e-15)
    np.testing.assert_allclose(velocity, (T_arm[:3, 3] - p_before) / 0.004)
    # To first order the arm side is the motor side turned by the deflection.
    np.testing.assert_allclose(T_arm, ur10.fk(q + dq), atol=1e-6)


def test_the_sensor_kernels_are_the_sensor_model():
    rng = np.random.default_rng(1)
    tool = Tool()
    load = ToolGravity(2.5, (0.001, -0.002, 0.07), (1.0, -2.0, 0.5), (0.02, 0.01, -0.03))
    weight = load.mass_kg * np.array([0.0, 0.0, -9.81])
    tcp = np.asarray(tool.tcp_offset_m, dtype=float)
    com = np.asarray(load.com_m, dtype=float)
    for _ in range(50):
        R = _random_rotation(rng)
        W = rng.normal(size=6) * 20
        noise = rng.normal(size=6) * 0.1
        want = contact_reading(R, tcp, W) + gravity_reading(R, load) + noise
        got = _kernels.sensor_reading(
            R, W, np.concatenate([weight, com, tcp, load.bias]), noise[None], 0
        )
        np.testing.assert_allclose(got, want, atol=1e-12)
        back = wrench_at_tcp_in_base(compensate_gravity(got - noise, R, load), R, tcp)
        compiled = _kernels.contact_wrench_tcp_base(got - noise, R, weight, com, tcp, load.bias)
        np.testing.assert_allclose(compiled, back, atol=1e-11)
        np.testing.assert_allclose(compiled, W, atol=1e-11)
    estimator = ForceEstimator(load.mass_kg, com, tcp, load.bias)
    data = estimator.tool_data()
    np.testing.assert_allclose(data, np.concatenate([weight, com, tcp, load.bias]))


# --- contact ----------------------------------------------------------------------------------


def _closest_points(p: np.ndarray, tri: np.ndarray) -> np.ndarray:
    """Closest points of triangles (F, 3, 3) to p, another way than the kernel's (Ericson's
    regions): the projection on the plane when it falls inside (barycentric coordinates by
    least squares), else the nearest of the three edges' clamped projections."""
    a, b, c = tri[:, 0], tri[:, 1], tri[:, 2]
    E = np.stack([b - a, c - a], axis=2)  # (F, 3, 2)
    rhs = np.einsum("fki,fk->fi", E, p - a)[..., None]
    uv = np.linalg.solve(np.einsum("fki,fkj->fij", E, E), rhs)[..., 0]
    inside = (uv >= 0).all(axis=1) & (uv.sum(axis=1) <= 1)
    out = a + np.einsum("fij,fj->fi", E, uv)
    best = np.full(len(tri), np.inf)
    on_edges = np.empty_like(out)
    for s, e in ((a, b), (b, c), (c, a)):
        d = e - s
        t = np.clip(np.einsum("fi,fi->f", p - s, d) / np.einsum("fi,fi->f", d, d), 0.0, 1.0)
        q = s + t[:, None] * d
        dist = np.linalg.norm(p - q, axis=1)
        closer = dist < best
        best[closer], on_edges[closer] = dist[closer], q[closer]
    return np.where(inside[:, None], out, on_edges)


def _ball_contact_reference(model: ContactModel, p, velocity, previous_depth, dt, radius):
    """The ball's contact from the closest points of every face of the part (faces that tie
    at an edge taken in the order the model holds its candidates, as the kernel does)."""
    tri = model._triangles
    closest = _closest_points(p, tri)
    d = np.linalg.norm(p - closest, axis=1)
    order = list(model._candidates) + sorted(set(range(len(tri))) - set(model._candidates))
    near = np.array([f for f in order if d[f] <= radius], dtype=int)
    if len(near) == 0:
        return None
    best = d[near].min()
    ties = near[d[near] <= best + 1e-12]
    behind = [(p - closest[f]) @ model._normals[f] < 0.0 for f in ties]
    if all(behind):
        depth, normal = radius + best, model._normals[ties[0]]
    else:
        depth = radius - best
        if depth <= 0.0:
            return None
        normal = (p - closest[ties[0]]) / best
    point = closest[ties[0]]
    k, c, mu, v0 = model.stiffness_N_m, model.damping_N_s_m, model.friction, 0.0005
    f_n = max(0.0, k * depth + c * (depth - previous_depth) / dt)
    v_t = velocity - (velocity @ normal) * normal
    force = f_n * normal
    speed = np.linalg.norm(v_t)
    if speed > 1e-12 and mu > 0.0:
        force = force - mu * f_n * math.tanh(speed / v0) * v_t / speed
    return depth, normal, np.concatenate([force, np.cross(point - p, force)])


def test_the_balls_contact_is_the_nearest_face_of_the_whole_part():
    """Candidates from coal within a skin, kept while the ball stays in it: every period the
    same as the nearest face over the whole mesh (trimesh's closest points)."""
    pump = builtin_workpiece("water_pump")
    tool = Tool()
    model = ContactModel(tool, pump)
    rng = np.random.default_rng(2)
    faces = rng.integers(0, len(model._triangles), 16)
    checked = 0
    for f in faces:
        surface = model._triangles[f].mean(axis=0)
        start = surface + model._normals[f] * rng.uniform(-0.8, 0.8) * tool.radius_m
        step = rng.normal(size=3) * 4e-5
        for k in range(25):  # a short walk: the candidates serve, then coal is asked again
            p = start + k * step
            T = np.eye(4)
            T[:3, 3] = p
            v = step / 0.004
            got = model.evaluate(T, v, 1e-4, 0.004)
            want = _ball_contact_reference(model, p, v, 1e-4, 0.004, tool.radius_m)
            assert got.in_contact == (want is not None)
            if want is not None:
                checked += 1
                assert got.depth_m == pytest.approx(want[0], abs=1e-9)  # slivers: a nanometre
                np.testing.assert_allclose(got.normal, want[1], atol=1e-6)
                np.testing.assert_allclose(got.wrench, want[2], atol=1e-3)
    assert checked > 100
    point = np.array([0.0, 0.0, 0.001])
    out = _kernels.penalty_wrench(1e-4, np.array([0.0, 0.0, 1.0]), point, np.zeros(3),
                                  np.zeros(3), 0.0, 0.004, model._params)  # fmt: skip
    np.testing.assert_allclose(out[3:6], [0.0, 0.0, model.stiffness_N_m * 1e-4 + 100.0 * 0.025])


def test_boxes_overlapping():
    rng = np.random.default_rng(3)
    lo = rng.uniform(-1, 1, (200, 3))
    hi = lo + rng.uniform(0, 0.3, (200, 3))
    box_lo, box_hi = np.array([-0.2, -0.3, 0.0]), np.array([0.3, 0.2, 0.4])
    want = np.flatnonzero(np.all((hi >= box_lo) & (lo <= box_hi), axis=1))
    np.testing.assert_array_equal(_kernels.boxes_overlapping(lo, hi, box_lo, box_hi), want)


# --- lead-through and path learning's controller ----------------------------------------------


def test_the_admittance_step_is_its_formula():
    rng = np.random.default_rng(4)
    mass, damping = np.array([2.0] * 3 + [0.05] * 3), np.array([500.0] * 3 + [10.0] * 3)
    deadband, limit = np.array([1.0] * 3 + [0.05] * 3), np.array([0.05] * 3 + [0.5] * 3)
    for _ in range(20):
        args = (
            np.eye(4), _random_rotation(rng), rng.normal(size=6) * 0.01, rng.normal(size=6) * 20,
            (rng.uniform(size=6) > 0.3).astype(float), mass, damping, deadband, limit, 0.004,
        )  # fmt: skip
        T, v = _kernels.admittance_reference(*args)
        T_ref, v_ref = _kernels.admittance_reference.py_func(*args)
        np.testing.assert_allclose(T, T_ref, atol=1e-14)
        np.testing.assert_allclose(v, v_ref, atol=1e-14)
    push = np.array([0.5, -0.5, 0.5, 0.01, -0.01, 0.01])  # inside the deadband
    still = _kernels.admittance_reference(
        np.eye(4), np.eye(3), np.zeros(6), push, np.ones(6), mass, damping, deadband, limit, 0.004
    )
    np.testing.assert_array_equal(still[0], np.eye(4))  # no drift


def _turn_reference(R_ref, Ra, omega, a, xp, length, p, max_turn):
    f = min(max(float((p - a) @ xp) / length, 0.0), 1.0)
    turn = pin.log3(R_ref.T @ Ra @ pin.exp3(omega * f))
    angle = np.linalg.norm(turn)
    return turn * (max_turn / angle) if angle > max_turn else turn


def test_the_controller_period_is_its_parts(cell):
    """One period of path learning's controller: the compensated wrench (sensor model), the law
    (its Python form), the recording's row and the turn (pinocchio's SO(3))."""
    rng = np.random.default_rng(5)
    estimator = ForceEstimator.from_tool(cell.tool)
    estimator.bias = rng.normal(size=6)
    params = contour_law_parameters(PathLearningSettings())
    axis = np.array([0.0, 0.0, -1.0])
    Ra = _random_rotation(rng)
    h_dir = np.array([0.995, 0.1, 0.0]) / np.linalg.norm([0.995, 0.1, 0.0])  # the height's chord
    leg = np.concatenate([[0.1, 0.2, 0.0], [1.0, 0.0, 0.0], [0.05], Ra.ravel(),
                          [0.0, 0.0, 0.3], [2.0], [0.001, -0.002],
                          [0.1, 0.201, 0.0], h_dir, [0.048]])  # fmt: skip
    ref = np.array([0.001, 0.1, -0.2, 0.0, 0.1, 0.2, 0.0, -1.05])
    R_tcp_flange = cell.tool.T_flange_tcp[:3, :3].T.copy()
    for _ in range(20):
        T_meas = np.eye(4)
        T_meas[:3, :3] = _random_rotation(rng)
        T_meas[:3, 3] = [0.12, 0.2 + rng.normal() * 1e-3, 0.0]
        T_ref = T_meas.copy()
        reading, q = rng.normal(size=6) * 5, rng.normal(size=6)
        w, state = np.array([0.0, 1.0, 0.0]), cf.initial_state()
        step, turn, record = np.zeros(3), np.zeros(3), np.zeros((2, cf.REC_WIDTH))
        w0, state0 = w.copy(), state.copy()
        out = cf.controller_period(reading, T_meas, q, 0.5, estimator.tool_data(),
                                   R_tcp_flange, leg, ref, axis, 1.0, T_ref, w, state, params,
                                   0.002, step, turn, record, 1)  # fmt: skip
        wrench = estimator.contact_wrench_tcp_base(reading, T_meas[:3, :3] @ R_tcp_flange)
        law = cf.contour_law.py_func(wrench[:3], w0, axis, 1.0, leg, ref, T_ref[:3, 3].copy(),
                                     state0, params)  # fmt: skip
        np.testing.assert_allclose(step, law[0], atol=1e-12)
        np.testing.assert_allclose(w, law[1], atol=1e-12)
        np.testing.assert_allclose(state, law[2], atol=1e-12)
        want_turn = _turn_reference(T_ref[:3, :3], Ra, leg[16:19], leg[:3], leg[3:6], leg[6],
                                    T_ref[:3, 3] + law[0], 0.002)  # fmt: skip
        np.testing.assert_allclose(turn, want_turn, atol=1e-9)
        assert out[0] == pytest.approx(np.linalg.norm(wrench[:3]), abs=1e-9)
        tangent = np.cross(w, axis)  # side +1: the advance is the step along the wall only
        assert out[5] == pytest.approx(abs(float(step @ tangent)), abs=1e-15)
        row = record[1]
        assert row[cf.REC_TIME] == 0.5 and row[cf.REC_SEGMENT] == 2.0
        np.testing.assert_array_equal(row[cf.REC_JOINTS : cf.REC_JOINTS + 6], q)
        np.testing.assert_array_equal(row[cf.REC_SENSOR : cf.REC_SENSOR + 6], reading)
        tool_frame = np.concatenate([T_meas[:3, :3].T @ wrench[:3], T_meas[:3, :3].T @ wrench[3:]])
        np.testing.assert_allclose(row[cf.REC_TOOL : cf.REC_TOOL + 6], tool_frame, atol=1e-9)
        assert out[6] == pytest.approx((T_ref[:3, 3] - leg[:3]) @ leg[3:6])


# --- supervision ------------------------------------------------------------------------------


def test_decide_and_the_margins_are_their_python_forms(cell):
    supervisor = cell_supervisor(cell)
    model = supervisor._model
    rng = np.random.default_rng(6)
    robot = cell.robot
    for _ in range(20):
        q0 = robot.home_rad + rng.normal(size=6) * 0.5
        q1 = q0 + rng.normal(size=6) * 0.01
        m0, T0, _, _ = sk.margins_at(q0, model)
        m1, T1, _, n1 = sk.margins_at(q1, model)
        ref = sk.margins_at.py_func(q1, model, sk._unpack.py_func(model))
        np.testing.assert_allclose(m1, ref[0], atol=1e-12, equal_nan=True)
        np.testing.assert_allclose(T1, ref[1], atol=1e-13)
        assert n1 == ref[3]
        got = sk.decide(m0, m1, q0, q1, T0, T1, True, model)
        want = sk.decide.py_func(m0, m1, q0, q1, T0, T1, True, model, sk._unpack(model))
        assert got[1:3] == want[1:3] and got[0] == pytest.approx(want[0], abs=1e-15)


def test_the_compiled_supervised_period_is_supervise_with_its_proposal(cell):
    """``supervise_increment`` (one compiled call) decides as ``Supervisor.supervise`` does with
    ``increment_proposal`` as the controller's proposal: steps that pass, slow down near a limit
    or are refused."""
    supervisor = cell_supervisor(cell)
    robot = cell.robot
    model = supervisor._model
    rng = np.random.default_rng(7)
    outcomes = set()
    for k in range(60):
        q = robot.home_rad + rng.normal(size=6) * 0.4
        if k % 3 == 0:  # near axis 2's limit: slowed, refused
            q[1] = robot.lower_rad[1] + rng.uniform(0.03, 0.2)
        T_ref = robot.fk(q).copy()
        step = rng.normal(size=3) * 10 ** rng.uniform(-6, -2.5)
        turn = rng.normal(size=3) * 1e-3
        memory = np.full(sk.MEMORY_MARGINS + len(supervisor._margin_defs), np.nan)
        status, scale, code, index, value, T_next, q_next = sk.supervise_increment(
            q, T_ref, step, turn, model, memory
        )
        if status < 0:
            continue
        m0, T0, J0, _ = sk.margins_at(q, model)

        def propose(s: float, q=q, T0=T0, J0=J0, T_ref=T_ref, step=step, turn=turn):
            return sk.increment_proposal(q, T0, J0, T_ref, step, turn, s, model)

        supervisor._recent = ()
        python = supervisor.supervise(q, propose)
        assert scale == pytest.approx(python.scale, abs=1e-12)
        np.testing.assert_allclose(q_next, python.q_next, atol=1e-12)
        np.testing.assert_allclose(T_next, python.T_ref, atol=1e-12)
        assert (code == 0) == (python.stop is None)
        outcomes.add("stop" if code else ("slowed" if scale < 1.0 else "free"))
        T_want = T_ref.copy()
        T_want[:3, :3] = T_ref[:3, :3] @ pin.exp3(turn * scale)
        T_want[:3, 3] += step * scale
        np.testing.assert_allclose(T_next, T_want, atol=1e-13)
        want_q = _ik_step_reference(q, T0, J0, T_want, robot.lower_rad, robot.upper_rad, 1e-4)
        np.testing.assert_allclose(q_next, want_q, atol=1e-10)
    assert outcomes == {"free", "slowed", "stop"}


# --- the contract ------------------------------------------------------------------------------

# Every compiled function of the core -> the test that holds it to its reference.
FAST_COPIES = (
    "tests/core/machining/test_trust.py::"
    "test_the_fast_copy_of_each_controller_equals_its_public_step"
)
REDUCTION = (
    "tests/core/postprocess/test_postprocess.py::"
    "test_compiled_reduction_equals_the_literal_fig3_scan"
)
CONTOUR_LAW = "tests/core/learning/test_law.py::test_the_compiled_law_equals_its_reference"
BALL = "test_the_balls_contact_is_the_nearest_face_of_the_whole_part"
SUPERVISED = "test_the_compiled_supervised_period_is_supervise_with_its_proposal"
_TESTS_BY_MODULE: dict[str, dict[str, str]] = {
    "robomach_core._kernels": {
        "exp3": "test_exp3_is_pinocchios",
        "log3": "test_log3_is_pinocchios_from_identity_to_pi",
        "rotate_about": "test_rotate_about_is_rodrigues",
        **dict.fromkeys(
            ("mul3", "rotate", "cross", "solve", "clamp"),
            "test_small_products_and_the_solve_are_numpys",
        ),
        "ik_newton_step": "test_ik_newton_step_is_the_damped_newton_step",
        "arm_side_pose": "test_arm_side_pose_is_the_linear_stiffness_model",
        "sensor_reading": "test_the_sensor_kernels_are_the_sensor_model",
        "contact_wrench_tcp_base": "test_the_sensor_kernels_are_the_sensor_model",
        **dict.fromkeys(
            ("ball_contact", "_closest_on_triangle", "penalty_wrench", "_penalty_wrench"), BALL
        ),
        "boxes_overlapping": "test_boxes_overlapping",
        "admittance_reference": "test_the_admittance_step_is_its_formula",
        "deviation_height_kept": REDUCTION,
        "_first_failing_end": REDUCTION,
    },
    "robomach_core.learning.law": {
        "contour_law": CONTOUR_LAW,
        "speed_ratio": CONTOUR_LAW,
        "route_height": CONTOUR_LAW,
        **dict.fromkeys(
            ("turn_towards", "controller_period", "record_row"),
            "test_the_controller_period_is_its_parts",
        ),
    },
    "robomach_core.cell.supervision._kernels": {
        **dict.fromkeys(
            ("chain_placements", "tcp_jacobian", "_compose"),
            "test_the_chains_pose_and_jacobian_are_pinocchios",
        ),
        **dict.fromkeys(
            ("margins_at", "_unpack", "_row", "_dot", "_cross", "_axpy", "_end"),
            "test_decide_and_the_margins_are_their_python_forms",
        ),
        "decide": "test_decide_and_the_margins_are_their_python_forms",
        **dict.fromkeys(
            ("convex_clearance", "_difference_support", "_nearest_on_simplex"),
            "test_the_gjk_clearance_near_the_part_is_coals",
        ),
        **dict.fromkeys(("increment_proposal", "supervise_increment"), SUPERVISED),
    },
    "robomach_core.cmrr.controllers._fast": dict.fromkeys(
        (
            "_memberships",
            "_fuzzy_infer",
            "_lq_estimate",
            "_lq_act",
            "lq_command",
            "lq_matching_integral",
        ),
        FAST_COPIES,
    ),
    "robomach_core.machining._kernel": {
        **dict.fromkeys(
            (
                "cut_kernel",
                "_power",
                "_fixed_pi_step",
                "_adaptive_pi_step",
                "_switch_level",
                "_fuzzy_step",
                "_lq_step",
                "_record",
                "_process_force",
                "_feed_step",
            ),
            "tests/core/machining/test_kernel.py::test_the_compiled_loop_equals_the_reference",
        ),
        **dict.fromkeys(
            ("speed_profile", "lowest_reach"),
            "tests/core/machining/test_kernel.py::test_the_stations_kernels_equal_numpy",
        ),
        "ball_envelope": "tests/core/machining/test_kernel.py::"
        "test_the_compiled_ball_envelope_equals_its_reference",
        "split_by_deviation": "tests/core/machining/test_kernel.py::"
        "test_the_compiled_target_placement_equals_its_reference",
    },
}
KERNEL_TESTS: dict[str, str] = {
    f"{module}.{name}": test
    for module, tests in _TESTS_BY_MODULE.items()
    for name, test in tests.items()
}


def _compiled_functions() -> set[str]:
    found = set()
    for info in pkgutil.walk_packages(robomach_core.__path__, "robomach_core."):
        module = importlib.import_module(info.name)
        for name, obj in vars(module).items():
            if isinstance(obj, CPUDispatcher) and obj.py_func.__module__ == info.name:
                found.add(f"{info.name}.{name}")
    return found


def test_every_compiled_kernel_has_a_reference_test():
    compiled = _compiled_functions()
    assert compiled - set(KERNEL_TESTS) == set(), "compiled kernels without a reference test"
    assert set(KERNEL_TESTS) - compiled == set(), "tests named for kernels that are gone"
    here = globals()
    for kernel, test in KERNEL_TESTS.items():
        if "::" in test:
            path, name = test.split("::")
            module = importlib.import_module(path.removesuffix(".py").replace("/", "."))
            assert callable(getattr(module, name)), f"{kernel}: no test {test}"
        else:
            assert callable(here.get(test)), f"{kernel}: no test {test}"


def test_the_gjk_clearance_of_a_cylinder_and_a_box_is_the_geometry():
    """``convex_clearance`` on cases whose answer is plain geometry: a unit box and a flat-ended
    cylinder (or a capsule) above it, beside it, over its edge; overlapping: NaN."""
    box = np.array([[x, y, z] for x in (0, 1) for y in (0, 1) for z in (0, 1)], dtype=float)
    clearance = sk.convex_clearance
    assert clearance(box, (0.5, 0.5, 1.5), (0.5, 0.5, 3.0), 0.2, True) == pytest.approx(0.5)
    assert clearance(box, (1.5, 0.5, 0.2), (1.5, 0.5, 0.8), 0.2, True) == pytest.approx(0.3)
    # The disc overhangs the edge: its flat bottom is nearest, 0.2 above the top face.
    assert clearance(box, (1.1, 0.5, 1.2), (1.1, 0.5, 2.0), 0.3, True) == pytest.approx(0.2)
    # A capsule's sphere over the edge: the distance from its centre to the edge, less r.
    got = clearance(box, (1.1, 0.5, 1.2), (1.1, 0.5, 2.0), 0.1, False)
    assert got == pytest.approx(math.hypot(0.1, 0.2) - 0.1)
    assert math.isnan(clearance(box, (0.5, 0.5, 0.9), (0.5, 0.5, 2.0), 0.2, True))
    assert clearance.py_func(box, (1.1, 0.5, 1.2), (1.3, 0.5, 2.0), 0.3, True) == pytest.approx(
        clearance(box, (1.1, 0.5, 1.2), (1.3, 0.5, 2.0), 0.3, True), abs=1e-15
    )


@pytest.mark.parametrize("part", ["water_pump", "block"])
def test_the_gjk_clearance_near_the_part_is_coals(part):
    """Near an obstacle ``margins_at`` measures the clearance itself (GJK) and leaves NaN for
    coal only where the two overlap: over tool poses with the spindle near the part's top (over
    its faces and past its edges, straight and tilted), every clearance it gives is coal's
    within coal's tolerance, and every one it leaves is an overlap."""
    import pinocchio as pin

    from robomach_core.cell import TOOL_DOWN

    cell = Cell(CellConfig(workpiece=part))
    supervisor = cell_supervisor(cell)
    model = supervisor._model
    coal_only = model.copy()
    sk.obstacle_corner_counts(coal_only)[:] = 0  # every near pair is NaN: coal measures it
    lo, hi = cell.workpiece.mesh_in_base().bounds
    rng = np.random.default_rng(11)
    q, given, left = cell.robot.home_rad, 0, 0
    for _ in range(300):
        # The TCP 12-22 mm below the top: the spindle's end 0-10 mm over it (the slow zone is
        # 5 mm), over the part or past its edges by up to 40 mm.
        p = rng.uniform(
            [lo[0] - 0.04, lo[1] - 0.04, hi[2] - 0.022], [*(hi[:2] + 0.04), hi[2] - 0.012]
        )
        T = np.eye(4)
        T[:3, :3] = TOOL_DOWN @ pin.exp3(rng.normal(size=3) * 0.08)
        T[:3, 3] = p
        q = cell.robot.ik(T, q)
        m, T_tcp, _, _ = sk.margins_at(q, model)
        by_coal, _, _, n_near = sk.margins_at(q, coal_only)
        if n_near == 0:
            continue
        reference = sk.margins_at.py_func(q, model, sk._unpack.py_func(model))[0]
        np.testing.assert_allclose(m, reference, atol=1e-12, equal_nan=True)
        near = np.isnan(by_coal)
        supervisor._measure_near(by_coal, T_tcp, q)
        measured = near & ~np.isnan(m)
        np.testing.assert_allclose(m[measured], by_coal[measured], atol=2e-6)
        assert np.all(by_coal[near & np.isnan(m)] <= 0.0)  # left to coal: overlaps only
        given += int(measured.sum())
        left += int((near & np.isnan(m)).sum())
    assert given > 100, (given, left)
