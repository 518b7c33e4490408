"""Identification of what the wrist F/T sensor carries, for its gravity compensation (5.3).

PROBLEM   The sensor at the flange reads the contact wrench plus the weight of spindle and tool
          plus its own bias, in the sensor frame (the model: ``sensor``), and the robot is not
          always wrist-down; the compensation needs the mass, centre of mass and bias.
STRATEGY  Read the sensor at 15 distinct configurations without contact. With g_s = R^T g the
          gravity vector in sensor axes, the readings are linear in the unknowns:
          f = m g_s + f_b and t = c x (m g_s) + t_b = -[g_s]x (m c) + t_b,
          so (m, f_b) and (m c, t_b) follow by least squares; c = (m c) / m.
SOLUTION  ``identify_tool_gravity`` gives a ``sensor.ToolGravity``; ``sensor.compensate_gravity``
          removes it from any reading.

The sensor frame is the flange frame (``Robot.flange_pose``).
"""

from __future__ import annotations

import numpy as np
import pinocchio as pin

from ..cell import GRAVITY_M_S2, HOME_JOINTS_RAD, Robot, ToolGravity, gravity_reading
from .errors import IdentificationError

CALIBRATION_CONFIGURATIONS = 15
# Joint spread of the calibration configurations around home [rad]: wide at the wrist, where
# the sensor orientation comes from, narrow at the arm.
CALIBRATION_SPREAD_RAD = (0.4, 0.3, 0.3, 1.5, 1.5, np.pi)


def calibration_joints(
    count: int = CALIBRATION_CONFIGURATIONS, *, seed: int = 0, center_rad: np.ndarray | None = None
) -> np.ndarray:
    """``count`` configurations with well-spread sensor orientations. Shape (count, 6) [rad]."""
    rng = np.random.default_rng(seed)
    center = HOME_JOINTS_RAD if center_rad is None else np.asarray(center_rad, dtype=float)
    spread = np.asarray(CALIBRATION_SPREAD_RAD)
    return center + rng.uniform(-1.0, 1.0, (count, 6)) * spread


def simulate_sensor_readings(
    robot: Robot,
    joints_rad: np.ndarray,
    tool: ToolGravity,
    *,
    force_noise_N: float = 0.3,
    torque_noise_Nm: float = 0.02,
    seed: int = 0,
) -> tuple[np.ndarray, np.ndarray]:
    """Sensor orientations and readings without contact at each configuration.

    Returns:
        (R_base_sensor (n, 3, 3), wrench_sensor (n, 6)).
    """
    rng = np.random.default_rng(seed)
    rotations, readings = [], []
    for q in np.asarray(joints_rad, dtype=float):
        R = robot.flange_pose(q)[:3, :3].copy()
        noise = np.concatenate(
            [rng.normal(0.0, force_noise_N, 3), rng.normal(0.0, torque_noise_Nm, 3)]
        )
        rotations.append(R)
        readings.append(gravity_reading(R, tool) + noise)
    return np.array(rotations), np.array(readings)


def identify_tool_gravity(R_base_sensor: np.ndarray, wrench_sensor: np.ndarray) -> ToolGravity:
    """Mass, centre of mass and sensor bias by least squares over the readings.

    Raises:
        IdentificationError: fewer than three distinct orientations, or no measurable mass.
    """
    Rs = np.asarray(R_base_sensor, dtype=float)
    W = np.asarray(wrench_sensor, dtype=float)
    if len(Rs) < 3:
        raise IdentificationError("gravity compensation needs at least three configurations")
    g_s = np.einsum("nji,j->ni", Rs, GRAVITY_M_S2)
    eye = np.broadcast_to(np.eye(3), (len(Rs), 3, 3))
    A_f = np.concatenate([g_s[:, :, None], eye], axis=2).reshape(-1, 4)
    A_t = np.concatenate([-np.array([pin.skew(g) for g in g_s]), eye], axis=2).reshape(-1, 6)
    if np.linalg.matrix_rank(A_f) < 4 or np.linalg.matrix_rank(A_t) < 6:
        raise IdentificationError("the configurations do not vary the sensor orientation enough")
    x_f = np.linalg.lstsq(A_f, W[:, :3].reshape(-1), rcond=None)[0]
    x_t = np.linalg.lstsq(A_t, W[:, 3:].reshape(-1), rcond=None)[0]
    mass = float(x_f[0])
    if mass <= 1e-6:
        raise IdentificationError(f"identified tool mass {mass:.3g} kg is not positive")
    com = x_t[:3] / mass
    return ToolGravity(
        mass_kg=mass,
        com_m=(float(com[0]), float(com[1]), float(com[2])),
        force_bias_N=(float(x_f[1]), float(x_f[2]), float(x_f[3])),
        torque_bias_Nm=(float(x_t[3]), float(x_t[4]), float(x_t[5])),
    )
