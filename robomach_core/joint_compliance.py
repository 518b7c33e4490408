"""Joint compliance of the simulated arm: the hidden truth of how much the robot bends.

The model of the chapter (section 5.1, eq. 16-19) and shared/DESIGN.md: six torsional springs,
the sensor and flange lumped into joint 6, so the arm-side joints under an external wrench W
(at the TCP, base-aligned axes) are

    q_arm = q_motor + Kq^-1 J(q)^T W.

The controller only sees ``q_motor``. The true ``Kq`` below belongs to the simulator: controller
code must identify it (``robomach_core.stiffness``) rather than import it.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .errors import InvalidInputError, UnknownNameError

# Joint stiffness [N*m/rad] chosen so the Cartesian stiffness at the work pose is 0.6-4 N/um,
# the range of industrial arms (the chapter: "usually less than 1 N/um"; under the chapter's
# 300 N feed + 300 N cutting + 50 N normal load the TCP moves about 0.3 mm).
TRUE_JOINT_STIFFNESS_NM_RAD: dict[str, tuple[float, ...]] = {
    "ur10": (1.2e6, 1.0e6, 7.0e5, 2.5e5, 2.5e5, 2.0e5),
    "ur5": (6.0e5, 5.0e5, 3.5e5, 1.2e5, 1.2e5, 1.0e5),
    "ur3": (3.0e5, 2.5e5, 1.8e5, 6.0e4, 6.0e4, 5.0e4),
    # The big ABB arms, chosen for 1.2-3.5 N/um (IRB 4400) and 1.3-6 N/um (IRB 6640) over the
    # translation directions with the tool down at their built-in work pose
    # (tests/core/test_abb.py checks the softest one is 1-3.5 N/um): stiffer than the UR10 and
    # the chapter's IRB 6400 (~0.5 N/um), in the range given for machining arms.
    "irb4400": (4.0e6, 3.5e6, 2.5e6, 4.0e5, 4.0e5, 2.5e5),
    "irb6640": (8.0e6, 7.0e6, 5.0e6, 8.0e5, 8.0e5, 5.0e5),
    # The Lund papers' IRB 2400 (no joint stiffness published): between the UR10 and the
    # IRB 4400, 0.8-3 N/um over the translation directions at its built-in work pose.
    "irb2400": (2.5e6, 2.0e6, 1.5e6, 2.5e5, 2.5e5, 1.5e5),
    # The KR 270: the inverse of the compliance paper's Table 1 joint compliances
    # k1..k6 = 0.26, 0.15, 0.26, 1.79, 1.52, 2.13 x 1e-6 rad/(N m).
    "kr270": tuple(1.0 / (c * 1e-6) for c in (0.26, 0.15, 0.26, 1.79, 1.52, 2.13)),
}


@dataclass(frozen=True)
class JointCompliance:
    """Six torsional joint springs.

    Attributes:
        stiffness_Nm_rad: (6,) joint stiffness Kq.
    """

    stiffness_Nm_rad: tuple[float, ...]

    def __post_init__(self) -> None:
        k = np.asarray(self.stiffness_Nm_rad, dtype=float)
        if k.shape != (6,) or not np.all(np.isfinite(k)) or np.any(k <= 0):
            raise InvalidInputError("joint stiffness must be six positive finite values in N*m/rad")

    @property
    def compliance_rad_Nm(self) -> np.ndarray:
        """(6,) Kq^-1."""
        return 1.0 / np.asarray(self.stiffness_Nm_rad, dtype=float)

    def joint_deflection(self, J: np.ndarray, wrench: np.ndarray) -> np.ndarray:
        """Arm-side minus motor-side joints, dq = Kq^-1 J^T W (eq. 16). Shapes (6,6), (6,)."""
        return self.compliance_rad_Nm * (J.T @ wrench)

    def cartesian_compliance(self, J: np.ndarray) -> np.ndarray:
        """C = J Kq^-1 J^T (6x6), the Cartesian compliance at the pose of ``J`` (eq. 19)."""
        return (J * self.compliance_rad_Nm) @ J.T


def true_joint_compliance(robot_name: str) -> JointCompliance:
    """The simulator's hidden joint stiffness for a robot model."""
    try:
        return JointCompliance(TRUE_JOINT_STIFFNESS_NM_RAD[robot_name.lower()])
    except KeyError:
        raise UnknownNameError(f"no joint stiffness known for robot {robot_name!r}") from None
