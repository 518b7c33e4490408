"""The whole programming-by-demonstration pipeline on the simulated cell (chapter section 3).

cell -> scripted lead-through (pushes) -> guide points -> path learning -> force-threshold
filter -> deviation-height reduction -> targets -> RAPID program, scored against the truth.
Each stage is a function of the previous stage's output plus its settings.
"""

from __future__ import annotations

import json
import time
from collections.abc import Callable
from dataclasses import dataclass, field, replace
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np

from .cell import CONTROL_PERIOD_S, Cell, CellConfig, GuidePoint, LeadThrough, Tool
from .errors import InvalidInputError, MeshFileError
from .export.languages import language
from .export.reachability import ReachabilityReport, check_program_reachability
from .learning.run import Recording
from .learning.settings import PathLearningSettings
from .part import MAX_MESH_BYTES, MESH_SUFFIXES, Workpiece, real_workpiece
from .postprocess import PostprocessResult, PostprocessSettings, Targets
from .project import (
    CellSettings,
    Project,
    build_workpiece,
    learn,
    process,
    program_export,
    program_languages,
    with_guide_points,
    with_learned,
    with_processed,
    with_registration,
)
from .project import compensate_program_targets as _compensate
from .project import wobj_transform as wobj_transform
from .scoring import PathScore
from .teaching import TOUCH_FORCE_N, intents_from_csv, registered_workpiece, scripted_leadthrough

if TYPE_CHECKING:
    from .learning import GuideWarning
    from .learning.settings import WallSideSetting

# progress(stage, fraction in [0, 1])
Progress = Callable[[str, float], None]
STAGES = ("calibration", "lead-through", "path learning", "post-processing", "export")


@dataclass(frozen=True)
class DemoSettings:
    """Settings of ``robomach demo`` (SI units inside).

    Attributes:
        robot: Robot model name.
        workpiece: Built-in name, or a path to an STL/OBJ/PLY file (mm).
        force_N: Contact force reference of path learning.
        speed_m_s: Learning speed.
        tolerance_m: Deviation-height tolerance.
        seed: Seed of every random element.
        tool: The tool.
        postprocess: Filter thresholds, speeds and contact compensation; its tolerance is
            replaced by ``tolerance_m``.
        force_control_variant: Also generate the FC (FCPressL) variant of the program.
        guide_points_csv: CSV text of guide points to lead the robot to (see
            ``demo_operator.intents_from_csv``) instead of the built-in plan; needed for mesh
            files, whose wall is unknown.
        wall_side: Side of the wall for path learning ("auto" reads the guide forces).
        wobj_mm_deg: Work-object frame (x, y, z [mm], rotation about base z [deg]) placing the
            workpiece; default: the built-in placement in front of the robot.
        cmrr: Feed-rate control settings (``robomach cmrr``); the program's machining moves
            are wrapped in an FC SpeedChange block.
        compensation: Identified stiffness and mode (``robomach compensate``); in the offline
            modes each target is corrected for the contact wrench learned at it.
        closed: Learn a closed contour (back to the first guide point); False for an open
            one (a groove, an edge that ends).
        language: Program language (``export.languages.language_choices``): ``"auto"``
            writes every language the arm's controller is offered (``project.program_files``).
        robot_urdf: (filename, bytes) of a user's 6-axis URDF (``robots.custom``); ``robot``
            is then its registered name.
        propose_at_m: (3,) a point on the wall to follow, work-object frame [m]: the guide
            points are proposed along that wall (``guide_proposal``) and the operator leads the
            robot to them; the wall decides open or closed, and the wall side.
        proposal: Gap and height of the proposed points.
        part_deviation: The real part's deviation from its mesh (``real_part``; the
            ``realistic`` preset is ``PartDeviation.realistic(seed)``); None: none.
        calibrate: Before teaching, the operator touches the real part
            (``teaching.calibration``) and the CAD is registered to the touches
            (``registration.fit_wobj``): the guide points are planned, checked and learned on
            the registered CAD, and the program written in the measured work object.
        touch_force_N: The calibration's touch force.
    """

    robot: str = "ur10"
    workpiece: str = "water_pump"
    force_N: float = PathLearningSettings.force_N
    speed_m_s: float = PathLearningSettings.speed_m_s
    tolerance_m: float = PostprocessSettings.tolerance_m
    seed: int = 0
    tool: Tool = field(default_factory=Tool)
    postprocess: PostprocessSettings = field(default_factory=PostprocessSettings)
    force_control_variant: bool = True
    guide_points_csv: str | None = None
    wall_side: WallSideSetting = "auto"
    wobj_mm_deg: tuple[float, ...] | None = None
    cmrr: Any = None  # robomach_core.cmrr.CmrrSettings
    compensation: Any = None  # robomach_core.stiffness.CompensationSettings
    closed: bool = True
    language: str = "auto"
    robot_urdf: tuple[str, bytes] | None = None
    propose_at_m: tuple[float, float, float] | None = None
    proposal: Any = None  # guide_proposal.ProposalSettings
    part_deviation: Any = None  # real_part.PartDeviation
    calibrate: bool = False
    touch_force_N: float = TOUCH_FORCE_N


