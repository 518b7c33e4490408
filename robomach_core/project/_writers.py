"""The one writer set: the targets the program runs, RAPID header and modules, program files,
settings.json."""

from __future__ import annotations

import json
from dataclasses import replace
from typing import TYPE_CHECKING, Any

import numpy as np

from ..cell import Robot
from ..errors import InvalidInputError
from ..learning.run import Recording
from ..part import Workpiece
from ..postprocess import Targets
from ._machining import compensation_for_arm, stale_settings
from ._machining_program import chosen_program, feed_note, machining_targets, ur_feed_loop
from ._stages import require_learned, require_processed
from ._value import (
    DEFAULT_MODULE_NAME,
    MissingResultError,
    Project,
    cmrr_document,
    compensation_document,
)

if TYPE_CHECKING:  # for the annotation; the functions import the registry when they run
    from ..export.languages import ProgramContext


def rapid_header(
    project: Project,
    workpiece_name: str,
    *,
    note: str | None = None,
    cmrr_in_program: bool = True,
) -> tuple[str, ...]:
    """The program's comment lines: cell, learning, reduction, CMRR and compensation; first, a
    banner for each problem that makes the program unfit to machine with (a partial run, the
    wrong wall, an overcut: ``ProcessedPath.problems``). ``cmrr_in_program`` False: the
    language carries no feed control, and the CMRR line says so instead of naming it."""
    c = project.cell
    processed = require_processed(project)
    learned = require_learned(project)
    learning = learned.settings
    lines = [f"NOT FIT TO MACHINE: {problem}" for problem in processed.problems()]
    if not learned.recording.completed:
        lines.append(f"path learning stopped: {learned.recording.stop_reason}")
    lines += [
        f"robomach: {c.robot}, {workpiece_name}, tool radius {c.tool_radius_m * 1e3:g} mm, "
        f"seed {c.seed}",
        f"path learning: force {learning.force_N:g} N, speed {learning.speed_m_s * 1e3:g} mm/s, "
        f"{len(project.guide_points)} guide points",
        f"{len(processed.result.targets)} targets from {processed.samples_raw} samples "
        f"({processed.result.samples_filtered} kept by the force filter), tolerance "
        f"{processed.settings.tolerance_m * 1e3:g} mm",
    ]
    from ._machining import planned_schedule

    if project.cmrr is not None:
        cmrr = (
            f"CMRR: {project.cmrr.controller.kind}, reference {project.cmrr.reference_force_N:g} N"
        )
        if planned_schedule(project):
            cmrr += (
                ", planned offline: its stages are this program's speeds (no online feed "
                "control; the cell's force supervision as for any program)"
            )
        elif not cmrr_in_program:
            cmrr += (
                " is NOT in this program: it has no force-driven feed override (its feeds are "
                "constant per move); the position-controlled RAPID or URScript program has it"
            )
        lines.append(cmrr)
    if note is not None:
        lines.append(note)
    from ._machining_program import (
        machining_note,
    )  # what the chosen configuration needs from the cell

    needs = machining_note(project)
    if needs is not None:
        lines.append(needs)
    return tuple(lines)


FEEDLESS = ("krl",)  # languages robomach writes no force-driven feed control for


def fc_module_name(module_name: str) -> str:
    """The Force Control variant's module name (RAPID names are at most 32 characters)."""
    return module_name[:30] + "FC"


def program_targets(
    project: Project,
    robot: Robot,
    *,
    solved: Targets | None = None,
    workpiece: Workpiece | None = None,
) -> tuple[Targets, str | None]:
    """The targets the program runs: post-processed, their joints the inverse kinematics of
    each target pose on ``robot`` (``export.target_joints``; ``solved`` when the caller has
    them), with the feeds the chosen machining configuration commands (``machining_targets``,
    when the project holds machining settings), corrected for deflection in the offline
    compensation modes; and the notes for the header (None without)."""
    from ..export.target_joints import with_target_joints

    processed = require_processed(project)
    targets = solved if solved is not None else with_target_joints(robot, processed.result.targets)
    chosen = chosen_program(project)
    if chosen is not None:  # offline compensation chosen from a current machining run
        program, note = chosen
        return program, f"{note}; {feed_note(project, program)}"
    machined = machining_targets(project, targets, workpiece)
    feeds = None
    if machined is not None:
        targets = machined
        feeds = feed_note(project, targets)
    if project.compensation is None:
        return targets, feeds
    compensation = compensation_for_arm(project, robot.name)  # settings of another arm: re-derived
    corrected, note = compensate_program_targets(
        robot, require_learned(project).recording, targets, compensation
    )
    stale = stale_settings(project).get("compensation")
    if stale is not None and compensation is not project.compensation:
        note = f"{note}; {stale}"
    return corrected, note if feeds is None else f"{note}; {feeds}"


