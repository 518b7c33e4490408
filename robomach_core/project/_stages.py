"""The stages: path learning, post-processing and scoring, and the program's targets."""

from __future__ import annotations

from collections.abc import Callable, Sequence
from dataclasses import replace
from pathlib import Path
from typing import Any

import numpy as np

from ..cell import Cell, CellState
from ..errors import InvalidInputError
from ..path_learning import PathLearningSettings, Recording, learn_path
from ..postprocess import PostprocessSettings, Targets, postprocess
from ..robot import Robot
from ..scoring import score_path
from ..sensor import ForceEstimator
from ..workpiece import Workpiece
from ._value import (
    CellSettings,
    LearnedPath,
    MissingResultError,
    ProcessedPath,
    Project,
    StaleResultError,
    processed_inputs_key,
    recording_inputs_key,
)


def learn(
    project: Project,
    cell: Cell,
    state: CellState,
    settings: PathLearningSettings,
    estimator: ForceEstimator,
    *,
    progress: Callable[[float], None] | None = None,
    cancelled: Callable[[], bool] | None = None,
) -> tuple[LearnedPath, CellState]:
    """Path learning through the project's guide points (``path_learning.learn_path``).

    ``cell`` is the project's cell (possibly seen through a proxy that taps each step); returns
    the learned path and the cell state at the end.
    """
    guides = list(project.guide_points)
    recording, end = learn_path(
        cell, state, guides, settings, estimator, progress=progress, cancelled=cancelled
    )
    quats = np.array([g.quaternion_wxyz for g in guides]).reshape(-1, 4)
    return LearnedPath(recording, quats, settings, recording_inputs_key(project)), end


def process(
    learned: LearnedPath,
    settings: PostprocessSettings,
    workpiece: Workpiece,
    tool_radius_m: float,
) -> ProcessedPath:
    """Force filter, deviation-height reduction and speeds (``postprocess.postprocess``), then
    the score against the true tool path when the workpiece has a known wall."""
    rec = learned.recording
    result = postprocess(
        rec, learned.guide_quaternions_wxyz, settings, closed=learned.settings.closed
    )
    score = None
    if workpiece.wall is not None and len(result.targets) >= 2:
        score = score_path(workpiece, tool_radius_m, result.targets.position_m)
    return ProcessedPath(settings, result, len(rec), score, processed_inputs_key(learned, settings))


def require_processed(project: Project) -> ProcessedPath:
    """The current post-processing result, or a clear error saying which stage to run."""
    if project.learned is None:
        raise MissingResultError("no recording yet: run path learning, then post-processing")
    if project.processed is None:
        raise MissingResultError("the recording is not post-processed yet: run post-processing")
    reasons = project.stale_reasons()
    if "postprocess" in reasons:
        raise StaleResultError(f"the post-processed path is out of date: {reasons['postprocess']}")
    return project.processed


def program_targets(project: Project, robot: Robot) -> tuple[Targets, str | None]:
    """The targets the program runs: post-processed, corrected for deflection in the offline
    compensation modes; and the compensation's note for the header (None without one)."""
    processed = require_processed(project)
    targets = processed.result.targets
    from ._machining import chosen_program

    chosen = chosen_program(project)
    if chosen is not None:  # offline compensation chosen from a current machining run
        return chosen
    if project.compensation is None:
        return targets, None
    return compensate_program_targets(
        robot, project.learned.recording, targets, project.compensation
    )


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
        robot, Ts, targets.joints_rad, wrenches, compensation.model, mode
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


# --- the workpiece of a project --------------------------------------------------------------


def wobj_transform(values: Sequence[float]) -> np.ndarray:
    """4x4 work-object frame from (x, y, z [mm]) or (x, y, z [mm], rz [deg])."""
    from ..transforms import make_transform, rotation_about

    v = [float(x) for x in values]
    if len(v) not in (3, 4) or not all(np.isfinite(v)):
        raise InvalidInputError("the work object is x,y,z in mm with an optional rz in degrees")
    rz = np.radians(v[3]) if len(v) == 4 else 0.0
    return make_transform(rotation_about("z", rz), np.array(v[:3]) * 1e-3)


def build_workpiece(
    cell: CellSettings, mesh: tuple[str, bytes] | None, *, max_triangles: int | None = None
) -> Workpiece:
    """The project's workpiece: built-in by name, or its mesh bytes; placed at ``wobj_mm_deg``."""
    from ..workpiece import MAX_MESH_TRIANGLES, builtin_workpiece, mesh_from_bytes

    if mesh is not None and not cell.workpiece_builtin:
        filename, data = mesh
        workpiece = mesh_from_bytes(
            data,
            Path(filename).suffix.lower(),
            name=Path(filename).stem,
            max_triangles=max_triangles or MAX_MESH_TRIANGLES,
        )
    else:
        workpiece = builtin_workpiece(cell.workpiece)
    if cell.wobj_mm_deg is not None:
        workpiece = workpiece.placed(wobj_transform(cell.wobj_mm_deg))
    return workpiece