@dataclass(frozen=True)
class DemoResult:
    """Everything the pipeline produced."""

    settings: DemoSettings
    workpiece: Workpiece
    guides: list[GuidePoint]
    recording: Recording
    processed: PostprocessResult
    score: PathScore | None
    module_text: str
    module_text_fc: str | None
    reachability: ReachabilityReport
    leadthrough_sim_s: float
    learning_wall_s: float
    wall_time_s: float
    project: Project | None = None
    files: dict[str, str] = field(default_factory=dict)
    proposal: Any = None  # guide_proposal.GuideProposal
    findings: tuple = ()  # learning.GuideWarning: the guide-point check before learning
    calibration: Any = None  # registration.WobjFit: the work object measured by touch

    @property
    def processed_settings(self) -> PostprocessSettings:
        """The post-processing settings the program was made with (the band after the rule
        of ``project.with_learned``)."""
        if self.project is not None:
            return self.project.post_settings
        return self.settings.postprocess

    def summary(self) -> dict:
        """The summary.json dictionary (units in key names)."""
        rec = self.recording
        kept = self.processed.keep_mask
        f = rec.force_normal_N[kept]
        setpoint = self.settings.force_N
        sim_s = float(rec.time_s[-1]) if len(rec) else 0.0
        out = {
            "robot": self.settings.robot,
            "workpiece": self.workpiece.name,
            "seed": self.settings.seed,
            "guide_points": len(self.guides),
            "samples_raw": len(rec),
            "samples_filtered": int(kept.sum()),
            "targets": len(self.processed.targets),
            "sample_period_s": CONTROL_PERIOD_S,
            "force_setpoint_N": setpoint,
            "force_min_N": self.processed_settings.force_min_N,
            "force_max_N": self.processed_settings.force_max_N,
            "force_mean_N": float(np.mean(f)),
            "force_abs_error_p95_N": float(np.percentile(np.abs(f - setpoint), 95)),
            "force_within_2N_fraction": float(np.mean(np.abs(f - setpoint) <= 2.0)),
            "force_peak_raw_N": float(np.max(np.abs(rec.force_normal_N))),
            "learning_speed_mm_s": self.settings.speed_m_s * 1e3,
            "tolerance_mm": self.settings.tolerance_m * 1e3,
            "tool_radius_mm": self.settings.tool.radius_m * 1e3,
            "contact_stiffness_N_mm": self.workpiece.contact_stiffness_N_m * 1e-3,
            "max_deviation_mm": None,
            "rms_deviation_mm": None,
            "targets_max_deviation_mm": None,
            "targets_rms_deviation_mm": None,
            "program_speed_mean_mm_s": float(np.mean(self.processed.targets.speed_m_s) * 1e3),
            "program_speed_min_mm_s": float(np.min(self.processed.targets.speed_m_s) * 1e3),
            "robtargets_reachable": self.reachability.reachable,
            "robtargets_total": self.reachability.total,
            "stop_reason": rec.stop_reason,
            "completed": rec.completed,
            "stop": None if rec.stop is None else rec.stop.document(),
            "wall_side": rec.wall_side,
            "wall_side_reason": rec.wall_side_reason,
            "wall_side_source": rec.wall_side_source,
            "guide_point_check": [
                {"point": w.point, "rule": w.rule, "severity": w.severity, "message": w.message}
                for w in self.findings
            ],
            "leadthrough_sim_time_s": self.leadthrough_sim_s,
            "sim_time_s": sim_s,
            "wall_time_s": self.wall_time_s,
            "learning_wall_time_s": self.learning_wall_s,
            "realtime_factor": sim_s / self.learning_wall_s if self.learning_wall_s > 0 else None,
            "cmrr_controller": None
            if self.settings.cmrr is None
            else self.settings.cmrr.controller.kind,
            "compensation_mode": None
            if self.settings.compensation is None
            else self.settings.compensation.mode,
        }
        if self.project is not None and self.project.processed is not None:
            from .project import result_extras

            out |= result_extras(self.project.processed)
            from .cell import program_language

            out["program_language"] = program_language(self.settings.robot)
            out["program_files"] = [
                name for name in self.files if name.startswith(("program.", "program_fc."))
            ]
            out["closed"] = self.settings.closed
        out["calibration"] = None if self.calibration is None else self.calibration.document()
        if self.proposal is not None:
            from .learning.planner import proposal_summary

            out["proposed_guide_points"] = proposal_summary(self.proposal)
        if self.score is not None:
            out["max_deviation_mm"] = self.score.max_m * 1e3
            out["rms_deviation_mm"] = self.score.rms_m * 1e3
            out["targets_max_deviation_mm"] = self.score.targets_max_m * 1e3
            out["targets_rms_deviation_mm"] = self.score.targets_rms_m * 1e3
        return out


