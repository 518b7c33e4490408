"""Deformation compensation: online joint-reference update and offline target correction.

PROBLEM   Under process forces the TCP lands C W away from where the controller put it; the
          controller only sees the motor side, so it must move the reference the other way.
STRATEGY  Online (chapter fig. 15): each control step, filter the sensor reading, remove the
          tool weight and bias, move it to the TCP, and shift the joint reference by
          -Kq^-1 J^T W (the identified model). Offline: correct the program targets for the
          predicted process wrench, linearly (t_F = t_0 - C(q_0) W) or by the compliance
          paper's iteration eq. (32), t_F' = t_F + mu (t_0 - f^-1(F | t_F)), where
          f^-1(F | t_F) is the non-linear loaded pose when commanding t_F.
SOLUTION  ``online_compensation_step`` (state, input, params, dt -> state, reference) and
          ``compensate_targets`` (poses in, corrected poses out); both are exact no-ops at
          zero load.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from ..cell import JointCompliance, Robot, ToolGravity, compensate_gravity, wrench_at_tcp_in_base
from ..transforms import pose_error
from .errors import ConvergenceError
from .model import apply_twist, loaded_equilibrium
from .modes import DEFAULT_OFFLINE_MODEL, OfflineModel

# Eq. (32): relaxation mu in (0, 1] and stopping tolerances of the target iteration.
NONLINEAR_RELAXATION = 1.0
NONLINEAR_TOLERANCE_M = 1e-10
NONLINEAR_TOLERANCE_RAD = 1e-10
NONLINEAR_MAX_ITERATIONS = 30
# Cut-off of the first-order low-pass on the measured wrench (chapter: "after the force sensor
# noise is filtrated") [Hz].
FORCE_FILTER_CUTOFF_HZ = 30.0


def compensate_targets_and_joints(
    robot: Robot,
    Ts_base_target: np.ndarray,
    joints: np.ndarray,
    wrenches: np.ndarray,
    model: JointCompliance,
    mode: OfflineModel = DEFAULT_OFFLINE_MODEL,
    *,
    relaxation: float = NONLINEAR_RELAXATION,
) -> tuple[np.ndarray, np.ndarray]:
    """Corrected targets and the joints that reach them; see ``compensate_targets``."""
    Ts = np.asarray(Ts_base_target, dtype=float).reshape(-1, 4, 4)
    qs = np.asarray(joints, dtype=float).reshape(-1, 6)
    Ws = np.asarray(wrenches, dtype=float).reshape(-1, 6)
    if not (len(Ts) == len(qs) == len(Ws)):
        raise ValueError("targets, joints and wrenches must have the same length")
    c = model.compliance_rad_Nm
    out_T = np.empty_like(Ts)
    out_q = np.empty_like(qs)
    for i, (T, q0, W) in enumerate(zip(Ts, qs, Ws, strict=True)):
        if not W.any():  # no load, no correction (exactly)
            out_T[i], out_q[i] = T, q0
            continue
        T0, J0 = robot.fk_and_jacobian(q0)
        T0 = T0.copy()
        if mode == "linear":
            theta = c * (J0.T @ W)
            twist = -(J0 @ theta)
            out_T[i] = apply_twist(T, twist)
            # The controller reaches a corrected robtarget by inverse kinematics of the pose.
            out_q[i] = robot.ik(
                apply_twist(T0, twist),
                q0 - theta,
                tolerance_m=NONLINEAR_TOLERANCE_M,
                tolerance_rad=NONLINEAR_TOLERANCE_RAD,
            )
            continue
        # Eq. (32) with the pose update carried to the joints through J, so the commanded pose
        # is always exactly FK(q_F); the desired pose is FK(q_0), which the nominal joints reach.
        q = q0.copy()
        for _ in range(NONLINEAR_MAX_ITERATIONS):
            loaded = loaded_equilibrium(robot, q, W, model)
            e = pose_error(loaded.T_base_tcp, T0)
            if np.linalg.norm(e[:3]) <= NONLINEAR_TOLERANCE_M and (
                np.linalg.norm(e[3:]) <= NONLINEAR_TOLERANCE_RAD
            ):
                break
            _, J = robot.fk_and_jacobian(q)
            q = q + relaxation * np.linalg.solve(J, e)
        else:
            raise ConvergenceError(
                f"target {i} did not converge in {NONLINEAR_MAX_ITERATIONS} iterations of eq. (32)"
            )
        out_T[i] = apply_twist(T, pose_error(T0, robot.fk(q)))
        out_q[i] = q
    return out_T, out_q


def compensate_targets(
    robot: Robot,
    Ts_base_target: np.ndarray,
    joints: np.ndarray,
    wrenches: np.ndarray,
    model: JointCompliance,
    mode: OfflineModel = DEFAULT_OFFLINE_MODEL,
) -> np.ndarray:
    """Program targets moved so that, under the predicted wrenches, the TCP lands on them.

    Args:
        robot: The arm with the machining tool's TCP.
        Ts_base_target: (n, 4, 4) programmed TCP poses.
        joints: (n, 6) nominal joint solutions of the targets [rad].
        wrenches: (n, 6) predicted process wrenches on the arm at the TCP, base axes [N, N*m].
        model: Identified joint stiffness.
        mode: ``"linear"`` (t_0 - C W) or ``"nonlinear"`` (eq. 32).

    Returns:
        (n, 4, 4) corrected poses; equal to the targets where the wrench is zero.
    """
    return compensate_targets_and_joints(robot, Ts_base_target, joints, wrenches, model, mode)[0]


@dataclass(frozen=True)
class OnlineCompensationParams:
    """The chapter's real-time compensation (fig. 15).

    Attributes:
        model: Identified joint stiffness.
        tool_gravity: Identified tool weight and sensor bias.
        filter_cutoff_hz: Low-pass on the compensated wrench.
        enabled: False passes the nominal reference through (for A/B runs).
    """

    model: JointCompliance
    tool_gravity: ToolGravity
    filter_cutoff_hz: float = FORCE_FILTER_CUTOFF_HZ
    enabled: bool = True


@dataclass(frozen=True)
class OnlineCompensationState:
    """Filtered contact wrench at the TCP in base axes, (6,) [N, N*m]."""

    wrench_filtered: np.ndarray = field(default_factory=lambda: np.zeros(6))


def online_compensation_step(
    robot: Robot,
    state: OnlineCompensationState,
    joints_nominal_rad: np.ndarray,
    wrench_sensor: np.ndarray,
    params: OnlineCompensationParams,
    dt: float,
) -> tuple[OnlineCompensationState, np.ndarray]:
    """One control step: q_ref = q_nom - Kq^-1 J(q_nom)^T W_f.

    W_f is the sensor reading, gravity-compensated with the sensor orientation the controller
    knows (motor side), moved to the TCP in base axes and low-pass filtered.

    Returns:
        (next state, joint reference (6,) [rad]).
    """
    q = np.asarray(joints_nominal_rad, dtype=float)
    if not params.enabled:
        return state, q.copy()
    R = robot.flange_pose(q)[:3, :3].copy()
    contact = compensate_gravity(wrench_sensor, R, params.tool_gravity)
    W = wrench_at_tcp_in_base(contact, R, robot.T_flange_tcp[:3, 3])
    tau = 1.0 / (2.0 * np.pi * params.filter_cutoff_hz)
    alpha = dt / (dt + tau)
    W_f = state.wrench_filtered + alpha * (W - state.wrench_filtered)
    _, J = robot.fk_and_jacobian(q)
    return OnlineCompensationState(W_f), q - params.model.compliance_rad_Nm * (J.T @ W_f)
