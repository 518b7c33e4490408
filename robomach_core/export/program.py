"""From learned targets to a RAPID program (``rapid_program``)."""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np

from ..cell import Tool
from ..part import Workpiece
from ..postprocess import Move, Targets
from ..transforms import (
    inverse_transform,
    make_transform,
    matrix_from_quaternion,
)
from .rapid import (
    ForceControlSettings,
    RapidProgram,
    RapidTarget,
    RapidTool,
    RapidWorkObject,
    SpeedChangeSettings,
)


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
