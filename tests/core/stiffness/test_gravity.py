"""Gravity compensation of the F/T sensor (chapter 5.3)."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from robomach_core.cell import (
    Tool,
    ToolGravity,
    compensate_gravity,
    contact_reading,
    gravity_reading,
    wrench_at_tcp_in_base,
    wrench_in_tool_frame,
)
from robomach_core.stiffness.errors import IdentificationError
from robomach_core.stiffness.gravity import (
    calibration_joints,
    identify_tool_gravity,
    simulate_sensor_readings,
)

TRUE_TOOL = ToolGravity(3.2, (0.004, -0.002, 0.08), (1.5, -0.8, 2.0), (0.05, 0.1, -0.02))


@settings(max_examples=20, deadline=None)
@given(
    mass=st.floats(0.5, 20.0),
    com=st.lists(st.floats(-0.1, 0.2), min_size=3, max_size=3),
    bias=st.lists(st.floats(-5, 5), min_size=6, max_size=6),
    seed=st.integers(0, 1000),
)
def test_exact_on_noise_free_data(robot, mass, com, bias, seed):
    tool = ToolGravity(mass, tuple(com), tuple(bias[:3]), tuple(bias[3:]))
    R, W = simulate_sensor_readings(
        robot, calibration_joints(15, seed=seed), tool, force_noise_N=0, torque_noise_Nm=0
    )
    est = identify_tool_gravity(R, W)
    assert est.mass_kg == pytest.approx(mass, rel=1e-9)
    np.testing.assert_allclose(est.com_m, com, atol=1e-9)
    np.testing.assert_allclose(est.force_bias_N, bias[:3], atol=1e-9)
    np.testing.assert_allclose(est.torque_bias_Nm, bias[3:], atol=1e-9)


def test_residual_at_random_poses_is_at_noise_level(robot):
    R, W = simulate_sensor_readings(robot, calibration_joints(15, seed=0), TRUE_TOOL, seed=1)
    est = identify_tool_gravity(R, W)
    R2, _ = simulate_sensor_readings(robot, calibration_joints(40, seed=9), TRUE_TOOL, seed=2)
    residual = [
        np.linalg.norm(compensate_gravity(gravity_reading(r, TRUE_TOOL), r, est)[:3]) for r in R2
    ]
    assert max(residual) < 0.5  # N, from 0.3 N reading noise on 15 configurations


def test_compensation_recovers_the_contact_wrench(robot, work_joints):
    R = robot.flange_pose(work_joints)[:3, :3]
    p = robot.T_flange_tcp[:3, 3]
    contact = np.array([-300.0, 300.0, 50.0, 1.0, -2.0, 0.5])
    reading = gravity_reading(R, TRUE_TOOL) + contact_reading(R, p, contact)
    back = wrench_at_tcp_in_base(compensate_gravity(reading, R, TRUE_TOOL), R, p)
    np.testing.assert_allclose(back, contact, atol=1e-9)


def test_tool_frame_moves_torque_to_the_tcp():
    T_sensor_tool = Tool().T_flange_tcp
    force_on_tcp = np.array([0.0, 10.0, 0.0])
    sensor = np.concatenate([force_on_tcp, np.cross(T_sensor_tool[:3, 3], force_on_tcp)])
    np.testing.assert_allclose(
        wrench_in_tool_frame(sensor, T_sensor_tool), [0, 10, 0, 0, 0, 0], atol=1e-12
    )


def test_one_orientation_is_refused(robot, work_joints):
    R, W = simulate_sensor_readings(robot, np.tile(work_joints, (5, 1)), TRUE_TOOL)
    with pytest.raises(IdentificationError):
        identify_tool_gravity(R, W)