def load_workpiece(name_or_path: str) -> tuple[CellSettings, tuple[str, bytes] | None]:
    """Cell settings naming a built-in workpiece, or a mesh file's (filename, bytes)."""
    path = Path(name_or_path)
    if not path.suffix:
        return CellSettings(workpiece=name_or_path), None
    if path.suffix.lower() not in MESH_SUFFIXES:
        raise MeshFileError(f"{path.name}: not a mesh file (expected {', '.join(MESH_SUFFIXES)})")
    if not path.is_file():
        raise MeshFileError(f"{path}: no such file")
    size = path.stat().st_size
    if size > MAX_MESH_BYTES:
        raise MeshFileError(
            f"{path.name}: {size / 1e6:.1f} MB exceeds the {MAX_MESH_BYTES / 1e6:.0f} MB limit"
        )
    return CellSettings(workpiece=path.stem, workpiece_builtin=False), (
        path.name,
        path.read_bytes(),
    )


def default_robot(language: str = "auto") -> str:
    """The arm a job gets when none is named: the language's own arm (``ProgramLanguage.
    default_arm``: an ABB IRB 4400, the chapter's, for RAPID; a KUKA KR 270 for KRL), else the
    UR10 (the CLI's default since the start)."""
    from .export.languages import default_arm

    return default_arm(language)


def demo_project(settings: DemoSettings) -> Project:
    """The project ``run_demo`` starts from: the cell, post-processing and process settings."""
    cell, mesh = load_workpiece(settings.workpiece)
    cell = replace(
        cell,
        robot=settings.robot,
        tool_radius_m=settings.tool.radius_m,
        seed=settings.seed,
        wobj_mm_deg=None if settings.wobj_mm_deg is None else tuple(settings.wobj_mm_deg),
        part_deviation=settings.part_deviation,
    )
    post = replace(settings.postprocess, tolerance_m=settings.tolerance_m)
    return Project(
        cell=cell,
        mesh=mesh,
        post_settings=post,
        cmrr=settings.cmrr,
        compensation=settings.compensation,
        robot_urdf=settings.robot_urdf,
    )


