"""The 6-axis force/torque sensor at the flange, and the controller's view of its readings.

The sensor measures, in its own (flange) frame, the contact wrench plus the weight of the tool
plus a bias plus white noise. The controller removes the tool's weight with its tool data and the
bias it estimated at a tare (chapter section 5.3), and moves the wrench to the TCP.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from . import _kernels
from .tool import Tool
from .transforms import cross3

GRAVITY_M_S2 = np.array([0.0, 0.0, -9.81])
_NOISE_BLOCK = 4096


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
        self._tcp = np.asarray(tool.tcp_offset_m, dtype=float)
        self._weight = tool.mass_kg * GRAVITY_M_S2

    def _draw_noise(self) -> np.ndarray:
        if self._next >= len(self._noise):
            self._noise = self._rng.standard_normal((_NOISE_BLOCK, 6)) * self._scale
            self._next = 0
        row = self._noise[self._next]
        self._next += 1
        return row

    def measure(self, R_base_flange: np.ndarray, contact_wrench_tcp_base: np.ndarray) -> np.ndarray:
        """(6,) reading [F (N), tau (N*m)] in the sensor frame.

        Args:
            R_base_flange: 3x3 orientation of the sensor (arm side, the true one).
            contact_wrench_tcp_base: (6,) contact wrench at the TCP, base-aligned axes.
        """
        return _kernels.sensor_reading(
            R_base_flange,
            contact_wrench_tcp_base,
            self._weight,
            self._com,
            self._tcp,
            self.bias,
            self._draw_noise(),
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

    def gravity_reading(self, R_base_flange: np.ndarray) -> np.ndarray:
        """(6,) reading the tool's weight alone would give at orientation ``R_base_flange``."""
        f = R_base_flange.T @ (self.mass_kg * GRAVITY_M_S2)
        return np.concatenate([f, cross3(self.com_m, f)])

    def tare(self, readings: np.ndarray, Rs_base_flange: np.ndarray) -> None:
        """Estimate the bias from readings (n, 6) taken out of contact at orientations (n, 3, 3)."""
        predicted = np.array([self.gravity_reading(R) for R in Rs_base_flange])
        self.bias = np.mean(np.asarray(readings) - predicted, axis=0)

    def contact_wrench_tcp_base(self, reading: np.ndarray, R_base_flange: np.ndarray) -> np.ndarray:
        """(6,) compensated contact wrench at the TCP in base-aligned axes."""
        return _kernels.contact_wrench_tcp_base(
            reading,
            np.ascontiguousarray(R_base_flange),
            self.mass_kg * GRAVITY_M_S2,
            self.com_m,
            self.tcp_m,
            self.bias,
        )
