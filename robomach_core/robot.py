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

import importlib.metadata
import threading
from collections.abc import Iterator, Mapping
from pathlib import Path

import numpy as np
import pinocchio as pin

from . import _kernels
from .errors import SingularConfigurationError, UnknownNameError, UnreachableTargetError
from .robots import builtin, custom
from .robots.builtin import GENERATED_ARMS, JointCoupling
from .transforms import pose_error

# A program language's name (``export.languages``: "rapid", "urscript", "krl", ...).
ProgramLanguage = str

_UR_URDFS: dict[str, str] = {
    "ur10": "ur_description/urdf/ur10_robot.urdf",
    "ur5": "ur_description/urdf/ur5_robot.urdf",
    "ur3": "ur_description/urdf/ur3_robot.urdf",
}


class _RobotUrdfs(Mapping):
    """Robot name -> URDF path, relative to ``robots_directory()`` for example-robot-data's arms.

    The ABB and KUKA arms' URDFs are generated (``robots.builtin``) and written into a cache
    folder when first looked up; their value is that absolute path, so
    ``robots_directory() / value`` is the file for every arm.
    """

    def __getitem__(self, name: str) -> str:
        if name in _UR_URDFS:
            return _UR_URDFS[name]
        if name in GENERATED_ARMS:
            return str(builtin.generated_urdf_path(name))
        if isinstance(name, str) and custom.is_custom(name):
            return str(custom.urdf_file(name))  # a user's file (robots.custom), cached
        raise KeyError(name)

    def __contains__(self, name: object) -> bool:  # no file is written to answer this
        return (
            name in _UR_URDFS
            or name in GENERATED_ARMS
            or (isinstance(name, str) and custom.is_custom(name))
        )

    def __iter__(self) -> Iterator[str]:
        return iter([*_UR_URDFS, *GENERATED_ARMS])

    def __len__(self) -> int:
        return len(_UR_URDFS) + len(GENERATED_ARMS)


ROBOT_URDFS: Mapping[str, str] = _RobotUrdfs()
# The built-in arms, for every robot choice (CLI, API schema, GUIs): UR, ABB, then KUKA arms.
ROBOT_NAMES: tuple[str, ...] = (*_UR_URDFS, *GENERATED_ARMS)
# Whose controller each arm has (``robots.builtin.ARM_FAMILIES``); uploaded arms register too.
ROBOT_FAMILY: dict[str, str] = {**dict.fromkeys(_UR_URDFS, "ur"), **builtin.ARM_FAMILY}
# The language a family's controller runs natively (``export.languages`` lists every language
# and the families it serves).
FAMILY_LANGUAGE: dict[str, ProgramLanguage] = {"ur": "urscript", "abb": "rapid", "kuka": "krl"}
# The language of the programs each arm's controller runs.
ROBOT_PROGRAM_LANGUAGE: dict[str, ProgramLanguage] = {
    name: FAMILY_LANGUAGE[family] for name, family in ROBOT_FAMILY.items()
}
FLANGE_FRAME = "tool0"
# A home pose with the tool pointing down above the table in front of the robot (UR arms).
HOME_JOINTS_RAD = np.array([0.0, -1.7, 1.9, -1.77, -1.5708, 0.0])
# Home poses per arm: tool pointing down, above the built-in workpiece's placement
# (``workpiece.default_T_base_wobj``), in the controller's axis zeros and directions (ABB's;
# KUKA's A1-A6).
ROBOT_HOME_JOINTS_RAD: dict[str, np.ndarray] = {
    **dict.fromkeys(_UR_URDFS, HOME_JOINTS_RAD),
    "irb4400": np.radians([0.0, 22.0, 19.0, 0.0, 49.0, -90.0]),
    "irb2400": np.radians([0.0, 4.1, 30.2, 0.0, 55.8, -90.0]),
    "irb6640": np.radians([0.0, 0.0, 41.0, 0.0, 49.0, -90.0]),
    "kr270": np.radians([0.0, -69.4, 96.9, 0.0, 62.5, 90.0]),
}
# Below this smallest singular value of the 6x6 TCP Jacobian the arm is called singular.
SINGULAR_VALUE_MIN = 1e-3