def run_demo(
    settings: DemoSettings,
    *,
    progress: Progress | None = None,
    checked: Callable[[tuple], None] | None = None,
) -> DemoResult:
    """Run the whole pipeline headless; ``progress(stage, fraction)`` reports as it goes, and
    ``checked(findings)`` gets the guide-point check before the run starts (a terminal prints
    it before the run, as the workbench shows it)."""
    started = time.perf_counter()
    report = progress or (lambda stage, fraction: None)
    if settings.robot_urdf is not None:
        from .robots.custom import register_urdf

        settings = replace(settings, robot=register_urdf(*settings.robot_urdf))
    project = demo_project(settings)
    cad = build_workpiece(project.cell, project.mesh)
    workpiece = real_workpiece(cad, project.cell.part_deviation)  # what the cell's tool meets
    if cad.wall is None and settings.guide_points_csv is None and settings.propose_at_m is None:
        raise InvalidInputError(
            f"{cad.name}: a mesh file has no known wall to plan guide points on; give "
            "--propose-guide-points X,Y,Z (a point on the wall, work-object frame, mm) or "
            "--guide-points FILE.csv"
        )
    cell = _cell(settings, project, workpiece)
    lt = LeadThrough(cell)
    state = lt.start(cell.initial_state())
    fit = None
    if settings.calibrate:
        fit, state = _calibrated(settings, project, cad, lt, state, report)
        project = with_registration(project, fit.registration())
        workpiece = registered_workpiece(workpiece, fit.T_base_wobj)
        cad = workpiece.cad()
        cell = _cell(settings, project, workpiece)
        lt = LeadThrough(cell, estimator=lt.estimator)  # the sensor stays tared
    intents, proposal, settings = _operator_intents(settings, cad, workpiece, cell)
    state, guides = scripted_leadthrough(
        lt,
        state,
        cad,
        np.random.default_rng(settings.seed),
        intents=intents,
        progress=lambda f: report("lead-through", f),
    )
    project = with_guide_points(project, guides)  # the transitions the workbench applies
    t_learn = time.perf_counter()
    learning = PathLearningSettings(
        force_N=settings.force_N,
        speed_m_s=settings.speed_m_s,
        wall_side=settings.wall_side,
        closed=settings.closed,
    )
    findings = _guide_point_findings(settings, guides, learning, cad, cell)
    if checked is not None:
        checked(findings)
    learned, _ = learn(
        project,
        cell,
        state.cell,
        learning,
        lt.estimator,
        progress=lambda f: report("path learning", f),
    )
    learning_wall = time.perf_counter() - t_learn
    report("post-processing", 0.0)
    project = with_learned(project, learned)  # the band rule the workbench applies
    processed = process(
        learned,
        project.post_settings,
        workpiece,
        project.cell.tool_radius_m,
        guides=project.guide_points,
    )
    project = with_processed(project, processed)
    report("post-processing", 1.0)
    report("export", 0.0)
    files, targets = program_export(project, workpiece, cell.robot, language=settings.language)
    main = program_languages(cell.robot, settings.language)[0]
    reach = check_program_reachability(files, main, cell.robot, workpiece, targets)
    main_files = language(main).file_names()
    report("export", 1.0)
    return DemoResult(
        settings=settings,
        workpiece=workpiece,
        guides=guides,
        recording=learned.recording,
        processed=processed.result,
        score=processed.score,
        module_text=files[main_files[0]],
        module_text_fc=files.get(language(main).file_names(force_control=True)[0])
        if settings.force_control_variant
        else None,
        reachability=reach,
        leadthrough_sim_s=float(state.cell.time_s),
        learning_wall_s=learning_wall,
        wall_time_s=time.perf_counter() - started,
        project=project,
        files=files,
        proposal=proposal,
        findings=findings,
        calibration=fit,
    )


def _cell(settings: DemoSettings, project: Project, workpiece: Workpiece) -> Cell:
    """The simulated cell: the settings' arm holding the project's tool, at the part the tool
    meets, seeded by the settings."""
    return Cell(
        CellConfig(
            robot=settings.robot, tool=project.tool(), workpiece=workpiece, seed=settings.seed
        )
    )


def _operator_intents(
    settings: DemoSettings, cad: Workpiece, workpiece: Workpiece, cell: Cell
) -> tuple[Any, Any, DemoSettings]:
    """How the scripted operator leads the robot: the intents of ``--guide-points``, or those to
    the guide points proposed through ``--propose-guide-points`` (the proposal comes back, and
    the settings with the wall's side and whether it is closed), else None (the operator's own
    plan). On a part that is not where its mesh is, the operator enters each groove in its
    middle and touches the real wall from there (``teaching.robust_intents``)."""
    intents = proposal = None
    if settings.guide_points_csv is not None:
        intents = intents_from_csv(settings.guide_points_csv, cell.robot)
    elif settings.propose_at_m is not None:
        proposal, intents, settings = _proposed(settings, cad, cell)
    if workpiece.nominal is not None and settings.guide_points_csv is None:
        from .teaching import guide_plan, robust_intents

        planned = intents or guide_plan(
            cad, cell.tool.radius_m, np.random.default_rng(settings.seed)
        )
        intents = robust_intents(planned, cad, cell.tool.radius_m)
    return intents, proposal, settings


def _guide_point_findings(
    settings: DemoSettings,
    guides: list[GuidePoint],
    learning: PathLearningSettings,
    cad: Workpiece,
    cell: Cell,
) -> tuple[GuideWarning, ...]:
    """The guide-point check the workbench shows before a run (``learning.guide_point_warnings``
    against the CAD part, the arm's reach and the cell's supervision); a refusal raises."""
    from .cell import cell_supervisor
    from .learning import guide_point_warnings

    return guide_point_warnings(
        guides,
        learning,
        workpiece=cad,
        tool_radius_m=cell.tool.radius_m,
        supervisor=cell_supervisor(cell),
        tolerance_m=settings.tolerance_m,
    )


