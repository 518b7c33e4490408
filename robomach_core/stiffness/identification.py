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

What the CMM sees decides what the campaign can identify. One sphere tip 0.15 m off the
joint-6 axis moves by 0.15 m x theta_6 when joint 6 twists: on the IRB 6640 under 300 N, 14 um,
under the CMM's 20 um noise, so joint 6's stiffness (with the sensor and flange lumped in) came
out with a 60 % standard deviation over seeds. The calibration tool therefore carries three
spheres (``CALIBRATION_SPHERES_M``: the load hangs on the first), as a CMM measuring a tool
with several targets does; their three displacements give the tool's rotation too, and each
sphere adds three rows of eq. (23) (sphere j's translational Jacobian, the same joint
torques). The loads grow with the arm (``campaign_loads_N``): a stiff arm needs a heavier weight
to bend measurably, as it carries one. The estimate is ordinary least squares on the
compliance c, which is linear in the data and so unbiased (a bounded solver clipped noisy
compliances and biased them); ``IdentificationError`` when a joint is not excited enough to
give a positive compliance.
"""

from __future__ import annotations

import functools
from dataclasses import dataclass

import numpy as np

from ..cell import JointCompliance, Robot, true_joint_compliance
from ..errors import SingularConfigurationError, UnreachableTargetError
from ..transforms import make_transform, rotation_about
from .errors import IdentificationError
from .model import ModelKind, loaded_equilibrium

# The calibration tool's spheres, flange frame [m]: the load hangs on the first (the sphere
# tip); the CMM measures all three (module docstring).
CALIBRATION_SPHERES_M = ((0.20, 0.0, 0.30), (-0.20, 0.0, 0.30), (0.0, 0.20, 0.30))
SPHERE_TIP_OFFSET_M = CALIBRATION_SPHERES_M[0]
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
# A pulley pulling across the tool at the sphere tip, tip frame [N]: it twists joint 6 by
# 0.2 m x F at every pose (the base-axis pulls do it only as the tool's spin allows).
DEFAULT_TOOL_LOADS_N = ((0.0, 300.0, 0.0), (0.0, -300.0, 0.0))
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


def sphere_offsets_m(spheres_m=CALIBRATION_SPHERES_M) -> np.ndarray:
    """(k, 3) the spheres relative to the first (the sphere tip, the robot's TCP in a
    campaign), in the tip's frame (aligned with the flange)."""
    o = np.asarray(spheres_m, dtype=float).reshape(-1, 3)
    return o - o[0]


@dataclass(frozen=True)
class StiffnessMeasurements:
    """One CMM campaign; row i is one load at one pose.

    Attributes:
        joints_rad: (n, 6) motor joints held during the load.
        force_N: (n, 3) load on the tip as the F/T sensor reads it, base axes.
        displacement_m: (n, 3) tip position after minus before the load, as the CMM reads it.
        sphere_displacements_m: (n, k, 3) every sphere's (the first is the tip's), or None
            when only the tip was measured.
        sphere_offsets_m: (k, 3) the spheres relative to the tip, tip frame (None: the tip).
    """

    joints_rad: np.ndarray
    force_N: np.ndarray
    displacement_m: np.ndarray
    sphere_displacements_m: np.ndarray | None = None
    sphere_offsets_m: np.ndarray | None = None


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
    spheres_m=CALIBRATION_SPHERES_M,
    tool_loads_N: np.ndarray | tuple = (),
) -> StiffnessMeasurements:
    """The chapter's procedure (fig. 14) on the simulated arm.

    ``robot`` must carry the sphere tip (the first of ``spheres_m``) as its TCP. Each CMM
    reading of each sphere has Gaussian noise of ``cmm_noise_m`` per axis (so a displacement
    has sqrt(2) of it); the F/T reading has ``force_noise_N`` per axis. ``nonlinear`` bends
    the arm by the exact equilibrium (the physical truth), otherwise by the linear model (for
    exactness checks). ``spheres_m`` with one sphere measures the tip alone.
    ``tool_loads_N`` are loads given in the tip's frame (a pulley set to pull across the
    tool, twisting joint 6), turned into base axes at each pose.
    """
    rng = np.random.default_rng(seed)
    base_loads = np.asarray(loads_N, dtype=float).reshape(-1, 3)
    tool_loads = np.asarray(tool_loads_N, dtype=float).reshape(-1, 3)
    offsets = sphere_offsets_m(spheres_m)
    rows_q, rows_f, rows_d = [], [], []
    mode: ModelKind = "nonlinear" if nonlinear else "linear"
    for q in np.asarray(joints_rad, dtype=float):
        T0 = robot.fk(q).copy()
        loads = np.vstack([base_loads, tool_loads @ T0[:3, :3].T])
        for f in loads:
            W = np.concatenate([f, np.zeros(3)])
            eq = loaded_equilibrium(robot, q, W, truth, mode=mode)
            if nonlinear:  # each sphere where the bent arm's exact kinematics puts it
                T1 = eq.T_base_tcp
                moved = (T1[:3, :3] - T0[:3, :3]) @ offsets.T + (T1[:3, 3] - T0[:3, 3])[:, None]
            else:  # the linear model: dp + dw x r
                r = T0[:3, :3] @ offsets.T
                moved = eq.deflection[:3, None] + np.cross(eq.deflection[3:], r.T).T
            before = rng.normal(0.0, cmm_noise_m, (len(offsets), 3))
            after = moved.T + rng.normal(0.0, cmm_noise_m, (len(offsets), 3))
            rows_q.append(q)
            rows_f.append(f + rng.normal(0.0, force_noise_N, 3))
            rows_d.append(after - before)
    d = np.array(rows_d)
    return StiffnessMeasurements(np.array(rows_q), np.array(rows_f), d[:, 0, :].copy(), d, offsets)


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


