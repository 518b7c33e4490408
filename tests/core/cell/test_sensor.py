from __future__ import annotations

import numpy as np

from robomach_core.cell import ForceEstimator, Tool
from robomach_core.cell.sensor import ForceTorqueSensor, SensorParams
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
