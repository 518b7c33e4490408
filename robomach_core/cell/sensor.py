"""The 6-axis force/torque sensor at the flange: one model of what it reads and of how the
controller turns a reading back into the contact wrench (chapter section 5.3).

The sensor measures, in its own (flange) frame, the contact wrench plus the weight of what it
carries (spindle and tool) plus its bias plus white noise:

    f_s = R^T (F_c + m g) + f_b,   tau_s = R^T tau_c + r_tcp x R^T F_c + r_com x R^T m g + t_b

(``contact_reading`` + ``gravity_reading``). The controller removes the weight and the bias
with its tool data (``compensate_gravity``) and moves the wrench to the TCP in base axes
(``wrench_at_tcp_in_base``). The simulated cell (``ForceTorqueSensor``), the controller
(``ForceEstimator``), path learning and the stiffness studies all use this model; the 4 ms
loops reach it through its compiled copies (``_kernels.sensor_reading``,
``_kernels.contact_wrench_tcp_base``), which tests hold equal to these functions.

A sensor wrench is (6,) [force (N); torque about the sensor origin (N*m)] in sensor axes.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .. import _kernels
from .tool import Tool

STANDARD_GRAVITY_M_S2 = 9.81
GRAVITY_M_S2 = np.array([0.0, 0.0, -STANDARD_GRAVITY_M_S2])  # in the robot's base frame
_NOISE_BLOCK = 4096


@dataclass(frozen=True)
class ToolGravity:
    """What the sensor carries and its offsets.

    Attributes:
        mass_kg: Mass below the sensor (spindle + tool).
        com_m: (3,) centre of mass in the sensor frame.
        force_bias_N: (3,) sensor force offset.
        torque_bias_Nm: (3,) sensor torque offset.
    """

    mass_kg: float
    com_m: tuple[float, float, float]
    force_bias_N: tuple[float, float, float] = (0.0, 0.0, 0.0)
    torque_bias_Nm: tuple[float, float, float] = (0.0, 0.0, 0.0)

    @classmethod
    def from_tool(
        cls,
        tool: Tool,
        *,
        force_bias_N: tuple[float, float, float] = (0.0, 0.0, 0.0),
        torque_bias_Nm: tuple[float, float, float] = (0.0, 0.0, 0.0),
    ) -> ToolGravity:
        """The true load of ``tool`` on a sensor with the given bias."""
        x, y, z = (float(v) for v in tool.com_m)
        return cls(tool.mass_kg, (x, y, z), force_bias_N, torque_bias_Nm)

    @property
    def bias(self) -> np.ndarray:
        """(6,) the force and torque offsets."""
        return np.concatenate([self.force_bias_N, self.torque_bias_Nm]).astype(float)


def gravity_reading(R_base_sensor: np.ndarray, tool: ToolGravity) -> np.ndarray:
    """(6,) what the sensor reads with no contact: tool weight plus bias, sensor axes."""
    f = tool.mass_kg * (np.asarray(R_base_sensor).T @ GRAVITY_M_S2)
    t = np.cross(np.asarray(tool.com_m, dtype=float), f)
    return np.concatenate([f, t]) + tool.bias


def contact_reading(
    R_base_sensor: np.ndarray, p_sensor_tcp_m: np.ndarray, wrench_base_at_tcp: np.ndarray
) -> np.ndarray:
    """(6,) a contact wrench at the TCP (base axes) as the sensor sees it (sensor axes/origin)."""
    R = np.asarray(R_base_sensor)
    f = R.T @ wrench_base_at_tcp[:3]
    t = R.T @ wrench_base_at_tcp[3:] + np.cross(np.asarray(p_sensor_tcp_m, dtype=float), f)
    return np.concatenate([f, t])


def compensate_gravity(
    wrench_sensor: np.ndarray, R_base_sensor: np.ndarray, tool: ToolGravity
) -> np.ndarray:
    """(6,) contact wrench in sensor axes: the reading minus tool weight and bias."""
    return np.asarray(wrench_sensor, dtype=float) - gravity_reading(R_base_sensor, tool)


def wrench_in_tool_frame(wrench_sensor: np.ndarray, T_sensor_tool: np.ndarray) -> np.ndarray:
    """(6,) a sensor-frame wrench expressed in the tool frame, torque about the TCP."""
    R = T_sensor_tool[:3, :3]
    p = T_sensor_tool[:3, 3]
    f = wrench_sensor[:3]
    return np.concatenate([R.T @ f, R.T @ (wrench_sensor[3:] - np.cross(p, f))])


def wrench_at_tcp_in_base(
    wrench_sensor: np.ndarray, R_base_sensor: np.ndarray, p_sensor_tcp_m: np.ndarray
) -> np.ndarray:
    """(6,) a sensor-frame wrench moved to the TCP in base axes (the stiffness model's input)."""
    f = wrench_sensor[:3]
    t = wrench_sensor[3:] - np.cross(np.asarray(p_sensor_tcp_m, dtype=float), f)
    R = np.asarray(R_base_sensor)
    return np.concatenate([R @ f, R @ t])


@dataclass(frozen=True)
class SensorParams:
    """Noise and bias of the simulated F/T sensor.

    Attributes:
        noise_force_N: Standard deviation of the force noise per axis.
        noise_torque_Nm: Standard deviation of the torque noise per axis.
        bias_force_N: Bias scale; the actual (3,) bias is drawn from the cell's seed.
        bias_torque_Nm: Torque bias scale.
    """

    noise_force_N: float = 0.25
    noise_torque_Nm: float = 0.01
    bias_force_N: float = 2.0
    bias_torque_Nm: float = 0.1


class ForceTorqueSensor:
    """Simulated sensor: deterministic given its generator."""

    def __init__(self, tool: Tool, params: SensorParams, rng: np.random.Generator) -> None:
        self.tool = tool
        self.params = params
        self._rng = rng
        self.bias = np.concatenate(
            [
                rng.uniform(-1, 1, 3) * params.bias_force_N,
                rng.uniform(-1, 1, 3) * params.bias_torque_Nm,
            ]
        )
        self._scale = np.array([params.noise_force_N] * 3 + [params.noise_torque_Nm] * 3)
        self._noise = np.empty((0, 6))
        self._next = 0
        self._com = np.asarray(tool.com_m, dtype=float)
        # weight m g, centre of mass, TCP, bias: the compiled reading's ``load``.
        self._load = np.concatenate(
            [tool.mass_kg * GRAVITY_M_S2, self._com, tool.tcp_offset_m, self.bias]
        ).astype(float)

    @property
    def load(self) -> ToolGravity:
        """What it carries and its true bias."""
        return ToolGravity(
            self.tool.mass_kg, tuple(self._com), tuple(self.bias[:3]), tuple(self.bias[3:])
        )

    def measure(self, R_base_flange: np.ndarray, contact_wrench_tcp_base: np.ndarray) -> np.ndarray:
        """(6,) reading [F (N), tau (N*m)] in the sensor frame: ``contact_reading`` +
        ``gravity_reading`` (of ``load``) + noise.

        Args:
            R_base_flange: 3x3 orientation of the sensor (arm side, the true one).
            contact_wrench_tcp_base: (6,) contact wrench at the TCP, base-aligned axes.
        """
        if self._next >= len(self._noise):  # white noise, drawn a block at a time
            self._noise = self._rng.standard_normal((_NOISE_BLOCK, 6)) * self._scale
            self._next = 0
        self._next += 1
        return _kernels.sensor_reading(
            R_base_flange, contact_wrench_tcp_base, self._load, self._noise, self._next - 1
        )


@dataclass
class ForceEstimator:
    """The controller's gravity and bias compensation with its tool data (section 5.3).

    Attributes:
        mass_kg: Tool mass the controller believes.
        com_m: (3,) centre of mass in the sensor frame.
        tcp_m: (3,) TCP in the sensor frame.
        bias: (6,) sensor bias estimated at the last tare.
    """

    mass_kg: float
    com_m: np.ndarray
    tcp_m: np.ndarray
    bias: np.ndarray

    @classmethod
    def from_tool(cls, tool: Tool) -> ForceEstimator:
        return cls(
            tool.mass_kg,
            np.asarray(tool.com_m, dtype=float),
            np.asarray(tool.tcp_offset_m, dtype=float),
            np.zeros(6),
        )

    @property
    def load(self) -> ToolGravity:
        """The load and bias the controller believes."""
        b = self.bias
        return ToolGravity(self.mass_kg, tuple(self.com_m), tuple(b[:3]), tuple(b[3:]))

    def tare(self, readings: np.ndarray, Rs_base_flange: np.ndarray) -> None:
        """Estimate the bias from readings (n, 6) taken out of contact at orientations (n, 3, 3)
        (the mass and centre of mass known: ``stiffness.gravity.identify_tool_gravity``
        identifies them too)."""
        weight_only = ToolGravity(self.mass_kg, tuple(self.com_m))
        predicted = np.array([gravity_reading(R, weight_only) for R in Rs_base_flange])
        self.bias = np.mean(np.asarray(readings) - predicted, axis=0)

    def tool_data(self) -> np.ndarray:
        """(15,) weight m g (3), centre of mass (3), TCP (3), bias (6): the compiled
        compensation's arguments (``_kernels.contact_wrench_tcp_base``)."""
        return np.concatenate([self.mass_kg * GRAVITY_M_S2, self.com_m, self.tcp_m, self.bias])

    def contact_wrench_tcp_base(self, reading: np.ndarray, R_base_flange: np.ndarray) -> np.ndarray:
        """(6,) compensated contact wrench at the TCP in base-aligned axes:
        ``wrench_at_tcp_in_base(compensate_gravity(reading, R, load), R, tcp)``."""
        return _kernels.contact_wrench_tcp_base(
            reading,
            np.ascontiguousarray(R_base_flange),
            self.mass_kg * GRAVITY_M_S2,
            self.com_m,
            self.tcp_m,
            self.bias,
        )