def compensate_program_targets(
    robot: Robot, recording: Recording, targets: Targets, compensation: Any
) -> tuple[Targets, str]:
    """Targets corrected for the contact wrench learned at each one (offline modes), and a note.

    The process wrench the program will meet is the one measured while learning it (the
    compensated tool-frame wrench at each target's sample, turned into base axes). Online
    compensation happens in the controller at run time, so it leaves the targets as they are.
    """
    from ..stiffness import compensate_targets_and_joints
    from ..transforms import make_transform, matrix_from_quaternion, quaternions_from_matrices

    if compensation.robot != robot.name:
        raise InvalidInputError(
            f"the compensation settings were identified on {compensation.robot}, "
            f"the cell has {robot.name}"
        )
    if compensation.mode != "offline":
        return targets, f"deflection compensation: {compensation.mode} (targets as learned)"
    Ts = np.array(
        [
            make_transform(matrix_from_quaternion(q), p)
            for p, q in zip(targets.position_m, targets.quaternion_wxyz, strict=True)
        ]
    )
    wrenches = np.empty((len(targets), 6))
    for k, i in enumerate(targets.sample_index):
        R = matrix_from_quaternion(recording.quaternion_wxyz[i])
        wrenches[k, :3] = R @ recording.wrench_tool[i, :3]
        wrenches[k, 3:] = R @ recording.wrench_tool[i, 3:]
    Ts_c, q_c = compensate_targets_and_joints(
        robot, Ts, targets.joints_rad, wrenches, compensation.model, compensation.offline_model
    )
    corrected = replace(
        targets,
        position_m=Ts_c[:, :3, 3].copy(),
        quaternion_wxyz=quaternions_from_matrices(Ts_c[:, :3, :3]),
        joints_rad=np.asarray(q_c),
    )
    shift = np.linalg.norm(corrected.position_m - targets.position_m, axis=1).max()
    return corrected, (
        f"deflection compensation: offline ({compensation.offline_model}), largest target "
        "correction "
        f"{shift * 1e3:.4f} mm"
    )


def program_context(
    project: Project,
    workpiece: Workpiece,
    robot: Robot,
    *,
    module_name: str = DEFAULT_MODULE_NAME,
    force_control: bool = False,
    program: tuple[Targets, str | None] | None = None,
    language: str | None = None,
) -> ProgramContext:
    """The ``export.languages.ProgramContext`` of the project's program: its targets
    (``program``, else ``program_targets``: IK joints, compensated in the offline modes), the
    header, the moves, the CMRR speed change (position-controlled program) or the learning
    force (``force_control``); ``language``: the one it is written in (KRL carries no CMRR,
    and its header says so)."""
    from ..export.languages import ProgramContext

    processed = require_processed(project)
    targets, note = (
        program if program is not None else program_targets(project, robot, workpiece=workpiece)
    )
    from ._machining import planned_schedule

    speed_change = feed_loop = None
    # A stage schedule planned offline is the program's speeds: no feed control to carry.
    if project.cmrr is not None and not force_control and not planned_schedule(project):
        from ..cmrr import to_speed_change_settings

        speed_change = to_speed_change_settings(project.cmrr)
        if robot.family == "ur":  # the feed loop its URScript program runs
            feed_loop = ur_feed_loop(project, workpiece, robot, targets)
    return ProgramContext(
        targets=targets,
        tool=project.tool(),
        workpiece=workpiece,
        robot=robot,
        moves=processed.moves,
        comment=rapid_header(
            project,
            workpiece.name,
            note=note,
            cmrr_in_program=not (
                force_control
                or language in FEEDLESS
                or (language == "urscript" and feed_loop is None)
            ),
        ),
        module_name=module_name,
        force_control_N=require_learned(project).settings.force_N if force_control else None,
        speed_change=speed_change,
        feed_loop=feed_loop,
    )


