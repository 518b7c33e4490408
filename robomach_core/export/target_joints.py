"""The joints of each program target: inverse kinematics of the target pose on the chosen arm.

PROBLEM   ``Targets.joints_rad`` are the joints recorded at each target's sample, but the target
          itself was moved back to the unloaded wall (``postprocess.surface_positions``), so
          those joints reach a point 0.09-0.25 mm off the target, and the confdata and
          targets.csv written from them disagree with the robtarget.
STRATEGY  Solve the IK of every target pose, seeded from the joints recorded at its sample
          (the branch path learning was on there, axis 6 wound as far as the run wound it), so
          the program follows the arm's branch along the path as the run did; refuse a solution
          that changes the configuration (a different ABB cfx / UR branch / KUKA Status) or
          lands more than ``MAX_JOINT_STEP_RAD`` on an axis from the joints it was seeded with.
          Seeded from the previous target instead, a wrist that turns round a loop met axis 6's
          limit and the solver landed a turn away: learning and export disagreed.
SOLUTION  ``target_joints(robot, targets) -> (m, 6)`` and ``with_target_joints`` (the same
          ``Targets`` with those joints).
"""

from __future__ import annotations

from dataclasses import replace

import numpy as np

from ..cell import Robot
from ..errors import RobomachError, UnreachableTargetError
from ..postprocess import Targets
from ..transforms import make_transform, matrix_from_quaternion
from .rapid import confdata_from_joints

# Between neighbouring targets of a machining path the joints move little; a larger step means
# the solver found another branch of the inverse kinematics.
MAX_JOINT_STEP_RAD = 0.5
# Solver tolerances of the target joints (a nanometre, a nanoradian).
IK_TOLERANCE_M = 1e-9
IK_TOLERANCE_RAD = 1e-9


def target_joints(
    robot: Robot, targets: Targets, *, q_seed: np.ndarray | None = None
) -> np.ndarray:
    """Joints [rad] reaching every target pose exactly (within 1 nm and 1 nrad).

    Args:
        robot: The arm with the program's tool as its TCP.
        targets: The program's targets (base frame).
        q_seed: Seed of the first target; default its recorded joints (every other target is
            seeded from its own recorded joints).

    Returns:
        Shape (m, 6).

    Raises:
        UnreachableTargetError: a target cannot be reached on the branch of the previous one
            (the message names the target, 1-based as in the program's p1, p2, ...).
    """
    n = len(targets)
    out = np.empty((n, 6))
    seed = np.asarray(targets.joints_rad[0] if q_seed is None else q_seed, dtype=float)
    branch = configuration(robot, seed)
    recorded = np.asarray(targets.joints_rad, dtype=float)
    for k in range(n):
        T = make_transform(
            matrix_from_quaternion(targets.quaternion_wxyz[k]), targets.position_m[k]
        )
        start = seed if k == 0 else recorded[k]
        try:
            # Converged far below the CSV's 1e-5 deg, so the joints do not depend on the seed's
            # history: the CLI and the workbench write the same bytes for the same targets.
            q = robot.ik(T, start, tolerance_m=IK_TOLERANCE_M, tolerance_rad=IK_TOLERANCE_RAD)
        except RobomachError as exc:
            raise UnreachableTargetError(f"target p{k + 1}: {exc}") from None
        # Against the joints the run had at this target (its branch there), not the previous
        # target's: a wrist turning round a loop moves axis 6 far between sparse targets.
        step = float(np.max(np.abs(q - start)))
        case = configuration(robot, q)
        if step > MAX_JOINT_STEP_RAD or case != branch:
            raise UnreachableTargetError(
                f"target p{k + 1}: the inverse kinematics leaves the arm's branch "
                f"(configuration {branch} -> {case}, largest joint step "
                f"{np.degrees(step):.0f} deg)"
            )
        out[k] = q
        seed = q
    return out


def configuration(robot: Robot, joints_rad: np.ndarray) -> int:
    """The arm's configuration case as its controller names it: KUKA's Status
    (``export.krl.status_turn``), else ABB's cfx (``rapid.confdata_from_joints``; the UR
    branch in ABB's numbering for a UR arm)."""
    if robot.family == "kuka":
        from .krl import status_turn

        return status_turn(robot, joints_rad)[0]
    return confdata_from_joints(joints_rad, arm=robot.name)[3]


def with_target_joints(robot: Robot, targets: Targets) -> Targets:
    """``targets`` with ``joints_rad`` replaced by ``target_joints(robot, targets)``."""
    return replace(targets, joints_rad=target_joints(robot, targets))
