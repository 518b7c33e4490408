"""The whole programming-by-demonstration pipeline on the simulated cell, headless: what
``robomach demo`` runs (chapter section 3).

cell -> scripted lead-through (pushes) -> guide points -> path learning -> force-threshold
filter -> deviation-height reduction -> targets -> program, scored against the truth. The job
is a ``project.Project`` (its settings are the project's own: ``CellSettings``, the
post-processing, CMRR and compensation settings), and every stage is the project's, in the
order the workbench applies them: the cell of ``project.build_cell``, ``with_guide_points``,
``guide_check``, ``learn`` and ``with_learned`` (the force filter's band rule),
``process`` and ``with_processed``, ``program_export``.
"""

from __future__ import annotations

import json
import time
from collections.abc import Callable
from dataclasses import dataclass, replace
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np

from .cell import CONTROL_PERIOD_S, Cell, GuidePoint, LeadThrough, program_language
from .errors import InvalidInputError, MeshFileError
from .export.reachability import check_program_reachability
from .learning.settings import PathLearningSettings
from .part import MAX_MESH_BYTES, MESH_SUFFIXES, Workpiece
from .project import (
    Project,
    build_cell,
    guide_check,
    learn,
    process,
    program_export,
    program_languages,
    result_extras,
    with_guide_points,
    with_learned,
    with_processed,
    with_registration,
)

if TYPE_CHECKING:
    from .export.reachability import ReachabilityReport
    from .learning import GuideWarning
    from .learning.run import Recording
    from .postprocess import PostprocessResult
    from .scoring import PathScore
    from .teaching import WobjFit
    from .teaching.pointing import GuideProposal, ProposalSettings

# progress(stage, fraction in [0, 1])
Progress = Callable[[str, float], None]
STAGES = ("calibration", "lead-through", "path learning", "post-processing", "export")


@dataclass(frozen=True)
class DemoResult:
    """What ``run_demo`` made: the project with every stage's result (its settings are the
    run's), the part the cell's tool met, the program's files, and the run's own figures."""

    project: Project
    workpiece: Workpiece
    guides: list[GuidePoint]
    recording: Recording
    processed: PostprocessResult
    score: PathScore | None
    files: dict[str, str]
    reachability: ReachabilityReport
    leadthrough_sim_s: float
    learning_wall_s: float
    wall_time_s: float
    proposal: GuideProposal | None = None
    findings: tuple[GuideWarning, ...] = ()  # the guide-point check before learning
    calibration: WobjFit | None = None  # the work object measured by touch

    def summary(self) -> dict:
        """The summary.json dictionary (units in key names)."""
        project, rec = self.project, self.recording
        assert project.learned is not None and project.processed is not None
        learning, post = project.learned.settings, project.post_settings
        f = rec.force_normal_N[self.processed.keep_mask]
        setpoint = learning.force_N
        sim_s = float(rec.time_s[-1]) if len(rec) else 0.0
        score = self.score
        out = {
            "robot": project.cell.robot,
            "workpiece": self.workpiece.name,
            "seed": project.cell.seed,
            "guide_points": len(self.guides),
            "samples_raw": len(rec),
            "samples_filtered": len(f),
            "targets": len(self.processed.targets),
            "sample_period_s": CONTROL_PERIOD_S,
            "force_setpoint_N": setpoint,
            "force_min_N": post.force_min_N,
            "force_max_N": post.force_max_N,
            "force_mean_N": float(np.mean(f)),
            "force_abs_error_p95_N": float(np.percentile(np.abs(f - setpoint), 95)),
            "force_within_2N_fraction": float(np.mean(np.abs(f - setpoint) <= 2.0)),
            "force_peak_raw_N": float(np.max(np.abs(rec.force_normal_N))),
            "learning_speed_mm_s": learning.speed_m_s * 1e3,
            "tolerance_mm": post.tolerance_m * 1e3,
            "tool_radius_mm": project.cell.tool_radius_m * 1e3,
            "contact_stiffness_N_mm": self.workpiece.contact_stiffness_N_m * 1e-3,
            "max_deviation_mm": None if score is None else score.max_m * 1e3,
            "rms_deviation_mm": None if score is None else score.rms_m * 1e3,
            "targets_max_deviation_mm": None if score is None else score.targets_max_m * 1e3,
            "targets_rms_deviation_mm": None if score is None else score.targets_rms_m * 1e3,
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
            "cmrr_controller": None if project.cmrr is None else project.cmrr.controller.kind,
            "compensation_mode": None
            if project.compensation is None
            else project.compensation.mode,
        }
        out |= result_extras(project.processed)
        out["program_language"] = program_language(project.cell.robot)
        out["program_files"] = [n for n in self.files if n.startswith(("program.", "program_fc."))]
        out["closed"] = learning.closed
        out["calibration"] = None if self.calibration is None else self.calibration.document()
        if self.proposal is not None:
            from .teaching.pointing import proposal_summary

            out["proposed_guide_points"] = proposal_summary(self.proposal)
        return out


