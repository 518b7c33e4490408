from __future__ import annotations

import numpy as np

from robomach_core.sensor import ForceEstimator, ForceTorqueSensor, SensorParams
from robomach_core.tool import Tool
from robomach_core.transforms import rotation_about


def test_compensation_recovers_the_contact_wrench_without_noise():
    tool = Tool()
    sensor = ForceTorqueSensor(
        tool, SensorParams(noise_force_N=0.0, noise_torque_Nm=0.0), np.random.default_rng(3)
    )
    est = ForceEstimator.from_tool(tool)
    rotations = [rotation_about([1, 2, 3], a) for a in np.linspace(0, 2, 5)]
    est.tare(np.array([sensor.measure(R, np.zeros(6)) for R in rotations]), np.array(rotations))
    np.testing.assert_allclose(est.bias, sensor.bias, atol=1e-12)
    R = rotation_about([0.3, -1, 0.2], 2.4)
    wrench = np.array([3.0, -7.0, 10.0, 0.02, -0.01, 0.05])
    np.testing.assert_allclose(
        est.contact_wrench_tcp_base(sensor.measure(R, wrench), R), wrench, atol=1e-10
    )


def test_reading_includes_the_tools_weight():
    tool = Tool(mass_kg=2.0)
    sensor = ForceTorqueSensor(
        tool,
        SensorParams(noise_force_N=0.0, noise_torque_Nm=0.0, bias_force_N=0.0, bias_torque_Nm=0.0),
        np.random.default_rng(0),
    )
    reading = sensor.measure(np.diag([1.0, -1.0, -1.0]), np.zeros(6))  # tool pointing down
    np.testing.assert_allclose(reading[:3], [0.0, 0.0, 2.0 * 9.81])


def test_compiled_arm_side_pose_is_eq_16():
    """The cell's kernel moves the TCP by J dq with dq = Kq^-1 J^T W (JointCompliance)."""
    from robomach_core import _kernels
    from robomach_core.joint_compliance import true_joint_compliance
    from robomach_core.robot import HOME_JOINTS_RAD, Robot

    robot = Robot("ur10", Tool().T_flange_tcp)
    compliance = true_joint_compliance("ur10")
    T, J = robot.fk_and_jacobian(HOME_JOINTS_RAD + 0.2)
    wrench = np.array([300.0, -300.0, 50.0, 2.0, -1.0, 0.5])
    T_arm, dq, _ = _kernels.arm_side_pose(T, J, wrench, compliance.compliance_rad_Nm, T[:3, 3], 1.0)
    np.testing.assert_allclose(dq, compliance.joint_deflection(J, wrench), rtol=1e-12)
    np.testing.assert_allclose(T_arm[:3, 3], T[:3, 3] + (J @ dq)[:3], atol=1e-15)
    # To first order the arm side is the motor side turned by the deflection.
    np.testing.assert_allclose(T_arm, robot.fk(HOME_JOINTS_RAD + 0.2 + dq), atol=1e-6)
