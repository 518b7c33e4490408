"""Joint compliance of the simulated arm: the hidden truth of how much the robot bends.

The model of the chapter (section 5.1, eq. 16-19) and shared/DESIGN.md: six torsional springs,
the sensor and flange lumped into joint 6, so the arm-side joints under an external wrench W
(at the TCP, base-aligned axes) are

    q_arm = q_motor + Kq^-1 J(q)^T W.

The controller only sees ``q_motor``. The true ``Kq`` below belongs to the simulator: controller
code must identify it (``robomach_core.stiffness``) rather than import it.
"""

from __future__ import annotations

from collections.abc import Iterator, Mapping
from dataclasses import dataclass

import numpy as np

from ..errors import InvalidInputError
from ..robots import registry


class _TrueStiffness(Mapping):
    """Robot name -> the simulator's joint stiffness Kq [N*m/rad] (``registry.Arm``, where
    the figures and their sources are): the built-in arms when iterated."""

    def __getitem__(self, name: str) -> tuple[float, ...]:
        if not isinstance(name, str) or not registry.known(name):
            raise KeyError(name)
        return registry.arm(name).stiffness_Nm_rad

    def __iter__(self) -> Iterator[str]:
        return iter(registry.BUILTIN_NAMES)

    def __len__(self) -> int:
        return len(registry.BUILTIN_NAMES)


TRUE_JOINT_STIFFNESS_NM_RAD: Mapping[str, tuple[float, ...]] = _TrueStiffness()


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

    def cartesian_compliance(self, J: np.ndarray) -> np.ndarray:
        """C = J Kq^-1 J^T (6x6), the Cartesian compliance at the pose of ``J`` (eq. 19)."""
        return (J * self.compliance_rad_Nm) @ J.T


def true_joint_compliance(robot_name: str) -> JointCompliance:
    """The simulator's hidden joint stiffness for a robot model."""
    return JointCompliance(registry.arm(robot_name).stiffness_Nm_rad)
