"""Identification of the joint stiffness from CMM measurements under known loads (chapter 5.2).

PROBLEM   The controller needs Kq but cannot take the arm apart; only the Cartesian deflection
          of a sphere tip under known loads can be measured (CMM, 10-50 um noise).
STRATEGY  Simulate the chapter's procedure: at many poses, measure the tip with the CMM before
          and after a known load (weights hung on the tip; a pulley for the other directions),
          the load read by the F/T sensor. Eq. (23), translational rows only:
          dx = J_v Kq^-1 J^T F = J_v diag(J^T F) c with c = Kq^-1, linear in c, so c follows by
          bounded least squares over all poses and loads.
SOLUTION  ``simulate_stiffness_measurements``, ``identify_joint_stiffness``,
          ``sample_workspace_joints`` and ``prediction_errors``; ``stiffness_campaign`` runs the
          whole campaign on an arm (what the studies and the machining run identify with).

The sphere tip sits off the joint-6 axis (``SPHERE_TIP_OFFSET_M``): a tip on the axis would not
move when joint 6 twists, and joint 6's stiffness (with the sensor and flange lumped in) would
be unobservable from translations alone.
"""

from __future__ import annotations

import functools
from dataclasses import dataclass

import numpy as np
from scipy.optimize import lsq_linear

from ..errors import SingularConfigurationError, UnreachableTargetError
from ..joint_compliance import JointCompliance, true_joint_compliance
from ..robot import Robot
from ..transforms import make_transform, rotation_about
from .errors import IdentificationError
from .model import loaded_equilibrium

# Eccentric sphere tip of the calibration tool, flange frame [m].
SPHERE_TIP_OFFSET_M = (0.15, 0.0, 0.30)
# Loads of one measurement set [N], base axes: 20 kg and 40 kg weights, then a pulley pulling
# 300 N four ways. Heavy loads and a long lever keep the wrist deflections well above the CMM
# noise (the wrist joints move the tip by only ~30 um under 200 N at a 150 mm lever).
DEFAULT_LOADS_N = (
    (0.0, 0.0, -196.2),
    (0.0, 0.0, -392.4),
    (300.0, 0.0, 0.0),
    (-300.0, 0.0, 0.0),
    (0.0, 300.0, 0.0),
    (0.0, -300.0, 0.0),
)
# The workspace box in front of the UR10 the studies sample [m] and the largest tilt of the
# tool from pointing straight down [rad].
WORKSPACE_CENTER_M = (0.70, 0.10, 0.15)
WORKSPACE_HALF_SIZE_M = (0.20, 0.30, 0.15)
WORKSPACE_TILT_MAX_RAD = 0.5
# Poses closer to a singularity than this (smallest Jacobian singular value) are skipped.
WORKSPACE_SINGULAR_VALUE_MIN = 0.05
# Stiffness below this compliance bound [rad/(N*m)] is treated as rigid by the solver.
COMPLIANCE_MIN_RAD_NM = 1e-10


def sphere_tip_transform() -> np.ndarray:
    """4x4 ``T_flange_tip`` of the calibration sphere tip."""
    return make_transform(np.eye(3), np.asarray(SPHERE_TIP_OFFSET_M, dtype=float))


def sample_workspace_joints(
    robot: Robot,
    count: int,
    *,
    seed: int,
    center_m: tuple[float, float, float] = WORKSPACE_CENTER_M,
    half_size_m: tuple[float, float, float] = WORKSPACE_HALF_SIZE_M,
    tilt_max_rad: float = WORKSPACE_TILT_MAX_RAD,
) -> np.ndarray:
    """Joint angles of ``count`` random TCP poses in a box, tool tilted from pointing down.

    Returns:
        Shape (count, 6) [rad]; every pose reachable and away from singularities.
    """
    rng = np.random.default_rng(seed)
    down = np.diag([1.0, -1.0, -1.0])
    joints: list[np.ndarray] = []
    attempts = 0
    while len(joints) < count:
        attempts += 1
        if attempts > 50 * count + 100:
            raise UnreachableTargetError("too few reachable poses in the workspace box")
        p = np.asarray(center_m) + rng.uniform(-1.0, 1.0, 3) * np.asarray(half_size_m)
        axis = rng.normal(size=3)
        axis[2] = 0.0
        tilt = rng.uniform(0.0, tilt_max_rad)
        spin = rng.uniform(-np.pi, np.pi)
        R = rotation_about(axis, tilt) @ down @ rotation_about("z", spin)
        try:
            q = robot.ik(make_transform(R, p))
        except (UnreachableTargetError, SingularConfigurationError):
            continue
        if robot.singular_value_min(q) >= WORKSPACE_SINGULAR_VALUE_MIN:
            joints.append(q)
    return np.array(joints)


