"""Joint-stiffness model of the arm: linear Cartesian compliance and the non-linear equilibrium.

PROBLEM   Process forces bend the arm; the controller must predict by how much, at any pose,
          from six joint stiffnesses (the chapter, section 5.1: torsional springs, the F/T sensor
          and flange lumped into joint 6).
STRATEGY  Linear model (chapter eq. 16-19): joint deflection dq = Kq^-1 J^T W and the Cartesian
          compliance C = J Kq^-1 J^T, both at the unloaded joints. Non-linear model (compliance
          paper, eq. 6-10 and 17): the equilibrium Kq theta = J(q_m + theta)^T W with the Jacobian
          at the *loaded* configuration, so the change of geometry under load is kept; solved by
          iteration, and its inverse problem (the wrench that holds the TCP at a given pose) by
          the paper's scheme eq. (10).
SOLUTION  ``cartesian_compliance``, ``loaded_equilibrium`` (mode linear or non-linear),
          ``equilibrium_at_pose`` (eq. 10), ``loaded_cartesian_compliance`` (eq. 17).

Conventions: a wrench W is (6,) [force (N); moment (N*m)] acting on the arm at the TCP, in
base-aligned axes; a twist is (6,) [dp (m); dtheta (rad)], dtheta a rotation vector in base axes.
The model is a ``JointCompliance`` (identified by ``identification``, or the simulator's truth).
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Literal

import numpy as np
import pinocchio as pin

from ..cell import JointCompliance, Robot
from ..transforms import pose_error
from .errors import ConvergenceError

ModelKind = Literal["linear", "nonlinear"]

# Fixed-point iterations of the loaded equilibrium stop when the joint deflection changes less
# than this between iterations (about 1e-9 m at a 1 m lever).
EQUILIBRIUM_TOLERANCE_RAD = 1e-12
EQUILIBRIUM_MAX_ITERATIONS = 50
# Joint step of the central differences of J(q)^T W in eq. (17).
HESSIAN_STEP_RAD = 1e-6


def apply_twist(T: np.ndarray, twist: np.ndarray) -> np.ndarray:
    """Pose ``T`` moved by a small twist: p + dp, R' = exp(dtheta) R (rotation in base axes)."""
    out = np.array(T, dtype=float, copy=True)
    out[:3, 3] = T[:3, 3] + twist[:3]
    if np.any(twist[3:]):
        out[:3, :3] = pin.exp3(np.asarray(twist[3:], dtype=float)) @ T[:3, :3]
    return out


def cartesian_compliance(
    robot: Robot, joints_rad: np.ndarray, model: JointCompliance
) -> np.ndarray:
    """C = J Kq^-1 J^T (6x6, [m/N, m/(N*m); rad/N, rad/(N*m)]) at ``joints_rad``, eq. (19)."""
    _, J = robot.fk_and_jacobian(np.asarray(joints_rad, dtype=float))
    return model.cartesian_compliance(J)


def linear_deflection(
    robot: Robot, joints_rad: np.ndarray, wrench: np.ndarray, model: JointCompliance
) -> np.ndarray:
    """TCP twist C W (6,) under ``wrench`` by the linear model at the unloaded joints."""
    return cartesian_compliance(robot, joints_rad, model) @ np.asarray(wrench, dtype=float)


@dataclass(frozen=True)
class LoadedEquilibrium:
    """The arm under a wrench.

    Attributes:
        joints_arm_rad: (6,) arm-side joints (motor joints + spring deflection).
        T_base_tcp: 4x4 loaded TCP pose.
        deflection: (6,) twist from the unloaded TCP pose to the loaded one.
        iterations: Iterations the non-linear scheme used (1 for the linear model).
    """

    joints_arm_rad: np.ndarray
    T_base_tcp: np.ndarray
    deflection: np.ndarray
    iterations: int