def _calibrated(
    settings: DemoSettings,
    project: Project,
    cad: Workpiece,
    lt: LeadThrough,
    state: Any,
    report: Progress,
) -> tuple[Any, Any]:
    """The scripted operator touches the part (``teaching.calibration``) and the CAD is
    registered to the touches (``registration.fit_wobj``): the fit and the robot's state."""
    from .teaching import fit_wobj, plan_touches, scripted_touches

    plan = plan_touches(cad, lt.cell.tool.radius_m, robot=lt.cell.robot)
    state, touches = scripted_touches(
        lt,
        state,
        plan,
        force_N=settings.touch_force_N,
        progress=lambda f: report("calibration", f),
    )
    stiffness = settings.postprocess.contact_stiffness_N_m
    return fit_wobj(cad, touches, contact_stiffness_N_m=stiffness), state


def _proposed(settings: DemoSettings, cad: Workpiece, cell: Cell) -> tuple[Any, list, DemoSettings]:
    """The guide points proposed along the wall through ``settings.propose_at_m``, the
    operator's intents to lead the robot to them, and the settings with the wall's side and
    whether it is closed."""
    from .cell import cell_supervisor
    from .learning.planner import (
        ProposalSettings,
        propose_guide_points,
        refuse_unreachable,
        tool_reach,
    )
    from .teaching import guide_intents

    proposal = propose_guide_points(
        cad,
        cell.robot,
        np.asarray(settings.propose_at_m, dtype=float),
        tool_radius_m=cell.tool.radius_m,
        settings=settings.proposal or ProposalSettings(),
        q_seed=cell.robot.home_rad,
        supervisor=cell_supervisor(cell),
        tool_reach_m=tool_reach(cell.tool),
    )
    refuse_unreachable(proposal)
    if not settings.closed and proposal.closed:
        raise InvalidInputError(
            "the picked wall is a closed loop; learn it closed (leave out --open)"
        )
    side = proposal.wall_side if settings.wall_side == "auto" else settings.wall_side
    return (
        proposal,
        guide_intents(proposal),
        replace(settings, closed=proposal.closed, wall_side=side),
    )


def compensate_program_targets(
    cell: Cell, recording: Recording, targets: Targets, compensation: Any
) -> tuple[Targets, str]:
    """``project.compensate_program_targets`` on the cell's robot (kept for callers)."""
    return _compensate(cell.robot, recording, targets, compensation)


def _write_cad_only(project: Any, workpiece: Workpiece, out: Path) -> list[Path]:
    """The CAD-only program's files in the languages of the learned one (none when the learned
    path follows no wall of the mesh)."""
    from .cell import Robot
    from .project import MissingResultError, cad_only_program_texts, program_languages

    if project.processed is None or project.processed.cad_comparison is None:
        return []
    robot = Robot(project.cell.robot, project.tool().T_flange_tcp)
    written: list[Path] = []
    for name_of_language in program_languages(robot):
        try:
            texts = cad_only_program_texts(project, workpiece, robot, name_of_language)
        except MissingResultError:
            return written
        out.mkdir(exist_ok=True)
        for name, text in texts.items():
            (out / name).write_text(text)
            written.append(out / name)
    return written


def write_demo_outputs(result: DemoResult, out_dir: str | Path) -> list[Path]:
    """Write the demo's files into ``out_dir`` (created if needed): the project's program files
    (``project.program_files``: the program in each language of the arm, e.g. program.mod and
    program_fc.mod, targets.csv, samples.csv, settings.json), summary.json, project.npz
    (``project.save_project_file``), workpiece.stl and, when the learned path follows a wall
    of the mesh, the CAD-only program in the same languages under ``cad_only/`` (the baseline
    it is compared with, ``project.cad_only_program_texts``); returns the paths."""
    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    files = dict(result.files)
    if result.module_text_fc is None:  # no force-controlled variant asked for
        files = {k: v for k, v in files.items() if not k.startswith("program_fc.")}
    files["summary.json"] = json.dumps(result.summary(), indent=2) + "\n"
    written = []
    for name, text in files.items():
        path = out / name
        path.write_text(text)
        written.append(path)
    if result.project is not None:  # what `robomach machine --from` and the workbench open
        from .project import PROJECT_FILE, save_project_file

        written.append(save_project_file(result.project, out / PROJECT_FILE))
        written += _write_cad_only(result.project, result.workpiece, out / "cad_only")
    stl = out / "workpiece.stl"
    result.workpiece.mesh_in_base().export(stl)
    written.append(stl)
    return written
