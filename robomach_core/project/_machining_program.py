"""What the exported program carries of the machining choice: its feeds, its header lines, a UR
program's feed loop and the offline-corrected program (``_writers`` reads these)."""

from __future__ import annotations

from dataclasses import replace
from typing import Any

import numpy as np

from ..cell import Robot
from ..part import Workpiece
from ..postprocess import Targets
from ._machining import (
    MachiningResult,
    MachiningSetup,
    _designed_settings,
    capabilities_of,
    chosen_feed,
    machining_setup_of,
    planned_schedule,
)
from ._machining_cut import build_stock, wall_normals_for_project, with_move_speeds
from ._stages import require_processed
from ._value import Project

MM = 1e-3
# How each family's program carries the force-driven feed override.
FEED_OVERRIDE_MEANS = {
    "abb": "FC SpeedChange (FCSpdChgAct in the RAPID module)",
    "ur": "the URScript program runs its own loop on the UR's force/torque sensor (the RAPID "
    "module carries FC SpeedChange for an ABB controller)",
}


def machining_targets(
    project: Project, targets: Targets, workpiece: Workpiece | None = None
) -> Targets | None:
    """``targets`` with the feeds the chosen machining configuration commands
    (``machining.program.machining_program``: the learned speeds capped at Vr, at the constant
    feed the stock allows for ``constant``, rounded down to 0.01 mm/s) and the positions as
    the files write them (``as_written``): the program the simulation cut; None when the
    project holds no machining settings."""
    if not isinstance(project.machining_settings, MachiningSetup):
        return None
    from ..machining.program import as_written, design_depth_m, machining_program

    s = machining_setup_of(project).settings
    targets = with_move_speeds(targets, require_processed(project).moves)
    if workpiece is None:
        from ._stages import build_workpiece

        workpiece = build_workpiece(project.cell, project.mesh)
    depth = s.design_depth_m
    if depth is None and s.controller == "constant" and s.constant_feed_m_s is None:
        processed = require_processed(project).result.targets
        normals = wall_normals_for_project(project, workpiece, processed)
        depth = build_stock(project, workpiece, processed, normals).max_allowance_m
    program = machining_program(targets, s, design_depth_m=design_depth_m(s, depth or 0.0))
    return as_written(program, workpiece.T_base_wobj)


def feed_note(project: Project, targets: Targets) -> str:
    """The header's line on the feeds the program commands."""
    s = machining_setup_of(project).settings
    v = np.asarray(targets.speed_m_s, dtype=float) / MM
    if planned_schedule(project):
        return (
            f"feeds as simulated: {v.min():.2f}-{v.max():.2f} mm/s per move, the {s.controller} "
            f"stage schedule planned offline (the lowest stage its cuts of the nominal wall ran "
            f"at each 0.1 mm, times the learned speed, at most {s.command_speed_cap_m_s / MM:g} "
            "mm/s); no online feed control: the program runs these speeds as written"
        )
    if s.controller == "constant":
        return (
            f"feeds as simulated: constant {v.max():.2f} mm/s (the greatest that keeps the "
            f"{s.force_limit_N:g} N limit at the stock's deepest cut), slower where learned"
            if v.min() < v.max()
            else f"feeds as simulated: constant {v.max():.2f} mm/s (the greatest that keeps "
            f"the {s.force_limit_N:g} N limit at the stock's deepest cut)"
        )
    return (
        f"feeds as simulated: programmed {v.min():.2f}-{v.max():.2f} mm/s (learned, at most "
        f"{s.command_speed_cap_m_s / MM:g} mm/s), scaled by the {s.controller} feed control "
        f"holding {s.reference_N:g} N"
    )