def stiffness_regressor(
    robot: Robot,
    joints_rad: np.ndarray,
    force_N: np.ndarray,
    sphere_offsets: np.ndarray | None = None,
) -> np.ndarray:
    """Rows of eq. (23) linear in c = Kq^-1, per load and sphere j: J_vj diag(J^T [f; 0]),
    J_vj = J_v - [R o_j]x J_w the translational Jacobian of sphere j (offset ``o_j`` from the
    tip, tip frame). Shape (3 k n, 6), the spheres of a load together."""
    offsets = np.zeros((1, 3)) if sphere_offsets is None else np.asarray(sphere_offsets)
    blocks = []
    for q, f in zip(np.asarray(joints_rad), np.asarray(force_N), strict=True):
        T, J = robot.fk_and_jacobian(q)
        tau = J[:3].T @ f
        for o in offsets:
            r = T[:3, :3] @ o
            skew = np.array([[0.0, -r[2], r[1]], [r[2], 0.0, -r[0]], [-r[1], r[0], 0.0]])
            blocks.append((J[:3] - skew @ J[3:]) * tau)
    return np.vstack(blocks)


def identify_joint_stiffness(
    robot: Robot, measurements: StiffnessMeasurements
) -> StiffnessIdentification:
    """Kq by ordinary least squares on c = Kq^-1 from the translational rows of eq. (23),
    every measured sphere's.

    Raises:
        IdentificationError: fewer equations than joints, a joint the loads never excite, or
            one excited too little to come out with a positive compliance.
    """
    m = measurements
    if m.sphere_displacements_m is not None:
        A = stiffness_regressor(robot, m.joints_rad, m.force_N, m.sphere_offsets_m)
        b = np.asarray(m.sphere_displacements_m, dtype=float).reshape(-1)
    else:
        A = stiffness_regressor(robot, m.joints_rad, m.force_N)
        b = np.asarray(m.displacement_m, dtype=float).reshape(-1)
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
    c = np.linalg.lstsq(As, b, rcond=None)[0] / scale
    if np.any(c <= COMPLIANCE_MIN_RAD_NM):
        weak = [i + 1 for i in np.flatnonzero(c <= COMPLIANCE_MIN_RAD_NM)]
        raise IdentificationError(
            f"joint(s) {weak} came out with no compliance: the loads bend them less than the "
            "CMM's noise; use heavier loads, more poses or a finer CMM"
        )
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


# The campaign's box is this high above the arm's work position (the UR10's box was centred
# 0.12 m above its work pose), grown with the arm's reach (``campaign_box``).
CAMPAIGN_HEIGHT_M = 0.12
# Where the studies and the machining cut on a UR arm: in front of it, tool down [m]; elsewhere
# this far from the built-in part's placement for the arm (``registry.Arm.part_position_m``).
UR_WORK_POSITION_M = (0.70, 0.10, 0.03)
WORK_OFFSET_FROM_PART_M = (0.0, 0.10, 0.03)
# The UR10's joint-2 stiffness [N m/rad]: the loads grow with an arm's as sqrt(k2 / this).
REFERENCE_STIFFNESS_NM_RAD = 1.0e6


