"""Online and offline deformation compensation."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from robomach_core.cell import ToolGravity, contact_reading, gravity_reading
from robomach_core.stiffness.compensation import (
    OnlineCompensationParams,
    OnlineCompensationState,
    compensate_targets,
    compensate_targets_and_joints,
    online_compensation_step,
)
from robomach_core.stiffness.model import loaded_equilibrium
from robomach_core.transforms import pose_error

from .conftest import CHAPTER_WRENCH

TOOL = ToolGravity(2.5, (0.0, 0.0, 0.07), (1.0, -2.0, 0.5), (0.02, 0.01, 0.0))


@settings(max_examples=15, deadline=None)
@given(dq=st.lists(st.floats(-0.2, 0.2), min_size=6, max_size=6))
def test_zero_load_changes_no_target(robot, truth, work_joints, dq):
    q = work_joints + np.array(dq)
    T = robot.fk(q).copy()
    for mode in ("linear", "nonlinear"):
        out = compensate_targets(robot, T[None], q[None], np.zeros((1, 6)), truth, mode)
        np.testing.assert_array_equal(out[0], T)


@pytest.mark.parametrize("mode", ["linear", "nonlinear"])
def test_compensated_targets_land_on_the_program(robot, truth, work_joints, mode):
    T0 = robot.fk(work_joints).copy()
    W = CHAPTER_WRENCH
    _, q = compensate_targets_and_joints(robot, T0[None], work_joints[None], W[None], truth, mode)
    landed = loaded_equilibrium(robot, q[0], W, truth).T_base_tcp
    tolerance = 1e-6 if mode == "linear" else 1e-9  # linear misses the second-order term
    assert np.linalg.norm(pose_error(landed, T0)[:3]) < tolerance


def test_nonlinear_beats_linear_under_heavy_load(robot, truth, work_joints):
    T0 = robot.fk(work_joints).copy()
    W = CHAPTER_WRENCH * 10

    def landing_error(mode: str) -> float:
        _, q = compensate_targets_and_joints(
            robot, T0[None], work_joints[None], W[None], truth, mode
        )
        landed = loaded_equilibrium(robot, q[0], W, truth).T_base_tcp
        return float(np.linalg.norm(pose_error(landed, T0)[:3]))

    assert landing_error("nonlinear") < 1e-3 * landing_error("linear")


def test_online_step_zero_contact_keeps_nominal_reference(robot, truth, work_joints):
    params = OnlineCompensationParams(truth, TOOL)
    R = robot.flange_pose(work_joints)[:3, :3]
    state = OnlineCompensationState()
    for _ in range(5):
        state, q_ref = online_compensation_step(
            robot, state, work_joints, gravity_reading(R, TOOL), params, 0.004
        )
    np.testing.assert_allclose(q_ref, work_joints, atol=1e-15)


def test_online_step_converges_to_the_static_correction(robot, truth, work_joints):
    params = OnlineCompensationParams(truth, TOOL)
    R = robot.flange_pose(work_joints)[:3, :3].copy()
    p = robot.T_flange_tcp[:3, 3]
    reading = gravity_reading(R, TOOL) + contact_reading(R, p, CHAPTER_WRENCH)
    state = OnlineCompensationState()
    for _ in range(200):
        state, q_ref = online_compensation_step(robot, state, work_joints, reading, params, 0.004)
    _, J = robot.fk_and_jacobian(work_joints)
    expected = work_joints - truth.compliance_rad_Nm * (J.T @ CHAPTER_WRENCH)
    np.testing.assert_allclose(q_ref, expected, atol=1e-12)
