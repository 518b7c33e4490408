"""The machining loop's private scalar copies equal the public models they stand in for, and
the online compensation's per-station shift equals ``online_compensation_step``."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from robomach_core.cell import contact_reading, gravity_reading
from robomach_core.cmrr.controllers.rls import RlsState, rls_update
from robomach_core.cmrr.feed_dynamics import FeedDynamics
from robomach_core.cmrr.process import ForceSensorModel
from robomach_core.machining import identify_stiffness, wall_normals_from_path
from robomach_core.machining.path import path_tangents
from robomach_core.machining.run import (
    CONTROL_PERIOD_S,
    _FeedState,
    _FilterState,
    force_directions,
    normal_compliance,
)
from robomach_core.stiffness import (
    OnlineCompensationParams,
    OnlineCompensationState,
    ToolGravity,
    online_compensation_step,
)

signals = st.lists(st.floats(-0.05, 0.05), min_size=1, max_size=200)


@given(signals)
@settings(max_examples=30, deadline=None)
def test_scalar_feed_model_equals_the_discretized_eq_1(commands):
    model = FeedDynamics().discretize(CONTROL_PERIOD_S)
    x = model.initial_state()
    fast = _FeedState.start(model)
    for u in commands:
        assert fast.feed() == pytest.approx(model.feed(x), abs=1e-15)
        x = model.step(x, u)
        fast.step(u)
        assert fast.position == pytest.approx(x[-1], abs=1e-15)


@given(st.lists(st.floats(-500.0, 500.0), min_size=1, max_size=200))
@settings(max_examples=30, deadline=None)
def test_scalar_filter_equals_the_sensor_low_pass(values):
    lowpass = ForceSensorModel().make_filter(CONTROL_PERIOD_S)
    state = lowpass.initial_state()
    fast = _FilterState.start(lowpass)
    for v in values:
        state, y = lowpass.step(state, v)
        assert fast.step(v) == pytest.approx(y, rel=1e-12, abs=1e-9)


def _rls_numpy(state, x, y, lam, caps):
    """Eq. (16) in 2x2 numpy: the generic path of rls_update, written out."""
    p = state.covariance
    px = p @ x
    gain = px / (lam + float(x @ px))
    theta = state.theta + gain * (y - float(state.theta @ x))
    p_new = (p - np.outer(gain, px)) / lam
    p_new = 0.5 * (p_new + p_new.T)
    diag = np.diagonal(p_new)
    if np.any(diag > caps):
        scale = np.sqrt(np.minimum(1.0, caps / np.maximum(diag, 1e-300)))
        p_new = p_new * np.outer(scale, scale)
    return theta, p_new


@given(
    st.lists(st.tuples(st.floats(-3.0, 1.0), st.floats(0.0, 7.0)), min_size=1, max_size=60),
    st.floats(0.9, 1.0),
)
@settings(max_examples=40, deadline=None)
def test_two_parameter_rls_equals_the_matrix_form(samples, lam):
    caps = np.array([1.0, 0.002])
    state = RlsState(np.array([4.0, 0.5]), np.diag([1.0, 0.002]))
    ref_theta, ref_p = state.theta, state.covariance
    for z, y in samples:
        x = np.array([1.0, z])
        state = rls_update(state, x, y, lam, caps)
        ref_theta, ref_p = _rls_numpy(RlsState(ref_theta, ref_p), x, y, lam, caps)
        assert state.theta == pytest.approx(ref_theta, rel=1e-9, abs=1e-12)
        assert state.covariance == pytest.approx(ref_p, rel=1e-9, abs=1e-15)


def test_online_shift_per_station_equals_online_compensation_step(robot, wall_program):
    """The run shifts the tool by -n^T C_hat u F_f; the chapter's step moves the joints by
    -Kq_hat^-1 J^T W_f. At 150 N their normal shifts agree to a fraction of a micrometre."""
    model = identify_stiffness(robot.name, seed=0).model
    P = wall_program.position_m
    N = wall_normals_from_path(P)
    U = force_directions(N, path_tangents(P), 0.5)
    tool = ToolGravity(2.5, (0.0, 0.0, 0.07))
    params = OnlineCompensationParams(model, tool)
    c_hat = normal_compliance(robot, wall_program.joints_rad, N, U, model)
    force = 150.0
    for i in (0, len(P) // 3, 2 * len(P) // 3):
        q = wall_program.joints_rad[i]
        W = np.concatenate([force * U[i], np.zeros(3)])
        R = robot.flange_pose(q)[:3, :3].copy()
        reading = gravity_reading(R, tool) + contact_reading(R, robot.T_flange_tcp[:3, 3], W)
        state = OnlineCompensationState()
        for _ in range(200):  # let the 30 Hz filter settle
            state, q_ref = online_compensation_step(
                robot, state, q, reading, params, CONTROL_PERIOD_S
            )
        p_nom = robot.fk(q)[:3, 3].copy()
        shift = float(N[i] @ (robot.fk(q_ref)[:3, 3] - p_nom))
        assert shift == pytest.approx(-c_hat[i] * force, abs=2e-7)
        assert abs(shift) > 20e-6  # a real correction, tens of micrometres