def arm_work_position_m(robot_name: str) -> np.ndarray:
    """Where the studies cut and measure on the arm, tool down: in front of a UR arm, else
    beside the built-in part's placement for the arm. Shape (3,)."""
    from ..robots.registry import arm

    record = arm(robot_name)
    if record.family == "ur" or record.part_position_m is None:
        return np.asarray(UR_WORK_POSITION_M, dtype=float)
    return np.asarray(record.part_position_m) + np.asarray(WORK_OFFSET_FROM_PART_M)


def campaign_box(
    robot_name: str,
) -> tuple[tuple[float, float, float], tuple[float, float, float]]:
    """(centre, half size) [m] of the campaign's workspace box on the arm: above its work
    position, as large as the UR10's box scaled by the arm's reach there."""
    centre = arm_work_position_m(robot_name) + np.array([0.0, 0.0, CAMPAIGN_HEIGHT_M])
    scale = max(1.0, float(np.linalg.norm(centre[:2]) / np.linalg.norm(WORKSPACE_CENTER_M[:2])))
    half = np.asarray(WORKSPACE_HALF_SIZE_M) * scale
    return _xyz(centre), _xyz(half)


def _xyz(values: np.ndarray | tuple[float, ...]) -> tuple[float, float, float]:
    """A (3,) vector as three plain floats (ValueError when it has another length)."""
    x, y, z = (float(v) for v in values)
    return x, y, z


def campaign_loads_N(robot_name: str) -> tuple[np.ndarray, np.ndarray]:
    """The campaign's loads on the arm, (base-axis loads (6, 3), tip-frame loads (2, 3)):
    ``DEFAULT_LOADS_N`` and ``DEFAULT_TOOL_LOADS_N`` scaled by sqrt(k2 / 1e6 N m/rad), at
    least 1 (on the IRB 6640, 2.6 x: 52 and 104 kg and 800 N pulls, within its 235 kg
    payload), so a stiff arm bends measurably under them."""
    k2 = float(true_joint_compliance(robot_name).stiffness_Nm_rad[1])
    scale = max(1.0, (k2 / REFERENCE_STIFFNESS_NM_RAD) ** 0.5)
    return (
        np.asarray(DEFAULT_LOADS_N, dtype=float) * scale,
        np.asarray(DEFAULT_TOOL_LOADS_N, dtype=float) * scale,
    )


@functools.lru_cache(maxsize=8)
def stiffness_campaign(
    robot_name: str,
    *,
    poses: int = 30,
    seed: int = 0,
    cmm_noise_m: float = 20e-6,
    center_m: tuple[float, float, float] | None = None,
) -> tuple[StiffnessMeasurements, StiffnessIdentification]:
    """The chapter's campaign on the arm ``robot_name`` (section 5.2): the calibration
    tool's three spheres measured by the CMM under known loads (``campaign_loads_N``: weights,
    pulleys along the base axes and across the tool) at ``poses``
    random poses in the arm's box (``campaign_box``, centred at ``center_m`` when given),
    with the simulator's true stiffness, then eq. (23) by least squares. Seeded, so cached
    (treat the arrays as read-only)."""
    centre, half = campaign_box(robot_name)
    if center_m is not None:
        centre = _xyz(center_m)
    tip_robot = Robot(robot_name, sphere_tip_transform())
    joints = sample_workspace_joints(tip_robot, poses, seed=seed, center_m=centre, half_size_m=half)
    loads, tool_loads = campaign_loads_N(robot_name)
    data = simulate_stiffness_measurements(
        tip_robot, joints, true_joint_compliance(robot_name), cmm_noise_m=cmm_noise_m,
        seed=seed, loads_N=loads, tool_loads_N=tool_loads,
    )  # fmt: skip
    return data, identify_joint_stiffness(tip_robot, data)


def identify_stiffness(
    robot_name: str, *, seed: int = 0, poses: int = 30, cmm_noise_m: float = 20e-6
) -> StiffnessIdentification:
    """Kq identified by ``stiffness_campaign`` in the arm's own box."""
    return stiffness_campaign(robot_name, poses=poses, seed=seed, cmm_noise_m=cmm_noise_m)[1]