def read_mesh_file(path: Path) -> tuple[str, bytes]:
    """(filename, bytes) of a workpiece mesh file, for ``project.with_uploaded_mesh``."""
    if path.suffix.lower() not in MESH_SUFFIXES:
        raise MeshFileError(f"{path.name}: not a mesh file (expected {', '.join(MESH_SUFFIXES)})")
    if not path.is_file():
        raise MeshFileError(f"{path}: no such file")
    size = path.stat().st_size
    if size > MAX_MESH_BYTES:
        raise MeshFileError(
            f"{path.name}: {size / 1e6:.1f} MB exceeds the {MAX_MESH_BYTES / 1e6:.0f} MB limit"
        )
    return path.name, path.read_bytes()


def run_demo(
    project: Project,
    learning: PathLearningSettings | None = None,
    *,
    guide_points_csv: str | None = None,
    propose_at_m: tuple[float, float, float] | None = None,
    proposal_settings: ProposalSettings | None = None,
    touch_force_N: float | None = None,
    language: str = "auto",
    progress: Progress | None = None,
    checked: Callable[[tuple], None] | None = None,
) -> DemoResult:
    """The job ``project`` run headless: the scripted operator teaches the guide points, path
    learning runs at ``learning`` (default ``PathLearningSettings()``), post-processing at the
    project's settings, and the program is written in ``language`` (``"auto"``: every language
    the arm's controller is offered, ``project.program_files``).

    Args:
        guide_points_csv: CSV text of guide points to lead the robot to
            (``teaching.intents_from_csv``) instead of the operator's own plan; needed for a
            mesh file, whose wall is unknown.
        propose_at_m: (3,) a point on the wall to follow, work-object frame [m]: the guide
            points are proposed along that wall (``proposal_settings``: their gap and height)
            and the operator leads the robot to them; the wall decides open or closed, and the
            side when ``learning``'s is "auto".
        touch_force_N: Before teaching, the operator touches the real part at this force
            (``teaching.calibration``) and the CAD is registered to the touches
            (``teaching.fit_wobj``): the guide points are planned, checked and learned on the
            registered CAD, and the program written in the measured work object. None: no
            calibration.
        progress: ``progress(stage, fraction)`` as it goes (``STAGES``).
        checked: Gets the guide-point check (``project.guide_findings``) before learning (a
            terminal prints it before the run, as the workbench shows it).
    """
    started = time.perf_counter()
    report = progress or (lambda stage, fraction: None)
    learning = learning or PathLearningSettings()
    if not project.cell.workpiece_builtin and guide_points_csv is None and propose_at_m is None:
        raise InvalidInputError(
            f"{project.cell.workpiece}: a mesh file has no known wall to plan guide points on; "
            "give --propose-guide-points X,Y,Z (a point on the wall, work-object frame, mm) or "
            "--guide-points FILE.csv"
        )
    cell = build_cell(project.cell, project.mesh)
    lt = LeadThrough(cell)
    state = lt.start(cell.initial_state())
    fit = None
    if touch_force_N is not None:
        fit, state = _calibrated(lt, state, touch_force_N, project, report)
        project = with_registration(project, fit.registration())
        cell = build_cell(project.cell, project.mesh)  # the CAD where the touches found it
        lt = LeadThrough(cell, estimator=lt.estimator)  # the sensor stays tared
    intents, found, learning = _operator_intents(
        cell, learning, project.cell.seed, guide_points_csv, propose_at_m, proposal_settings
    )
    state, guides = _teach(lt, state, intents, project.cell.seed, report)
    project = with_guide_points(project, guides)
    findings, route = guide_check(project, cell, learning)
    if checked is not None:
        checked(findings)
    t_learn = time.perf_counter()
    learned, _ = learn(
        project,
        cell,
        state.cell,
        learning,
        lt.estimator,
        progress=lambda f: report("path learning", f),
        route=route,  # the route checked (None when refused: ``learn`` plans it and says why)
    )
    learning_wall = time.perf_counter() - t_learn
    report("post-processing", 0.0)
    project = with_learned(project, learned)  # the band rule
    radius = project.cell.tool_radius_m
    processed = process(learned, project.post_settings, cell.workpiece, radius, guides=guides)
    project = with_processed(project, processed)
    report("post-processing", 1.0)
    report("export", 0.0)
    files, targets = program_export(project, cell.workpiece, cell.robot, language=language)
    main = program_languages(cell.robot, language)[0]
    reach = check_program_reachability(files, main, cell.robot, cell.workpiece, targets)
    report("export", 1.0)
    return DemoResult(
        project=project,
        workpiece=cell.workpiece,
        guides=guides,
        recording=learned.recording,
        processed=processed.result,
        score=processed.score,
        files=files,
        reachability=reach,
        leadthrough_sim_s=float(state.cell.time_s),
        learning_wall_s=learning_wall,
        wall_time_s=time.perf_counter() - started,
        proposal=found,
        findings=findings,
        calibration=fit,
    )


