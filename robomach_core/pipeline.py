"""The whole programming-by-demonstration pipeline on the simulated cell (chapter section 3).

cell -> scripted lead-through (pushes) -> guide points -> path learning -> force-threshold
filter -> deviation-height reduction -> targets -> RAPID program, scored against the truth.
Each stage is a function of the previous stage's output plus its settings.
"""

from __future__ import annotations

import time
from collections.abc import Callable
from dataclasses import dataclass, field, replace
from pathlib import Path
from typing import Any

import numpy as np

from .cell import CONTROL_PERIOD_S, Cell, CellConfig
from .demo_operator import intents_from_csv, scripted_leadthrough
from .errors import InvalidInputError
from .export.program import ReachabilityReport, check_reachability, rapid_program
from .export.rapid import rapid_module
from .leadthrough import GuidePoint, LeadThrough
from .path_learning import PathLearningSettings, Recording, learn_path
from .postprocess import PostprocessResult, PostprocessSettings, Targets, postprocess
from .scoring import PathScore, score_path
from .tool import Tool
from .workpiece import Workpiece, builtin_workpiece, load_mesh_file

# progress(stage, fraction in [0, 1])
Progress = Callable[[str, float], None]
STAGES = ("lead-through", "path learning", "post-processing", "export")


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
    """

    robot: str = "ur10"
    workpiece: str = "water_pump"
    force_N: float = 10.0
    speed_m_s: float = 0.005
    tolerance_m: float = 0.0002
    seed: int = 0
    tool: Tool = field(default_factory=Tool)
    postprocess: PostprocessSettings = field(default_factory=PostprocessSettings)
    force_control_variant: bool = True
    guide_points_csv: str | None = None
    wall_side: str = "auto"
    wobj_mm_deg: tuple[float, ...] | None = None
    cmrr: Any = None  # robomach_core.cmrr.CmrrSettings
    compensation: Any = None  # robomach_core.stiffness.CompensationSettings


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
            "force_min_N": self.settings.postprocess.force_min_N,
            "force_max_N": self.settings.postprocess.force_max_N,
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
        if self.score is not None:
            out["max_deviation_mm"] = self.score.max_m * 1e3
            out["rms_deviation_mm"] = self.score.rms_m * 1e3
            out["targets_max_deviation_mm"] = self.score.targets_max_m * 1e3
            out["targets_rms_deviation_mm"] = self.score.targets_rms_m * 1e3
        return out


def wobj_transform(values: tuple[float, ...]) -> np.ndarray:
    """4x4 work-object frame from (x, y, z [mm]) or (x, y, z [mm], rz [deg])."""
    from .transforms import make_transform, rotation_about

    v = [float(x) for x in values]
    if len(v) not in (3, 4) or not all(np.isfinite(v)):
        raise InvalidInputError("the work object is x,y,z in mm with an optional rz in degrees")
    rz = np.radians(v[3]) if len(v) == 4 else 0.0
    return make_transform(rotation_about("z", rz), np.array(v[:3]) * 1e-3)


def load_workpiece(name_or_path: str) -> Workpiece:
    """A built-in workpiece by name, or a mesh file by path."""
    if Path(name_or_path).suffix:
        return load_mesh_file(name_or_path)
    return builtin_workpiece(name_or_path)


def run_demo(settings: DemoSettings, *, progress: Progress | None = None) -> DemoResult:
    """Run the whole pipeline headless; ``progress(stage, fraction)`` reports as it goes."""
    started = time.perf_counter()
    report = progress or (lambda stage, fraction: None)
    learning = PathLearningSettings(
        force_N=settings.force_N, speed_m_s=settings.speed_m_s, wall_side=settings.wall_side
    )
    post = PostprocessSettings(
        **{**settings.postprocess.__dict__, "tolerance_m": settings.tolerance_m}
    )
    workpiece = load_workpiece(settings.workpiece)
    if settings.wobj_mm_deg is not None:
        workpiece = workpiece.placed(wobj_transform(settings.wobj_mm_deg))
    if workpiece.wall is None and settings.guide_points_csv is None:
        raise InvalidInputError(
            f"{workpiece.name}: a mesh file has no known wall to plan guide points on; "
            "give --guide-points FILE.csv"
        )
    cell = Cell(
        CellConfig(
            robot=settings.robot, tool=settings.tool, workpiece=workpiece, seed=settings.seed
        )
    )
    intents = None
    if settings.guide_points_csv is not None:
        intents = intents_from_csv(settings.guide_points_csv, cell.robot)
    lt = LeadThrough(cell)
    state = lt.start(cell.initial_state())
    state, guides = scripted_leadthrough(
        lt,
        state,
        workpiece,
        np.random.default_rng(settings.seed),
        intents=intents,
        progress=lambda f: report("lead-through", f),
    )
    t_learn = time.perf_counter()
    recording, _ = learn_path(
        cell,
        state.cell,
        guides,
        learning,
        lt.estimator,
        progress=lambda f: report("path learning", f),
    )
    learning_wall = time.perf_counter() - t_learn
    report("post-processing", 0.0)
    processed = postprocess(
        recording, np.array([g.quaternion_wxyz for g in guides]), post, closed=learning.closed
    )
    score = None
    if workpiece.wall is not None:
        score = score_path(workpiece, settings.tool.radius_m, processed.targets.position_m)
    report("post-processing", 1.0)
    report("export", 0.0)
    header = (
        f"robomach demo: {settings.robot}, {workpiece.name}, force {settings.force_N:g} N, "
        f"learning speed {settings.speed_m_s * 1e3:g} mm/s, tolerance "
        f"{settings.tolerance_m * 1e3:g} mm, seed {settings.seed}",
        f"{len(processed.targets)} targets from {len(recording)} samples "
        f"({processed.samples_filtered} kept by the force filter)",
    )
    targets = processed.targets
    speed_change = None
    if settings.cmrr is not None:
        from .cmrr import to_speed_change_settings

        speed_change = to_speed_change_settings(settings.cmrr)
        header += (
            f"CMRR: {settings.cmrr.controller.kind}, reference "
            f"{settings.cmrr.reference_force_N:g} N",
        )
    if settings.compensation is not None:
        targets, note = compensate_program_targets(cell, recording, targets, settings.compensation)
        header += (note,)
    module_text = rapid_module(
        rapid_program(targets, settings.tool, workpiece, comment=header, speed_change=speed_change)
    )
    module_text_fc = None
    if settings.force_control_variant:
        module_text_fc = rapid_module(
            rapid_program(
                targets,
                settings.tool,
                workpiece,
                module_name="LearnedPathFC",
                force_control_N=settings.force_N,
                comment=header,
            )
        )
    reach = check_reachability(module_text, cell.robot, workpiece, targets.joints_rad[0])
    report("export", 1.0)
    return DemoResult(
        settings=settings,
        workpiece=workpiece,
        guides=guides,
        recording=recording,
        processed=processed,
        score=score,
        module_text=module_text,
        module_text_fc=module_text_fc,
        reachability=reach,
        leadthrough_sim_s=float(state.cell.time_s),
        learning_wall_s=learning_wall,
        wall_time_s=time.perf_counter() - started,
    )


def compensate_program_targets(
    cell: Cell, recording: Recording, targets: Targets, compensation: Any
) -> tuple[Targets, str]:
    """Targets corrected for the contact wrench learned at each one (offline modes), and a note.

    The process wrench the program will meet is the one measured while learning it (the
    compensated tool-frame wrench at each target's sample, turned into base axes). Online
    compensation happens in the controller at run time, so it leaves the targets as they are.
    """
    from .errors import InvalidInputError
    from .stiffness import compensate_targets_and_joints
    from .transforms import make_transform, matrix_from_quaternion, quaternions_from_matrices

    if compensation.robot != cell.robot.name:
        raise InvalidInputError(
            f"the compensation settings were identified on {compensation.robot}, "
            f"the cell has {cell.robot.name}"
        )
    if compensation.mode in ("off", "online"):
        return targets, f"deflection compensation: {compensation.mode} (targets as learned)"
    mode = "linear" if compensation.mode == "offline_linear" else "nonlinear"
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
        cell.robot, Ts, targets.joints_rad, wrenches, compensation.model, mode
    )
    corrected = replace(
        targets,
        position_m=Ts_c[:, :3, 3].copy(),
        quaternion_wxyz=quaternions_from_matrices(Ts_c[:, :3, :3]),
        joints_rad=np.asarray(q_c),
    )
    shift = np.linalg.norm(corrected.position_m - targets.position_m, axis=1).max()
    return corrected, (
        f"deflection compensation: {compensation.mode}, largest target correction "
        f"{shift * 1e3:.4f} mm"
    )