def loaded_equilibrium(
    robot: Robot,
    joints_motor_rad: np.ndarray,
    wrench: np.ndarray,
    model: JointCompliance,
    *,
    mode: ModelKind = "nonlinear",
    tolerance_rad: float = EQUILIBRIUM_TOLERANCE_RAD,
    max_iterations: int = EQUILIBRIUM_MAX_ITERATIONS,
) -> LoadedEquilibrium:
    """Static equilibrium of the arm whose motors hold ``joints_motor_rad`` under ``wrench``.

    ``"linear"``: theta = Kq^-1 J(q_m)^T W and the TCP moves by the twist C(q_m) W (eq. 16-19).
    ``"nonlinear"``: Kq theta = J(q_m + theta)^T W, eq. (6) without link weights, by fixed-point
    iteration (each step re-evaluates the Jacobian at the deflected joints, the change of
    geometry under load); the TCP pose is the exact forward kinematics at q_m + theta.

    Raises:
        ConvergenceError: the iteration did not settle (a load near the arm's buckling limit).
    """
    q_m = np.asarray(joints_motor_rad, dtype=float)
    W = np.asarray(wrench, dtype=float)
    c = model.compliance_rad_Nm
    T0, J0 = robot.fk_and_jacobian(q_m)
    T0 = T0.copy()
    if not W.any():  # no load: the arm where its motors hold it (exactly)
        return LoadedEquilibrium(q_m.copy(), T0, np.zeros(6), 1)
    theta = c * (J0.T @ W)
    if mode == "linear":
        deflection = J0 @ theta
        return LoadedEquilibrium(q_m + theta, apply_twist(T0, deflection), deflection, 1)
    for iteration in range(1, max_iterations + 1):
        _, J = robot.fk_and_jacobian(q_m + theta)
        theta_next = c * (J.T @ W)
        step = float(np.max(np.abs(theta_next - theta)))
        theta = theta_next
        if step <= tolerance_rad:
            T = robot.fk(q_m + theta).copy()
            return LoadedEquilibrium(q_m + theta, T, pose_error(T0, T), iteration)
    raise ConvergenceError(
        f"the loaded equilibrium did not converge in {max_iterations} iterations "
        f"(last step {step:.1e} rad); the load is too large for the model"
    )


def equilibrium_at_pose(
    robot: Robot,
    joints_motor_rad: np.ndarray,
    T_base_tcp: np.ndarray,
    model: JointCompliance,
    *,
    tolerance_rad: float = EQUILIBRIUM_TOLERANCE_RAD,
    max_iterations: int = EQUILIBRIUM_MAX_ITERATIONS,
) -> tuple[np.ndarray, np.ndarray]:
    """Wrench and arm-side joints that hold the TCP at ``T_base_tcp``: the scheme of eq. (10).

    F_{i+1} = (J Kq^-1 J^T)^-1 (t - g(theta_i) + J theta_i), theta_{i+1} = Kq^-1 J^T F_{i+1},
    with J = J(q_m + theta_i) and no link weights (G = 0). The inverse of ``loaded_equilibrium``.

    Returns:
        (wrench (6,), joints_arm_rad (6,)).
    """
    q_m = np.asarray(joints_motor_rad, dtype=float)
    c = model.compliance_rad_Nm
    theta = np.zeros(6)
    for _ in range(max_iterations):
        T, J = robot.fk_and_jacobian(q_m + theta)
        rhs = pose_error(T, T_base_tcp) + J @ theta
        F = np.linalg.solve((J * c) @ J.T, rhs)
        theta_next = c * (J.T @ F)
        step = float(np.max(np.abs(theta_next - theta)))
        theta = theta_next
        if step <= tolerance_rad:
            return F, q_m + theta
    raise ConvergenceError(
        f"the equilibrium at the given pose did not converge in {max_iterations} iterations"
    )


def loaded_cartesian_compliance(
    robot: Robot, joints_motor_rad: np.ndarray, wrench: np.ndarray, model: JointCompliance
) -> np.ndarray:
    """Compliance about the loaded equilibrium, eq. (17): C = J (Kq - H)^-1 J^T.

    H = d(J(q)^T W)/dq at the loaded joints (central differences) is the geometric stiffness
    the load adds; at zero load C equals ``cartesian_compliance``.
    """
    W = np.asarray(wrench, dtype=float)
    q = loaded_equilibrium(robot, joints_motor_rad, W, model).joints_arm_rad
    H = np.empty((6, 6))
    for j in range(6):
        dq = np.zeros(6)
        dq[j] = HESSIAN_STEP_RAD
        _, J_plus = robot.fk_and_jacobian(q + dq)
        g_plus = J_plus.T @ W
        _, J_minus = robot.fk_and_jacobian(q - dq)
        H[:, j] = (g_plus - J_minus.T @ W) / (2 * HESSIAN_STEP_RAD)
    _, J = robot.fk_and_jacobian(q)
    K = np.diag(np.asarray(model.stiffness_Nm_rad, dtype=float))
    return J @ np.linalg.solve(K - H, J.T)