def program_texts(
    project: Project,
    workpiece: Workpiece,
    robot: Robot,
    language: str,
    *,
    module_name: str = DEFAULT_MODULE_NAME,
    force_control: bool = False,
    program: tuple[Targets, str | None] | None = None,
) -> dict[str, str]:
    """One program of the project in a registered language (``export.languages``): file
    name -> text (``program.mod``; ``program.src`` and ``program.dat``; ``program_fc.*`` for
    the force-controlled variant); ``program`` the ``program_targets`` when already solved.

    Raises:
        StaleResultError: the post-processing is missing or out of date.
        UnknownNameError: no such language.
        InvalidInputError: the language has no force-controlled variant and one is asked for.
    """
    from ..errors import InvalidInputError
    from ..export.languages import language as language_named

    require_processed(project)
    lang = language_named(language)
    if force_control and not lang.force_control:
        raise InvalidInputError(f"{lang.title} programs have no force-controlled variant here")
    if force_control and module_name == DEFAULT_MODULE_NAME:
        module_name = fc_module_name(module_name)
    context = program_context(
        project, workpiece, robot, module_name=module_name, force_control=force_control,
        program=program, language=lang.name,
    )  # fmt: skip
    texts = lang.write(context)
    return dict(zip(lang.file_names(force_control=force_control), texts, strict=True))


CAD_ONLY_MODULE_NAME = "CadOnlyPath"


def cad_only_targets(project: Project, robot: Robot) -> Targets:
    """The CAD-only program's targets (``cad_program``: the mesh's wall offset by the tool
    radius, reduced with the same tolerance, placed with the nominal work object): each with
    the learned orientation, feed and arm branch of the learned target nearest it, and its
    own inverse kinematics (``export.target_joints``).

    Raises:
        StaleResultError: the post-processing is missing or out of date.
        MissingResultError: the learned path follows no wall of the mesh (no CAD-only program).
    """
    from ..export.target_joints import with_target_joints

    processed = require_processed(project)
    comparison = processed.cad_comparison
    if comparison is None:
        raise MissingResultError(
            "no CAD-only program: the learned path follows no wall of the part's mesh"
        )
    learned = processed.result.targets
    positions = np.asarray(comparison.cad_positions_m, dtype=float)
    nearest = np.array(
        [int(np.argmin(np.linalg.norm(learned.position_m - p, axis=1))) for p in positions]
    )
    targets = Targets(
        position_m=positions,
        quaternion_wxyz=np.asarray(comparison.cad_quaternions_wxyz, dtype=float),
        joints_rad=learned.joints_rad[nearest],
        speed_m_s=learned.speed_m_s[nearest],
        curvature_1_m=learned.curvature_1_m[nearest],
        sample_index=learned.sample_index[nearest],
    )
    return with_target_joints(robot, targets)


def cad_only_program_texts(
    project: Project,
    workpiece: Workpiece,
    robot: Robot,
    language: str,
    *,
    module_name: str = CAD_ONLY_MODULE_NAME,
) -> dict[str, str]:
    """The CAD-only program (``cad_only_targets``) in a registered language: file name ->
    text. A position-controlled program of straight moves, its header saying what it is and
    how far both programs are from the (real) wall: the baseline learning is measured
    against, not the program to machine with."""
    from ..export.languages import ProgramContext
    from ..export.languages import language as language_named

    processed = require_processed(project)
    comparison = processed.cad_comparison
    lang = language_named(language)
    targets = cad_only_targets(project, robot)
    assert comparison is not None  # cad_only_targets refuses a project without one
    wall = "the real wall" if comparison.part_deviates else "the wall"
    c = project.cell
    comment = (
        "CAD-ONLY PROGRAM: planned from the mesh alone (the wall offset by the tool radius), "
        "not learned; for comparison with the learned program",
        f"against {wall}: max {comparison.cad_only.max_m * 1e3:.3f} mm, overcut "
        f"{comparison.cad_only.overcut_m * 1e3:.3f} mm (the learned program: max "
        f"{comparison.learned.max_m * 1e3:.3f} mm)",
        f"robomach: {c.robot}, {workpiece.name}, tool radius {c.tool_radius_m * 1e3:g} mm, "
        f"{len(targets)} targets, tolerance {processed.settings.tolerance_m * 1e3:g} mm, feeds "
        "of the nearest learned targets",
    )
    context = ProgramContext(
        targets=targets,
        tool=project.tool(),
        workpiece=workpiece,
        robot=robot,
        moves=None,
        comment=comment,
        module_name=module_name,
    )
    return dict(zip(lang.file_names(), lang.write(context), strict=True))


def rapid_text(
    project: Project,
    workpiece: Workpiece,
    robot: Robot,
    *,
    module_name: str = DEFAULT_MODULE_NAME,
    force_control: bool = False,
) -> str:
    """One RAPID module of the project's program.

    The position-controlled program carries the FC SpeedChange block when a CMRR controller
    is chosen; ``force_control`` gives the FCPressL variant pressing at the learning force
    instead. Both use the compensated targets in the offline compensation modes.
    """
    texts = program_texts(
        project, workpiece, robot, "rapid", module_name=module_name, force_control=force_control
    )
    return next(iter(texts.values()))


