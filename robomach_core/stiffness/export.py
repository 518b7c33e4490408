"""Compensated robtargets in a RAPID program, for users who compensate offline.

The targets are corrected for the predicted process wrench (``compensate_targets``) and handed
to the project's RAPID exporter; the header names the mode and the model so the program says
which correction it carries.
"""

from __future__ import annotations

import numpy as np

from ..cell import JointCompliance, Robot, Tool
from ..export.rapid import RapidProgram, RapidTarget, RapidTool, RapidWorkObject
from .compensation import compensate_targets_and_joints
from .modes import OfflineModel


def compensated_rapid_program(
    robot: Robot,
    tool: Tool,
    Ts_base_target: np.ndarray,
    joints: np.ndarray,
    wrenches: np.ndarray,
    model: JointCompliance,
    mode: OfflineModel,
    *,
    speed_mm_s: float,
    module_name: str = "CompensatedPath",
) -> RapidProgram:
    """A RAPID program whose robtargets are corrected for the predicted wrenches.

    Args:
        Ts_base_target: (n, 4, 4) programmed poses in the base frame (the work object is the
            base frame).
        joints: (n, 6) nominal joints of the targets.
        wrenches: (n, 6) predicted process wrenches at the TCP, base axes [N, N*m].
        mode: ``"linear"`` or ``"nonlinear"`` (eq. 32).
        speed_mm_s: Feed speed of the moves.
    """
    Ts, qs = compensate_targets_and_joints(robot, Ts_base_target, joints, wrenches, model, mode)
    targets = tuple(RapidTarget(T, q, speed_mm_s) for T, q in zip(Ts, qs, strict=True))
    stiffness = ", ".join(f"{k:.4g}" for k in model.stiffness_Nm_rad)
    return RapidProgram(
        module_name=module_name,
        tool=RapidTool(tool.name, tool.T_flange_tcp, tool.mass_kg, np.asarray(tool.com_m)),
        wobj=RapidWorkObject("wobj_base", np.eye(4)),
        targets=targets,
        comment=(
            f"robomach deflection compensation: {mode} target correction",
            f"joint stiffness [N*m/rad]: {stiffness}",
        ),
    )
