"""The robot arm: pinocchio kinematics of a UR (example-robot-data), ABB or KUKA arm, with a TCP.

PROBLEM   The controller needs FK, the TCP Jacobian and an inverse kinematics that never leaves
          the joint limits, and users need a clear word when a pose cannot be reached.
STRATEGY  Build the pinocchio model once from the URDF, add the TCP as an operational frame,
          reuse one ``Data`` buffer. IK is damped least squares (Levenberg-Marquardt) on the
          6-D pose error in the base frame, clamped to the joint limits after every step.
SOLUTION  ``Robot.fk``, ``Robot.fk_and_jacobian``, ``Robot.ik`` and ``Robot.ik_step`` (one
          control-period step), errors from ``robomach_core.errors``.
"""

from __future__ import annotations

import threading
from collections.abc import Iterator, Mapping
from pathlib import Path

import numpy as np
import pinocchio as pin

from .. import _kernels
from ..errors import SingularConfigurationError, UnreachableTargetError
from ..robots import builtin, registry
from ..robots.builtin import JointCoupling
from ..robots.registry import robots_directory as robots_directory
from ..transforms import pose_error

# A program language's name (``export.languages``: "rapid", "urscript", "krl", ...).
ProgramLanguage = str


class _RobotUrdfs(Mapping):
    """Robot name -> its URDF file (``registry.Arm.urdf_path``): the built-in arms when
    iterated; a registered upload is in it too."""

    def __getitem__(self, name: str) -> str:
        if not isinstance(name, str) or not registry.known(name):
            raise KeyError(name)
        return str(registry.arm(name).urdf_path())

    def __contains__(self, name: object) -> bool:  # no file is written to answer this
        return isinstance(name, str) and registry.known(name)

    def __iter__(self) -> Iterator[str]:
        return iter(registry.BUILTIN_NAMES)

    def __len__(self) -> int:
        return len(registry.BUILTIN_NAMES)


ROBOT_URDFS: Mapping[str, str] = _RobotUrdfs()
# The built-in arms, for every robot choice (CLI, API schema, GUIs): UR, ABB, then KUKA arms.
ROBOT_NAMES: tuple[str, ...] = registry.BUILTIN_NAMES
FLANGE_FRAME = "tool0"
# A home pose with the tool pointing down above the table in front of the robot (UR arms).
HOME_JOINTS_RAD = np.array(registry.UR_HOME_JOINTS_RAD)
# Below this smallest singular value of the 6x6 TCP Jacobian the arm is called singular.
SINGULAR_VALUE_MIN = 1e-3
# Damping of the control period's IK step where its Newton step is large (near a singularity).
IK_STEP_DAMPING = 1e-4


def robot_urdf_path(name: str) -> Path:
    """The URDF file of a robot by name (ABB and KUKA arms: generated at first use)."""
    return registry.arm(name).urdf_path()


def program_language(name: str) -> ProgramLanguage:
    """The language the arm's controller runs: ``"rapid"`` (ABB), ``"urscript"`` (UR),
    ``"krl"`` (KUKA)."""
    return registry.arm(name).language