def program_languages(robot: Robot, language: str = "auto") -> tuple[str, ...]:
    """The program languages to write (``export.languages.resolve_languages``): ``auto``,
    every language the arm's controller is offered (UR: RAPID and URScript; ABB: RAPID; KUKA:
    KRL); a language's name, that one if the arm's controller runs it."""
    from ..export.languages import resolve_languages

    return tuple(lang.name for lang in resolve_languages(robot, language))


def program_files(
    project: Project,
    workpiece: Workpiece,
    robot: Robot,
    *,
    module_name: str = DEFAULT_MODULE_NAME,
    project_name: str | None = None,
    compliance: dict[str, Any] | None = None,
    language: str = "auto",
) -> dict[str, str]:
    """The program's files (the one writer set of the CLI and the workbench): for every
    language of ``program_languages`` its program and, where it has one, its force-controlled
    variant (program.mod and program_fc.mod; program.script and program_fc.script;
    program.src and program.dat), then targets.csv, samples.csv and settings.json."""
    return program_export(
        project, workpiece, robot, module_name=module_name, project_name=project_name,
        compliance=compliance, language=language,
    )[0]  # fmt: skip


def program_export(
    project: Project,
    workpiece: Workpiece,
    robot: Robot,
    *,
    module_name: str = DEFAULT_MODULE_NAME,
    project_name: str | None = None,
    compliance: dict[str, Any] | None = None,
    language: str = "auto",
) -> tuple[dict[str, str], Targets]:
    """``program_files`` and the targets its programs run: the targets' inverse kinematics is
    solved once (``export.target_joints``) for every program, its variants and targets.csv."""
    from ..export.languages import language as language_named
    from ..export.tables import samples_csv, targets_csv
    from ..export.target_joints import with_target_joints

    processed = require_processed(project)
    languages = program_languages(robot, language)
    doc = settings_document(project, workpiece, project_name=project_name, compliance=compliance)
    solved = with_target_joints(robot, processed.result.targets)
    program = program_targets(project, robot, solved=solved, workpiece=workpiece)
    files: dict[str, str] = {}
    for name in languages:
        files |= program_texts(
            project, workpiece, robot, name, module_name=module_name, program=program
        )
        if language_named(name).force_control:
            files |= program_texts(
                project, workpiece, robot, name, module_name=fc_module_name(module_name),
                force_control=True, program=program,
            )  # fmt: skip
    files |= {
        "targets.csv": targets_csv(solved),
        "samples.csv": samples_csv(require_learned(project).recording, processed.result.keep_mask),
        "settings.json": json.dumps(doc, indent=2) + "\n",
    }
    return files, program[0]


def targets_text(project: Project, robot: Robot) -> str:
    """targets.csv: the post-processed targets (mm, degrees, mm/s), their joints the inverse
    kinematics of each target pose on ``robot`` (the joints the program's confdata is read
    from)."""
    from ..export.tables import targets_csv
    from ..export.target_joints import with_target_joints

    return targets_csv(with_target_joints(robot, require_processed(project).result.targets))


