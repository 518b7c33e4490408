"""From learned targets to a RAPID program, and the check that every target is reachable."""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from ..arcs import Move
from ..errors import RobomachError
from ..postprocess import Targets
from ..robot import Robot
from ..tool import Tool
from ..transforms import inverse_transform, make_transform, matrix_from_quaternion
from ..workpiece import Workpiece
from .rapid import (
    ForceControlSettings,
    RapidProgram,
    RapidTarget,
    RapidTool,
    RapidWorkObject,
    SpeedChangeSettings,
)
from .rapid_check import check_rapid_module


def rapid_program(
    targets: Targets,
    tool: Tool,
    workpiece: Workpiece,
    *,
    module_name: str = "LearnedPath",
    force_control_N: float | None = None,
    speed_change: SpeedChangeSettings | None = None,
    comment: tuple[str, ...] = (),
    arm: str | None = None,
    moves: Sequence[Move] | None = None,
) -> RapidProgram:
    """A RAPID program: one robtarget per target, in the work-object frame.

    Args:
        force_control_N: When given, the Force Control variant pressing with this force along
            the tool's Y axis (the learned contact direction) is generated.
        arm: ABB arm whose geometry gives the confdata's cfx (``RapidProgram.arm``).
        moves: Move sequence with circular moves (``arcs.arc_targets``); None: MoveL to each.
    """
    T_wobj_base = inverse_transform(workpiece.T_base_wobj)
    rapid_targets = []
    for p, q, joints, v in zip(
        targets.position_m,
        targets.quaternion_wxyz,
        targets.joints_rad,
        targets.speed_m_s,
        strict=True,
    ):
        T_base_target = make_transform(matrix_from_quaternion(q), p)
        rapid_targets.append(RapidTarget(T_wobj_base @ T_base_target, joints, float(v) * 1e3))
    fc = ForceControlSettings(force_N=force_control_N) if force_control_N else None
    return RapidProgram(
        module_name=module_name,
        tool=RapidTool(tool.name, tool.T_flange_tcp, tool.mass_kg, np.asarray(tool.com_m)),
        wobj=RapidWorkObject("wobj_" + workpiece.name, workpiece.T_base_wobj),
        targets=tuple(rapid_targets),
        force_control=fc,
        speed_change=speed_change,
        comment=comment,
        arm=arm,
        moves=moves,
    )


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


def check_reachability(
    module_text: str, robot: Robot, workpiece: Workpiece, joints_hint: np.ndarray | None = None
) -> ReachabilityReport:
    """Parse the module and solve IK for each robtarget (targets in mm, in the wobj frame)."""
    info = check_rapid_module(module_text)
    failures = []
    q = joints_hint
    for name, (pos_mm, quat, _conf) in info.robtargets.items():
        T_base = workpiece.T_base_wobj @ make_transform(
            matrix_from_quaternion(quat), np.asarray(pos_mm) * 1e-3
        )
        try:
            q = robot.ik(T_base, q)
        except RobomachError as exc:
            failures.append((name, str(exc)))
    total = len(info.robtargets)
    return ReachabilityReport(total, total - len(failures), tuple(failures))


def check_program_reachability(
    files: dict[str, str],
    language: str,
    robot: Robot,
    workpiece: Workpiece,
    joints_hint: np.ndarray | None = None,
) -> ReachabilityReport:
    """Read the motion targets back from a written program (``ProgramLanguage.read_poses``:
    the checker of its language parses them) and solve the IK of each, as
    ``check_reachability`` does for a RAPID module."""
    from .languages import language as language_named

    lang = language_named(language)
    names = lang.file_names()
    if lang.read_poses is None or not all(name in files for name in names):
        return ReachabilityReport(0, 0, ())
    poses = lang.read_poses(tuple(files[name] for name in names), workpiece)
    failures = []
    q = joints_hint
    for name, T_base in poses:
        try:
            q = robot.ik(T_base, q)
        except RobomachError as exc:
            failures.append((name, str(exc)))
    total = len(poses)
    return ReachabilityReport(total, total - len(failures), tuple(failures))