@dataclass(frozen=True)
class StiffnessMeasurements:
    """One CMM campaign; row i is one load at one pose.

    Attributes:
        joints_rad: (n, 6) motor joints held during the load.
        force_N: (n, 3) load on the tip as the F/T sensor reads it, base axes.
        displacement_m: (n, 3) tip position after minus before the load, as the CMM reads it.
    """

    joints_rad: np.ndarray
    force_N: np.ndarray
    displacement_m: np.ndarray


def simulate_stiffness_measurements(
    robot: Robot,
    joints_rad: np.ndarray,
    truth: JointCompliance,
    *,
    loads_N: np.ndarray | tuple = DEFAULT_LOADS_N,
    cmm_noise_m: float = 20e-6,
    force_noise_N: float = 0.5,
    seed: int = 0,
    nonlinear: bool = True,
) -> StiffnessMeasurements:
    """The chapter's procedure (fig. 14) on the simulated arm.

    ``robot`` must carry the sphere tip as its TCP. Each CMM reading has Gaussian noise of
    ``cmm_noise_m`` per axis (so a displacement has sqrt(2) of it); the F/T reading has
    ``force_noise_N`` per axis. ``nonlinear`` bends the arm by the exact equilibrium (the
    physical truth), otherwise by the linear model (for exactness checks).
    """
    rng = np.random.default_rng(seed)
    loads = np.asarray(loads_N, dtype=float).reshape(-1, 3)
    rows_q, rows_f, rows_d = [], [], []
    mode = "nonlinear" if nonlinear else "linear"
    for q in np.asarray(joints_rad, dtype=float):
        for f in loads:
            W = np.concatenate([f, np.zeros(3)])
            deflection = loaded_equilibrium(robot, q, W, truth, mode=mode).deflection[:3]
            before = rng.normal(0.0, cmm_noise_m, 3)
            after = deflection + rng.normal(0.0, cmm_noise_m, 3)
            rows_q.append(q)
            rows_f.append(f + rng.normal(0.0, force_noise_N, 3))
            rows_d.append(after - before)
    return StiffnessMeasurements(np.array(rows_q), np.array(rows_f), np.array(rows_d))


@dataclass(frozen=True)
class StiffnessIdentification:
    """The identified model and how well the data determine it.

    Attributes:
        model: Identified joint stiffness.
        standard_error_Nm_rad: (6,) one-sigma uncertainty of each joint stiffness.
        residual_rms_m: RMS of the translational residuals.
        condition_number: Of the scaled regressor; large means poorly excited joints.
    """

    model: JointCompliance
    standard_error_Nm_rad: np.ndarray
    residual_rms_m: float
    condition_number: float


def stiffness_regressor(robot: Robot, joints_rad: np.ndarray, force_N: np.ndarray) -> np.ndarray:
    """Rows of eq. (23) linear in c = Kq^-1: A_i = J_v diag(J^T [f; 0]). Shape (3n, 6)."""
    blocks = []
    for q, f in zip(np.asarray(joints_rad), np.asarray(force_N), strict=True):
        _, J = robot.fk_and_jacobian(q)
        tau = J[:3].T @ f
        blocks.append(J[:3] * tau)
    return np.vstack(blocks)


