"""The simulated machining cell: robot + joint compliance + tool + sensor + workpiece contact.

PROBLEM   Controllers must see what a real controller sees (motor-side joints, the F/T reading)
          while the physics behind it (joint compliance, penalty contact) stays hidden.
STRATEGY  Quasi-static arm: the motor-side joints track the commanded joints exactly within one
          4 ms period (a stiff position loop); the arm side bends under the contact wrench,
          q_arm = q_motor + Kq^-1 J^T W (chapter eq. 16), evaluated with the wrench of the
          previous period (deflections are micrometres and change slowly). The contact wrench
          comes from coal at the true (arm-side) TCP pose.
SOLUTION  ``Cell.step(state, q_motor_cmd, dt) -> CellState``, a function of its inputs plus the
          cell's seeded noise generator.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import NamedTuple

import numpy as np

from .. import _kernels
from ..errors import InvalidInputError
from ..part import Workpiece, builtin_workpiece
from .clock import CONTROL_PERIOD_S as CONTROL_PERIOD_S
from .contact import NO_CONTACT, ContactModel, ContactResult
from .joint_compliance import JointCompliance, true_joint_compliance
from .robot import Robot
from .sensor import ForceEstimator, ForceTorqueSensor, SensorParams
from .tool import Tool


@dataclass(frozen=True)
class CellConfig:
    """Everything that defines a cell.

    Attributes:
        robot: ``"ur10"``, ``"ur5"``, ``"ur3"`` or an ABB arm (``"irb4400"``, ``"irb6640"``).
        tool: The tool.
        workpiece: Built-in name (``"water_pump"``, ``"block"``), placed where the robot reaches
            it (``workpiece.default_T_base_wobj``), or a ``Workpiece``.
        sensor: Sensor noise and bias.
        seed: Seed of every random element (sensor bias and noise).
    """

    robot: str = "ur10"
    tool: Tool = field(default_factory=Tool)
    workpiece: str | Workpiece = "water_pump"
    sensor: SensorParams = field(default_factory=SensorParams)
    seed: int = 0


class CellState(NamedTuple):
    """The cell at one instant. Controllers may read ``q_motor``, ``T_base_tcp`` and ``ft_reading``.

    A named tuple rather than a frozen dataclass: one is made every 4 ms period, and a frozen
    dataclass takes three times as long to build.

    Attributes:
        time_s: Simulated time.
        q_motor: (6,) motor-side joints (what the resolvers read), rad.
        T_base_tcp: 4x4 TCP pose from the motor-side joints (the controller's belief).
        ft_reading: (6,) F/T sensor reading in the sensor frame.
        T_base_tcp_true: 4x4 true (arm-side) TCP pose, hidden from controllers.
        contact: Contact at the true pose, hidden from controllers.
        deflection_rad: (6,) arm-side minus motor-side joints, hidden from controllers.
    """

    time_s: float
    q_motor: np.ndarray
    T_base_tcp: np.ndarray
    ft_reading: np.ndarray
    T_base_tcp_true: np.ndarray
    contact: ContactResult
    deflection_rad: np.ndarray

    @property
    def in_contact(self) -> bool:
        return self.contact.in_contact


class Cell:
    """The simulator: immutable models plus reusable buffers (pinocchio Data, coal BVH cells)."""

    def __init__(self, config: CellConfig | None = None) -> None:
        self.config = config or CellConfig()
        self.robot = Robot(self.config.robot, self.config.tool.T_flange_tcp)
        self.tool = self.config.tool
        wp = self.config.workpiece
        self.workpiece: Workpiece = (
            builtin_workpiece(wp, robot=self.config.robot) if isinstance(wp, str) else wp
        )
        self.contact_model = ContactModel(self.tool, self.workpiece)
        self._compliance: JointCompliance = true_joint_compliance(self.robot.name)
        self._compliance_vec = self._compliance.compliance_rad_Nm
        self._rng = np.random.default_rng(self.config.seed)
        self.sensor = ForceTorqueSensor(self.tool, self.config.sensor, self._rng)
        self._R_tcp_flange = self.tool.T_flange_tcp[:3, :3].T.copy()
        self._tcp_rotated = not np.allclose(self._R_tcp_flange, np.eye(3))

    def force_estimator(self) -> ForceEstimator:
        """A controller-side compensator with the nominal tool data (bias not yet tared)."""
        return ForceEstimator.from_tool(self.tool)

    def initial_state(self, q_motor: np.ndarray | None = None) -> CellState:
        """The cell at rest at ``q_motor`` (default: the robot's home pose), t = 0."""
        q = (
            self.robot.home_rad.copy()
            if q_motor is None
            else np.asarray(q_motor, dtype=float).copy()
        )
        if q.shape != (6,) or not self.robot.within_limits(q):
            raise InvalidInputError("initial joints must be 6 values inside the joint limits")
        T = self.robot.fk(q).copy()
        contact = self.contact_model.evaluate(T, np.zeros(3), 0.0, CONTROL_PERIOD_S)
        if contact.in_contact:
            raise InvalidInputError("the initial pose puts the tool inside the workpiece")
        return CellState(
            0.0,
            q,
            T,
            self.sensor.measure(self.flange_rotation(T), contact.wrench),
            T.copy(),
            NO_CONTACT,
            np.zeros(6),
        )

    def step(
        self, state: CellState, q_motor_cmd: np.ndarray, dt: float = CONTROL_PERIOD_S
    ) -> CellState:
        """Advance one control period with the motor-side joints at ``q_motor_cmd``."""
        q = _kernels.clamp(q_motor_cmd, self.robot.lower_rad, self.robot.upper_rad)
        T_motor, J = self.robot.fk_and_jacobian(q)
        # Arm-side pose: motor pose displaced by J dq, dq = Kq^-1 J^T W (previous period's W).
        T_true, dq, velocity = _kernels.arm_side_pose(
            T_motor, J, state.contact.wrench, self._compliance_vec, state.T_base_tcp_true[:3, 3], dt
        )
        T_motor = T_motor.copy()
        contact = self.contact_model.evaluate(T_true, velocity, state.contact.depth_m, dt)
        reading = self.sensor.measure(self.flange_rotation(T_true), contact.wrench)
        return CellState(state.time_s + dt, q, T_motor, reading, T_true, contact, dq)

    def flange_rotation(self, T_base_tcp: np.ndarray) -> np.ndarray:
        """Sensor orientation for a TCP orientation (the controller's frame bookkeeping)."""
        if self._tcp_rotated:
            return T_base_tcp[:3, :3] @ self._R_tcp_flange
        return T_base_tcp[:3, :3]