def ur_feed_loop(project: Project, workpiece: Workpiece, robot: Robot, targets: Targets) -> Any:
    """The feed loop a UR program runs for the chosen CMRR controller
    (``export.urscript_feed``): the controller as the simulation designed it for this program
    on this stock, its filter and the path acceleration; None for constant feed. Without
    machining settings, the defaults' (``machining_setup_of``) with the project's CMRR: a UR
    program of a project with CMRR settings said "CMRR: two-stage" in its header and ran plain
    moves at the learned feeds."""
    if project.cmrr is None and not isinstance(project.machining_settings, MachiningSetup):
        return None
    s = machining_setup_of(project).settings
    if s.controller == "constant" or planned_schedule(project):
        return None  # no feed control: the constant feed, or a stage schedule as the speeds
    import copy

    from ..export.urscript_feed import UrFeedLoop
    from ..machining.run import FORCE_SUPERVISION_FACTOR, plan_cut

    processed = require_processed(project).result.targets
    normals = wall_normals_for_project(project, workpiece, processed)
    stock = build_stock(project, workpiece, processed, normals)
    designed = _designed_settings(project, s.controller)
    if s.controller_settings is None and designed is not None:
        s = replace(s, controller_settings=designed)
    plan = plan_cut(robot, targets, None, stock, replace(s, compensation="off"))
    if plan.packed is NotImplemented:
        return None
    i = plan.inputs
    return UrFeedLoop(
        controller=s.controller,
        reference_N=s.reference_N,
        packed=copy.deepcopy(plan.packed),
        filter_sos=tuple(float(v) for v in i.filt),
        filter_z0=(float(i.filt_z[0]), float(i.filt_z[1])),
        dt_s=i.dt,
        acceleration_m_s2=s.path_acceleration_m_s2,
        force_limit_N=s.force_limit_N,
        supervision_factor=FORCE_SUPERVISION_FACTOR,
    )


def chosen_program(project: Project) -> tuple[Targets, str] | None:
    """The corrected program of the chosen offline-compensated run, when the project's machining
    result holds it and is current; else None (``program_targets`` falls back)."""
    result = project.machining
    if not isinstance(project.machining_settings, MachiningSetup) or not isinstance(
        result, MachiningResult
    ):
        return None
    s = machining_setup_of(project).settings
    if s.compensation != "offline" or project.status()["machining"] != "current":
        return None
    program = result.programs.get(f"{s.controller}/{s.compensation}")
    if program is None:
        return None
    nominal = require_processed(project).result.targets
    cut = (
        f"its stage schedule's cut (planned from {s.controller} cuts of the nominal wall)"
        if planned_schedule(project)
        else f"the {s.controller} cut"
    )
    return program, (
        f"deflection compensation: offline, planned from rehearsals of {cut} on the stock, "
        f"{len(program)} targets from {len(nominal)}"
    )


def machining_note(project: Project) -> str | None:
    """The program header's line on the chosen configuration: what it needs from the cell
    and whether the cell (``capabilities_of``) has it; None without machining settings."""
    from ..machining.choice import missing, needs_text, requirements

    if not isinstance(project.machining_settings, MachiningSetup):
        return None
    s = machining_setup_of(project).settings
    caps = capabilities_of(project)
    feed = chosen_feed(project)
    needs = requirements(s.controller, s.compensation, feed)
    lacks = set(missing(s.controller, s.compensation, caps, feed))
    head = f"machining: {s.controller} / {s.compensation}"
    if feed == "program":
        head += " (the stage schedule planned offline as the program's speeds)"
    if not needs:
        return f"{head}; needs nothing from the cell beyond this program"
    parts = []
    for r in needs:
        if r in lacks:
            parts.append(f"{needs_text(r, caps)} (MISSING in this cell)")
        elif r == "feed_override" and caps.family in FEED_OVERRIDE_MEANS:
            means = FEED_OVERRIDE_MEANS[caps.family]
            parts.append(f"a force-driven feed override: {means} (the cell has it)")
        else:
            parts.append(f"{needs_text(r, caps)} (the cell has it)")
    return f"{head}; the cell must provide " + " and ".join(parts)