def settings_document(
    project: Project,
    workpiece: Workpiece,
    *,
    project_name: str | None = None,
    compliance: dict[str, Any] | None = None,
) -> dict[str, Any]:
    """Every setting that shaped the program, for settings.json (mm, N, s at the boundary).

    Top-level ``robot``, ``workpiece``, ``T_base_wobj_mm`` and ``tool`` keep the layout the CLI
    wrote before; ``cell`` is the workbench's; ``status`` says which results are out of date.
    """
    c, post = project.cell, project.post_settings
    tool = project.tool()
    learned, processed = project.learned, project.processed
    doc: dict[str, Any] = {
        "project": project_name,
        "robot": c.robot,
        "workpiece": workpiece.name,
        "T_base_wobj_mm": [
            [round(float(v) * (1e3 if j == 3 and i < 3 else 1.0), 6) for j, v in enumerate(row)]
            for i, row in enumerate(workpiece.T_base_wobj)
        ],
        "cell": {
            "robot": c.robot,
            "tool_radius_mm": c.tool_radius_m * 1e3,
            "workpiece": c.workpiece,
            "workpiece_builtin": c.workpiece_builtin,
            "seed": c.seed,
            "wobj_mm_deg": None if c.wobj_mm_deg is None else list(c.wobj_mm_deg),
            "part_deviation": None if c.part_deviation is None else c.part_deviation.as_dict(),
            "registration": None if c.registration is None else c.registration.document(),
        },
        "tool": {
            "name": tool.name,
            "tcp_offset_mm": [v * 1e3 for v in tool.tcp_offset_m],
            "mass_kg": tool.mass_kg,
            "com_mm": [v * 1e3 for v in tool.com_m],
            "shape": tool.shape,
            "radius_mm": tool.radius_m * 1e3,
        },
        "compliance": compliance,
        "guide_points": len(project.guide_points),
        "path_learning": None
        if learned is None
        else {
            "force_N": learned.settings.force_N,
            "speed_mm_s": learned.settings.speed_m_s * 1e3,
            "closed": learned.settings.closed,
            "wall_side": learned.settings.wall_side,
            "force_limit_N": learned.settings.force_limit_N,
            "seed": c.seed,
        },
        "postprocess": {
            "force_min_N": post.force_min_N,
            "force_max_N": post.force_max_N,
            "tolerance_mm": post.tolerance_m * 1e3,
            "speed_mean_mm_s": post.speed_mean_m_s * 1e3,
            "speed_min_mm_s": post.speed_min_m_s * 1e3,
            "contact_stiffness_N_mm": post.contact_stiffness_N_m * 1e-3,
            "arcs": post.arcs,
            "arc_tolerance_mm": None
            if post.arc_tolerance_m is None
            else post.arc_tolerance_m * 1e3,
        },
        "result": None
        if processed is None
        else {
            "samples_raw": processed.samples_raw,
            "samples_filtered": processed.result.samples_filtered,
            "targets": len(processed.result.targets),
            "max_deviation_mm": None if processed.score is None else processed.score.max_m * 1e3,
            "rms_deviation_mm": None if processed.score is None else processed.score.rms_m * 1e3,
            **result_extras(processed),
        },
        "cmrr": cmrr_document(project),
        "compensation": compensation_document(project),
        "machining": _machining_doc(project),
        "status": project.status(),
    }
    return doc


def result_extras(processed: Any) -> dict[str, Any]:
    """The post-processing result's mesh score and move counts (mm), for settings.json,
    summary.json and the API: ``mesh_max_deviation_mm``, ``mesh_rms_deviation_mm``,
    ``mesh_overcut_mm``, ``mesh_air_mm``, ``follows_taught_wall``, ``taught_wall``,
    ``problems``, ``moves``, ``circular_moves``, ``straight_moves``."""
    mesh = processed.mesh_score
    n = len(processed.result.targets)
    moves = processed.moves
    taught = processed.taught_wall
    return {
        "mesh_max_deviation_mm": None if mesh is None else mesh.max_m * 1e3,
        "mesh_rms_deviation_mm": None if mesh is None else mesh.rms_m * 1e3,
        "mesh_overcut_mm": None if mesh is None else mesh.overcut_m * 1e3,
        "mesh_air_mm": None if mesh is None else mesh.air_m * 1e3,
        "follows_taught_wall": None if taught is None else taught.follows,
        "taught_wall": None if taught is None else taught.message,
        "problems": processed.problems(),
        "arcs": moves is not None,
        "moves": n if moves is None else len(moves),
        "circular_moves": 0 if moves is None else sum(m.via is not None for m in moves),
        "straight_moves": n if processed.straight_targets is None else processed.straight_targets,
        "cad_comparison": None
        if getattr(processed, "cad_comparison", None) is None
        else processed.cad_comparison.summary(),
    }


def _machining_doc(project: Project) -> dict[str, Any] | None:
    """The machining settings, the chosen configuration and the result's figures."""
    from ._machining import MachiningResult, MachiningSetup, machining_setup_of
    from ._machining_documents import machining_setup_document

    setup = project.machining_settings
    if setup is None:
        return None
    if not isinstance(setup, MachiningSetup):
        return {"settings": repr(setup)}
    setup = machining_setup_of(project)
    doc = machining_setup_document(setup)
    doc["chosen"] = {
        "controller": setup.settings.controller,
        "compensation": setup.settings.compensation,
    }
    result = project.machining
    if isinstance(result, MachiningResult):
        # Wall-clock figures differ from one machine (and run) to the next: left out, so the
        # same project gives the same settings.json from the CLI and the workbench.
        timing = ("wall_time_s", "realtime_factor")
        doc["runs"] = [{k: v for k, v in r.items() if k not in timing} for r in result.rows]
        doc["status"] = project.status()["machining"]
    return doc
