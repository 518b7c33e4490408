"""The check that a written program's motion targets are reachable: its poses read back from
the text (``ProgramLanguage.read_poses``) against the targets whose joints were solved for it."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..cell import Robot
from ..errors import RobomachError
from ..part import Workpiece
from ..postprocess import Targets
from ..transforms import matrices_from_quaternions, rotation_log
from .languages import language as language_named


@dataclass(frozen=True)
class ReachabilityReport:
    """Inverse kinematics of every robtarget of a module.

    Attributes:
        total: Number of robtargets.
        reachable: Number with an IK solution inside the joint limits.
        failures: (name, reason) of each unreachable target.
    """

    total: int
    reachable: int
    failures: tuple[tuple[str, str], ...]


# A pose read back from a written program is one of the program's targets when it lies this
# close to it (the text rounds positions to 1 um and quaternions to 1e-6).
SAME_POSE_M = 1e-5
SAME_POSE_RAD = 1e-4


def check_program_reachability(
    files: dict[str, str],
    language: str,
    robot: Robot,
    workpiece: Workpiece,
    targets: Targets,
) -> ReachabilityReport:
    """Read the motion targets back from a written program (``ProgramLanguage.read_poses``:
    the checker of its language parses them) and check the arm reaches each: a pose that is
    one of ``targets`` (within the text's rounding) is reached by that target's joints, solved
    for the program (``target_joints``); any other pose is solved here, seeded from the
    nearest target's joints."""
    lang = language_named(language)
    names = lang.file_names()
    if lang.read_poses is None or not all(name in files for name in names):
        return ReachabilityReport(0, 0, ())
    poses = lang.read_poses(tuple(files[name] for name in names), workpiece)
    P = np.asarray(targets.position_m, dtype=float)
    Rs = matrices_from_quaternions(np.asarray(targets.quaternion_wxyz, dtype=float))
    failures = []
    for name, T_base in poses:
        k = int(np.argmin(np.linalg.norm(P - T_base[:3, 3], axis=1)))
        same = (
            float(np.linalg.norm(P[k] - T_base[:3, 3])) <= SAME_POSE_M
            and float(np.linalg.norm(rotation_log(Rs[k].T @ T_base[:3, :3]))) <= SAME_POSE_RAD
        )
        if same:
            continue
        try:
            robot.ik(T_base, targets.joints_rad[k])
        except RobomachError as exc:
            failures.append((name, str(exc)))
    total = len(poses)
    return ReachabilityReport(total, total - len(failures), tuple(failures))