def _teach(
    lt: LeadThrough, state: Any, intents: Any, seed: int, report: Progress
) -> tuple[Any, list[GuidePoint]]:
    """The scripted operator leads the robot by pushes (``teaching.scripted_leadthrough``),
    planning on the mesh they see."""
    from .teaching import scripted_leadthrough

    return scripted_leadthrough(
        lt,
        state,
        lt.cell.workpiece.cad(),
        np.random.default_rng(seed),
        intents=intents,
        progress=lambda f: report("lead-through", f),
    )


def _operator_intents(
    cell: Cell,
    learning: PathLearningSettings,
    seed: int,
    csv: str | None,
    propose_at_m: tuple[float, float, float] | None,
    proposal: ProposalSettings | None,
) -> tuple[Any, GuideProposal | None, PathLearningSettings]:
    """How the scripted operator leads the robot: the intents of ``csv``, or those to the
    guide points proposed through ``propose_at_m`` (the proposal comes back, and ``learning``
    with the wall's side and whether it is closed), else None (the operator's own plan). On a
    part that is not where its mesh is, the operator enters each groove in its middle and
    touches the real wall from there (``teaching.robust_intents``)."""
    from .teaching import guide_intents, guide_plan, intents_from_csv, robust_intents

    intents, found, cad, radius = None, None, cell.workpiece.cad(), cell.tool.radius_m
    if csv is not None:
        intents = intents_from_csv(csv, cell.robot)
    elif propose_at_m is not None:
        found, learning = _proposed(cell, learning, propose_at_m, proposal)
        intents = guide_intents(found)
    if cell.workpiece.nominal is not None and csv is None:
        planned = intents or guide_plan(cad, radius, np.random.default_rng(seed))
        intents = robust_intents(planned, cad, radius)
    return intents, found, learning


def _calibrated(
    lt: LeadThrough, state: Any, force_N: float, project: Project, report: Progress
) -> tuple[WobjFit, Any]:
    """The scripted operator touches the part (``teaching.calibration``) and the CAD is
    registered to the touches (``teaching.fit_wobj``): the fit and the robot's state."""
    from .teaching import fit_wobj, plan_touches, scripted_touches

    cad = lt.cell.workpiece.cad()
    plan = plan_touches(cad, lt.cell.tool.radius_m, robot=lt.cell.robot)
    progress = lambda f: report("calibration", f)  # noqa: E731
    state, touches = scripted_touches(lt, state, plan, force_N=force_N, progress=progress)
    stiffness = project.post_settings.contact_stiffness_N_m
    return fit_wobj(cad, touches, contact_stiffness_N_m=stiffness), state


def _proposed(
    cell: Cell,
    learning: PathLearningSettings,
    at_m: tuple[float, float, float],
    settings: ProposalSettings | None,
) -> tuple[GuideProposal, PathLearningSettings]:
    """The guide points proposed along the wall through ``at_m``, and ``learning`` with the
    wall's side (on "auto") and whether it is closed."""
    from .cell import cell_supervisor
    from .teaching.pointing import (
        ProposalSettings,
        propose_guide_points,
        refuse_unreachable,
        tool_reach,
    )

    proposal = propose_guide_points(
        cell.workpiece.cad(),
        cell.robot,
        np.asarray(at_m, dtype=float),
        tool_radius_m=cell.tool.radius_m,
        settings=settings or ProposalSettings(),
        q_seed=cell.robot.home_rad,
        supervisor=cell_supervisor(cell),
        tool_reach_m=tool_reach(cell.tool),
    )
    refuse_unreachable(proposal)
    if not learning.closed and proposal.closed:
        raise InvalidInputError(
            "the picked wall is a closed loop; learn it closed (leave out --open)"
        )
    side = proposal.wall_side if learning.wall_side == "auto" else learning.wall_side
    return proposal, replace(learning, closed=proposal.closed, wall_side=side)


def _write_cad_only(project: Project, workpiece: Workpiece, out: Path) -> list[Path]:
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
    files = result.files | {"summary.json": json.dumps(result.summary(), indent=2) + "\n"}
    written = []
    for name, text in files.items():
        path = out / name
        path.write_text(text)
        written.append(path)
    from .project import PROJECT_FILE, save_project_file

    # what `robomach machine --from` and the workbench open
    written.append(save_project_file(result.project, out / PROJECT_FILE))
    written += _write_cad_only(result.project, result.workpiece, out / "cad_only")
    stl = out / "workpiece.stl"
    result.workpiece.mesh_in_base().export(stl)
    written.append(stl)
    return written
