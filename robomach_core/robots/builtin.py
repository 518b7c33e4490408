"""The arms robomach builds from published kinematics, by name: their family (whose
controller, hence which program language), URDF, controller axis values and combined limits.

The UR arms come from example-robot-data (``robot.py``); the ABB arms from ``robots.abb``;
the KUKA arms from ``robots.kuka``. A user's URDF registers its own family (``robots.custom``).
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from pathlib import Path
from typing import Literal

import numpy as np

from ..errors import UnknownNameError
from . import abb, kuka

ArmFamily = Literal["ur", "abb", "kuka"]
# The language a family's controller runs natively (``export.languages`` lists every language
# and the families it serves).
FAMILY_LANGUAGE: dict[str, str] = {"ur": "urscript", "abb": "rapid", "kuka": "krl"}
# Every family a controller can belong to, for choices (CLI, upload form, schemas).
ARM_FAMILIES: tuple[str, ...] = tuple(FAMILY_LANGUAGE)
GENERATED_ARMS: tuple[str, ...] = (*abb.ABB_ARMS, *kuka.KUKA_ARMS)


@dataclass(frozen=True)
class JointCoupling:
    """A limit on a combination of joints: lower <= coefficients . q <= upper [rad].

    Attributes:
        coefficients: (6,) weights of the joints.
        lower_rad, upper_rad: The range of the combination.
        axis: The controller axis (1-based) whose value the combination is.
        description: What it is, for messages ("axis 3 from the horizontal (axes 2 + 3)").
    """

    coefficients: tuple[float, ...]
    lower_rad: float
    upper_rad: float
    axis: int
    description: str

    def value(self, joints_rad: np.ndarray) -> float:
        """The combination at ``joints_rad`` [rad]."""
        return float(np.dot(self.coefficients, joints_rad))

    def margin(self, joints_rad: np.ndarray) -> float:
        """Distance to the nearer end of the range [rad]; negative outside it."""
        v = self.value(joints_rad)
        return min(v - self.lower_rad, self.upper_rad - v)


def generated_urdf_text(name: str) -> str:
    """The URDF text of an ABB or KUKA arm built here."""
    key = name.lower()
    if key in abb.ABB_ARMS:
        return abb.urdf_text(abb.ABB_ARMS[key])
    if key in kuka.KUKA_ARMS:
        return kuka.urdf_text(kuka.KUKA_ARMS[key])
    raise UnknownNameError(f"no generated arm {name!r}; known: {', '.join(GENERATED_ARMS)}")


def generated_urdf_path(name: str) -> Path:
    """The URDF file of an ABB or KUKA arm built here (written at first use)."""
    key = name.lower()
    if key in abb.ABB_ARMS:
        return abb.urdf_path(key)
    if key in kuka.KUKA_ARMS:
        return kuka.urdf_path(key)
    raise UnknownNameError(f"no generated arm {name!r}; known: {', '.join(GENERATED_ARMS)}")


def controller_axes_deg(name: str, joints_rad: np.ndarray) -> np.ndarray:
    """The axis values [deg] the arm's controller shows for model joints ``joints_rad``:
    ABB's coupled axis 3 on parallel-bar arms, the model's joints otherwise (KUKA's A1-A6 and
    UR's joints are the model's)."""
    key = name.lower()
    if key in abb.ABB_ARMS:
        return abb.controller_axes_deg(key, joints_rad)
    return np.degrees(np.asarray(joints_rad, dtype=float))


def joint_couplings(name: str) -> tuple[JointCoupling, ...]:
    """The combined limits of an arm: on a parallel-bar ABB arm, ABB's axis-3 range on the
    controller's axis 3 = q2 + q3 (``abb.ArmSpec.axis3_from_horizontal_deg``); none else."""
    spec = abb.ABB_ARMS.get(name.lower())
    if spec is None or spec.axis3_from_horizontal_deg is None:
        return ()
    lo, hi = spec.axis3_from_horizontal_deg
    return (
        JointCoupling(
            (0.0, 1.0, 1.0, 0.0, 0.0, 0.0),
            math.radians(lo),
            math.radians(hi),
            3,
            "axis 3 from the horizontal (axes 2 + 3 combined)",
        ),
    )


def within_couplings(couplings: tuple[JointCoupling, ...], joints_rad: np.ndarray) -> bool:
    """True when every combined limit holds (1e-9 rad of slack, as ``Robot.within_limits``)."""
    return all(c.margin(joints_rad) >= -1e-9 for c in couplings)


def project_couplings(
    couplings: tuple[JointCoupling, ...],
    joints_rad: np.ndarray,
    lower_rad: np.ndarray,
    upper_rad: np.ndarray,
) -> np.ndarray:
    """The joints moved the least (in the least-squares sense) into every combined limit and
    the box limits: alternating projections, exact for one coupling on joints inside the box."""
    q = np.asarray(joints_rad, dtype=float).copy()
    for _ in range(4):
        changed = False
        for c in couplings:
            a = np.asarray(c.coefficients)
            v = float(a @ q)
            target = min(max(v, c.lower_rad), c.upper_rad)
            if target != v:
                q += (target - v) / float(a @ a) * a
                changed = True
        if not changed:
            break
        q = np.minimum(np.maximum(q, lower_rad), upper_rad)
    return q