class Robot:
    """A 6-axis arm with a TCP frame; holds one pinocchio Model and its Data buffers.

    Args:
        name: ``"ur10"`` (default), ``"ur5"``, ``"ur3"`` (example-robot-data), an ABB arm
            (``"irb4400"``, ``"irb2400"``, ``"irb6640"``, built by ``robots.abb``), a KUKA arm
            (``"kr270"``, ``robots.kuka``) or a registered user arm (``robots.custom``).
        T_flange_tcp: 4x4 TCP pose in the flange frame (metres).
    """

    def __init__(self, name: str = "ur10", T_flange_tcp: np.ndarray | None = None) -> None:
        self.record = record = registry.arm(name)
        self.name = record.name
        if record.urdf_file is not None:
            self.model = pin.buildModelFromUrdf(str(record.urdf_path()))
        else:
            self.model = pin.buildModelFromXML(record.urdf())
        self.home_rad = np.array(record.home_rad)
        self.program_language: ProgramLanguage = record.language
        self.family: str = record.family
        # Limits on combinations of joints (a parallel-bar arm's axis 3 from the horizontal).
        self.couplings: tuple[JointCoupling, ...] = builtin.joint_couplings(record.name)
        flange_id = self.model.getFrameId(FLANGE_FRAME)
        flange = self.model.frames[flange_id]
        T = np.eye(4) if T_flange_tcp is None else np.asarray(T_flange_tcp, dtype=float)
        self.T_flange_tcp = T.copy()
        placement = flange.placement * pin.SE3(T[:3, :3], T[:3, 3])
        self.tcp_frame_id = self.model.addFrame(
            pin.Frame("tcp", flange.parentJoint, flange_id, placement, pin.FrameType.OP_FRAME)
        )
        self.flange_frame_id = flange_id
        self.data = self.model.createData()
        # One Data buffer (and the FK cache) per robot: the workbench's threads (a running job,
        # an export's reachability check) must not interleave inside pinocchio's buffers.
        self._lock = threading.RLock()
        self._cache_key: bytes = b""
        self._cache_T = np.eye(4)
        self._cache_J = np.zeros((6, 6))
        self.lower_rad = self.model.lowerPositionLimit.copy()
        self.upper_rad = self.model.upperPositionLimit.copy()
        self.velocity_limit_rad_s = self.model.velocityLimit.copy()
        pin.framesForwardKinematics(self.model, self.data, np.zeros(6))
        shoulder = self.data.oMi[2].translation
        self.base_to_shoulder_m = shoulder.copy()
        # Upper bound of the reach: sum of link lengths from the shoulder to the TCP.
        pin.framesForwardKinematics(self.model, self.data, np.zeros(6))
        self.reach_m = float(
            sum(
                np.linalg.norm(self.data.oMi[i + 1].translation - self.data.oMi[i].translation)
                for i in range(2, self.model.njoints - 1)
            )
            + np.linalg.norm(placement.translation)
            + np.linalg.norm(self.model.frames[flange_id].placement.translation)
        )

    @property
    def nq(self) -> int:
        return self.model.nq

    def within_limits(self, q: np.ndarray) -> bool:
        """True when every joint is inside its limits, and every combined limit holds."""
        inside = bool(np.all(q >= self.lower_rad - 1e-9) and np.all(q <= self.upper_rad + 1e-9))
        return inside and builtin.within_couplings(self.couplings, q)

    def clamp(self, q: np.ndarray) -> np.ndarray:
        """``q`` moved into the joint limits and the combined limits (``couplings``)."""
        out = np.minimum(np.maximum(np.asarray(q, dtype=float), self.lower_rad), self.upper_rad)
        if self.couplings:
            out = builtin.project_couplings(self.couplings, out, self.lower_rad, self.upper_rad)
        return out

    def controller_axes_deg(self, q: np.ndarray) -> np.ndarray:
        """The axis values [deg] the arm's controller shows (``robots.controller_axes_deg``)."""
        return builtin.controller_axes_deg(self.name, q)

    def fk(self, q: np.ndarray) -> np.ndarray:
        """4x4 ``T_base_tcp`` at joints ``q`` (rad)."""
        return self._frame_pose(q, self.tcp_frame_id)

    def flange_pose(self, q: np.ndarray) -> np.ndarray:
        """4x4 ``T_base_flange`` at joints ``q`` (rad)."""
        return self._frame_pose(q, self.flange_frame_id)

    def _frame_pose(self, q: np.ndarray, frame_id: int) -> np.ndarray:
        with self._lock:
            self._cache_key = b""  # the data buffer no longer holds the cached Jacobian's pose
            pin.forwardKinematics(self.model, self.data, q)
            return pin.updateFramePlacement(self.model, self.data, frame_id).homogeneous

    def fk_and_jacobian(self, q: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """``T_base_tcp`` and the 6x6 TCP Jacobian [v; omega] in base-aligned axes.

        The last result is cached: a control loop asks for the same joints twice per period
        (the simulator, then the controller's IK), and pinocchio's data buffer is reused.
        Treat the returned arrays as read-only.
        """
        key = q.tobytes()
        with self._lock:
            if key == self._cache_key:
                return self._cache_T, self._cache_J
            J = pin.computeFrameJacobian(
                self.model, self.data, q, self.tcp_frame_id, pin.ReferenceFrame.LOCAL_WORLD_ALIGNED
            )
            T = pin.updateFramePlacement(self.model, self.data, self.tcp_frame_id).homogeneous
            self._cache_key, self._cache_T, self._cache_J = key, T, J
            return T, J

    def ik_step(
        self, q: np.ndarray, T_base_target: np.ndarray, *, damping: float = IK_STEP_DAMPING
    ) -> np.ndarray:
        """One damped-least-squares step towards ``T_base_target``, clamped to the joint limits.

        dq = J^T (J J^T + lambda^2 I)^-1 e, with e the 6-D pose error. Used every control
        period, where the target moves by micrometres so one step tracks it.
        """
        T, J = self.fk_and_jacobian(q)
        # Plain Newton step, exact away from singularities; damped least squares near them.
        out = _kernels.ik_newton_step(
            np.asarray(q, dtype=float),
            T,
            J,
            np.asarray(T_base_target, dtype=float),
            self.lower_rad,
            self.upper_rad,
            damping,
        )
        if self.couplings:
            out = builtin.project_couplings(self.couplings, out, self.lower_rad, self.upper_rad)
        return out

    def ik(
        self,
        T_base_target: np.ndarray,
        q_init: np.ndarray | None = None,
        *,
        tolerance_m: float = 1e-6,
        tolerance_rad: float = 1e-5,
        max_iterations: int = 200,
    ) -> np.ndarray:
        """Joint angles reaching ``T_base_target`` inside the joint limits.

        Raises:
            UnreachableTargetError: the TCP position is beyond the arm's reach, or the solver
                cannot reach the pose inside the joint limits.
            SingularConfigurationError: the solution would be at a singularity.
        """
        target = np.asarray(T_base_target, dtype=float)
        p = target[:3, 3]
        distance = float(np.linalg.norm(p - self.base_to_shoulder_m))
        if not np.all(np.isfinite(target)):
            raise UnreachableTargetError("target pose has non-finite values")
        if distance > self.reach_m:
            raise UnreachableTargetError(
                f"target at {np.round(p * 1e3, 1).tolist()} mm is {distance * 1e3:.0f} mm from "
                f"the shoulder, beyond the {self.name} reach of {self.reach_m * 1e3:.0f} mm"
            )
        seeds = [self.home_rad.copy() if q_init is None else np.asarray(q_init, float).copy()]
        seeds += [
            self.home_rad + d
            for d in (np.array([0.6, 0, 0, 0, 0, 0]), np.array([-0.6, 0, 0, 0, 0, 0]))
        ]
        best_error = np.inf
        for seed in seeds:
            q = self.clamp(seed)
            damping = 1e-3
            for _ in range(max_iterations):
                T, J = self.fk_and_jacobian(q)
                e = pose_error(T, target)
                if np.linalg.norm(e[:3]) < tolerance_m and np.linalg.norm(e[3:]) < tolerance_rad:
                    sigma_min = np.linalg.svd(J, compute_uv=False)[-1]
                    if sigma_min < SINGULAR_VALUE_MIN:
                        raise SingularConfigurationError(
                            f"target at {np.round(p * 1e3, 1).tolist()} mm is at a singular "
                            f"configuration (smallest Jacobian singular value {sigma_min:.1e})"
                        )
                    return q
                dq = J.T @ np.linalg.solve(J @ J.T + damping**2 * np.eye(6), e)
                step = np.linalg.norm(dq)
                if step > 0.5:
                    dq *= 0.5 / step
                q = self.clamp(q + dq)
            best_error = min(best_error, float(np.linalg.norm(e[:3])))
        raise UnreachableTargetError(
            f"cannot reach target at {np.round(p * 1e3, 1).tolist()} mm inside the joint limits "
            f"(closest {best_error * 1e3:.2f} mm)"
        )

    def singular_value_min(self, q: np.ndarray) -> float:
        """Smallest singular value of the TCP Jacobian (a distance to singularity)."""
        _, J = self.fk_and_jacobian(q)
        return float(np.linalg.svd(J, compute_uv=False)[-1])