def robots_directory() -> Path:
    """Folder of the URDFs that the ``example-robot-data`` wheel installs (it has no module)."""
    dist = importlib.metadata.distribution("example-robot-data")
    return Path(str(dist.locate_file("cmeel.prefix/share/example-robot-data/robots")))


def robot_urdf_path(name: str) -> Path:
    """The URDF file of a robot by name (ABB arms: generated at first use)."""
    key = name.lower()
    if key not in ROBOT_URDFS:
        raise UnknownNameError(
            f"unknown robot {name!r}; choose one of {', '.join(sorted(ROBOT_URDFS))}"
        )
    return robots_directory() / ROBOT_URDFS[key]


def program_language(name: str) -> ProgramLanguage:
    """The language the arm's controller runs: ``"rapid"`` (ABB), ``"urscript"`` (UR),
    ``"krl"`` (KUKA)."""
    try:
        return ROBOT_PROGRAM_LANGUAGE[name.lower()]
    except KeyError:
        raise UnknownNameError(
            f"unknown robot {name!r}; choose one of {', '.join(sorted(ROBOT_URDFS))}"
        ) from None


class Robot:
    """A 6-axis arm with a TCP frame; holds one pinocchio Model and its Data buffers.

    Args:
        name: ``"ur10"`` (default), ``"ur5"``, ``"ur3"`` (example-robot-data), an ABB arm
            (``"irb4400"``, ``"irb2400"``, ``"irb6640"``, built by ``robots.abb``), a KUKA arm
            (``"kr270"``, ``robots.kuka``) or a registered user arm (``robots.custom``).
        T_flange_tcp: 4x4 TCP pose in the flange frame (metres).
    """

    def __init__(self, name: str = "ur10", T_flange_tcp: np.ndarray | None = None) -> None:
        key = name.lower()
        if key not in ROBOT_URDFS:
            raise UnknownNameError(
                f"unknown robot {name!r}; choose one of {', '.join(sorted(ROBOT_URDFS))}"
            )
        self.name = key
        if key in GENERATED_ARMS:
            self.model = pin.buildModelFromXML(builtin.generated_urdf_text(key))
        elif custom.is_custom(key):
            self.model = pin.buildModelFromXML(custom.urdf_text(key))
        else:
            self.model = pin.buildModelFromUrdf(str(robots_directory() / ROBOT_URDFS[key]))
        self.home_rad = ROBOT_HOME_JOINTS_RAD[key].copy()
        self.program_language: ProgramLanguage = ROBOT_PROGRAM_LANGUAGE[key]
        self.family: str = ROBOT_FAMILY.get(key, "abb")
        # Limits on combinations of joints (a parallel-bar arm's axis 3 from the horizontal).
        self.couplings: tuple[JointCoupling, ...] = builtin.joint_couplings(key)
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
        with self._lock:
            self._cache_key = b""  # the data buffer no longer holds the cached Jacobian's pose
            pin.framesForwardKinematics(self.model, self.data, q)
            return self.data.oMf[self.tcp_frame_id].homogeneous

    def flange_pose(self, q: np.ndarray) -> np.ndarray:
        """4x4 ``T_base_flange`` at joints ``q`` (rad)."""
        with self._lock:
            self._cache_key = b""
            pin.framesForwardKinematics(self.model, self.data, q)
            return self.data.oMf[self.flange_frame_id].homogeneous

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
            pin.computeJointJacobians(self.model, self.data, q)
            pin.updateFramePlacements(self.model, self.data)
            J = pin.getFrameJacobian(
                self.model, self.data, self.tcp_frame_id, pin.ReferenceFrame.LOCAL_WORLD_ALIGNED
            )
            T = self.data.oMf[self.tcp_frame_id].homogeneous
            self._cache_key, self._cache_T, self._cache_J = key, T, J
            return T, J

    def ik_step(
        self, q: np.ndarray, T_base_target: np.ndarray, *, damping: float = 1e-4
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