def identify_joint_stiffness(
    robot: Robot, measurements: StiffnessMeasurements
) -> StiffnessIdentification:
    """Kq by least squares from the translational rows of eq. (23).

    Raises:
        IdentificationError: fewer equations than joints, or a joint the loads never excite.
    """
    A = stiffness_regressor(robot, measurements.joints_rad, measurements.force_N)
    b = np.asarray(measurements.displacement_m, dtype=float).reshape(-1)
    if A.shape[0] <= 6:
        raise IdentificationError(
            f"{A.shape[0]} equations cannot determine six joint stiffnesses; add poses or loads"
        )
    scale = np.linalg.norm(A, axis=0)
    if np.any(scale <= 1e-9 * max(float(scale.max()), 1e-300)):
        idle = [i + 1 for i in np.flatnonzero(scale <= 1e-9 * max(float(scale.max()), 1e-300))]
        raise IdentificationError(f"the loads never twist joint(s) {idle}; vary poses or loads")
    As = A / scale
    singular = np.linalg.svd(As, compute_uv=False)
    condition = float(singular[0] / singular[-1]) if singular[-1] > 0 else np.inf
    if not np.isfinite(condition) or condition > 1e8:
        raise IdentificationError("the poses and loads do not separate the six joints")
    solution = lsq_linear(As, b, bounds=(COMPLIANCE_MIN_RAD_NM * scale, np.inf), method="bvls")
    c = solution.x / scale
    residual = A @ c - b
    dof = max(A.shape[0] - 6, 1)
    sigma2 = float(residual @ residual) / dof
    cov_c = sigma2 * np.linalg.inv(A.T @ A)
    std_c = np.sqrt(np.maximum(np.diag(cov_c), 0.0))
    k = 1.0 / c
    return StiffnessIdentification(
        model=JointCompliance(tuple(float(v) for v in k)),
        standard_error_Nm_rad=std_c * k**2,
        residual_rms_m=float(np.sqrt(np.mean(residual**2))),
        condition_number=condition,
    )


def prediction_errors(
    robot: Robot,
    joints_rad: np.ndarray,
    wrenches: np.ndarray,
    model: JointCompliance,
    truth: JointCompliance,
) -> np.ndarray:
    """|predicted - true| TCP deflection [m] per pose: identified linear model vs simulated arm.

    Shapes: joints (n, 6), wrenches (n, 6) base-aligned at the TCP; returns (n,).
    """
    errors = []
    for q, W in zip(np.asarray(joints_rad), np.asarray(wrenches), strict=True):
        predicted = loaded_equilibrium(robot, q, W, model, mode="linear").deflection[:3]
        true = loaded_equilibrium(robot, q, W, truth).deflection[:3]
        errors.append(float(np.linalg.norm(predicted - true)))
    return np.array(errors)


@functools.lru_cache(maxsize=8)
def stiffness_campaign(
    robot_name: str,
    *,
    poses: int = 30,
    seed: int = 0,
    cmm_noise_m: float = 20e-6,
    center_m: tuple[float, float, float] = WORKSPACE_CENTER_M,
) -> tuple[StiffnessMeasurements, StiffnessIdentification]:
    """The chapter's campaign on the arm ``robot_name`` (section 5.2): the sphere tip measured
    by the CMM under known loads at ``poses`` random poses around ``center_m``, with the
    simulator's true stiffness, then eq. (23) by least squares. Seeded, so cached (treat the
    arrays as read-only)."""
    tip_robot = Robot(robot_name, sphere_tip_transform())
    joints = sample_workspace_joints(tip_robot, poses, seed=seed, center_m=center_m)
    data = simulate_stiffness_measurements(
        tip_robot, joints, true_joint_compliance(robot_name), cmm_noise_m=cmm_noise_m, seed=seed
    )
    return data, identify_joint_stiffness(tip_robot, data)


def identify_stiffness(
    robot_name: str, *, seed: int = 0, poses: int = 30, cmm_noise_m: float = 20e-6
) -> StiffnessIdentification:
    """Kq identified by ``stiffness_campaign`` in the default workspace box."""
    return stiffness_campaign(robot_name, poses=poses, seed=seed, cmm_noise_m=cmm_noise_m)[1]
