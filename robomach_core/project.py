"""One job as one value, and the stages that turn it into a program (chapter section 3).

PROBLEM   The CLI (``robomach demo``) and the workbench (viser, REST, pendant) both run cell ->
          guide points -> path learning -> post-processing -> RAPID. Composed twice, the copies
          drift (two settings.json writers, two RAPID headers, two scoring paths), and when an
          upstream input changes, a result computed from the old one can be shown as if current.
STRATEGY  ``Project`` is a frozen value holding the inputs of every stage and the result of each
          (``LearnedPath``, ``ProcessedPath``, a machining slot). Each stage is a pure function
          of the previous stage's output and its own settings (``learn``, ``process``,
          ``program_files``). Each result carries a fingerprint of the inputs it was computed
          from; ``Project.status()`` compares them with the project's current inputs, so a
          result is ``"current"``, ``"stale"`` (kept, flagged) or ``"none"``.
SOLUTION  Callers replace the value (``dataclasses.replace``) and never mark anything by hand:
          changing the guide points or the cell makes the recording, the post-processing and the
          machining results stale by construction. Writers refuse stale results
          (``StaleResultError``, a 409 in the API): a program is never exported from a path that
          no longer matches the project's guide points or cell. ``settings.json`` carries the
          status, so a saved document says what it was made from.
"""

from __future__ import annotations

import hashlib
import json
from collections.abc import Callable, Sequence
from dataclasses import asdict, dataclass, field, replace
from functools import cached_property
from pathlib import Path
from typing import Any, Literal

import numpy as np

from .cell import Cell, CellState
from .errors import InvalidInputError, RobomachError
from .leadthrough import GuidePoint
from .path_learning import PathLearningSettings, Recording, learn_path
from .postprocess import PostprocessResult, PostprocessSettings, Targets, postprocess
from .robot import Robot
from .scoring import PathScore, score_path
from .sensor import ForceEstimator
from .tool import Tool
from .workpiece import Workpiece

StageStatus = Literal["none", "current", "stale"]
STAGE_NAMES = ("guide_points", "recording", "postprocess", "machining")
DEFAULT_MODULE_NAME = "LearnedPath"


class StaleResultError(RobomachError, RuntimeError):
    """A result is out of date with the project's inputs; re-run its stage before exporting."""


class MissingResultError(RobomachError, RuntimeError):
    """A stage has not run yet, so what depends on it cannot be produced."""


# --- the values ------------------------------------------------------------------------------


@dataclass(frozen=True)
class CellSettings:
    """The user's cell settings.

    Attributes:
        robot: ``"ur10"``, ``"ur5"`` or ``"ur3"``.
        tool_radius_m: Ball cutter radius.
        workpiece: Built-in name, or the stem of the uploaded mesh file.
        workpiece_builtin: False for an uploaded mesh (the project holds its bytes).
        seed: Seed of the sensor noise and the example operator.
        wobj_mm_deg: Work-object frame (x, y, z [mm], optional rz [deg]) placing the workpiece;
            None for the built-in placement.
    """

    robot: str = "ur10"
    tool_radius_m: float = 0.001
    workpiece: str = "water_pump"
    workpiece_builtin: bool = True
    seed: int = 0
    wobj_mm_deg: tuple[float, ...] | None = None


@dataclass(frozen=True)
class LearnedPath:
    """The path-learning stage's result: the recording and what it was learned from.

    Attributes:
        recording: The 4 ms samples.
        guide_quaternions_wxyz: (n, 4) orientations of the guide points it followed.
        settings: The path-learning settings.
        inputs: Fingerprint of the cell and guide points it was learned from.
    """

    recording: Recording
    guide_quaternions_wxyz: np.ndarray
    settings: PathLearningSettings
    inputs: str

    @cached_property
    def key(self) -> str:
        """Fingerprint of this result (its inputs, settings and samples)."""
        rec = self.recording
        return _digest(
            self.inputs,
            _settings_json(self.settings),
            rec.time_s,
            rec.position_m,
            rec.force_normal_N,
            self.guide_quaternions_wxyz,
        )


@dataclass(frozen=True)
class ProcessedPath:
    """The post-processing stage's result: filter + reduction, and its score.

    Attributes:
        settings: The post-processing settings used.
        result: Keep mask, surface points and targets.
        samples_raw: Samples of the recording.
        score: Deviation from the true tool path (built-in workpieces), else None.
        inputs: Fingerprint of the recording and settings it was computed from.
    """

    settings: PostprocessSettings
    result: PostprocessResult
    samples_raw: int
    score: PathScore | None
    inputs: str


@dataclass(frozen=True)
class Project:
    """The state of one job (module docstring). SI units inside.

    Attributes:
        cell: Robot, tool radius, workpiece, seed, work-object placement.
        mesh: (filename, bytes) of an uploaded workpiece mesh (mm), None for a built-in one.
        guide_points: The recorded guide points, in order.
        learned: The last path-learning result.
        post_settings: The post-processing settings the user holds now.
        processed: The last post-processing result.
        cmrr: ``robomach_core.cmrr.CmrrSettings`` of the chosen feed controller, or None: the
            program's machining moves are wrapped in an FC SpeedChange block.
        compensation: ``robomach_core.stiffness.CompensationSettings``, or None: in the
            offline modes each target is corrected for the contact wrench learned at it.
        machining_settings: Slot for the machining run's settings (``robomach_core.machining``).
        machining: Slot for the machining run's result.
        machining_inputs: Fingerprint the machining result was computed from
            (``machining_inputs_key`` of the project at the time).
    """

    cell: CellSettings = field(default_factory=CellSettings)
    mesh: tuple[str, bytes] | None = None
    guide_points: tuple[GuidePoint, ...] = ()
    learned: LearnedPath | None = None
    post_settings: PostprocessSettings = field(default_factory=PostprocessSettings)
    processed: ProcessedPath | None = None
    cmrr: Any = None
    compensation: Any = None
    machining_settings: Any = None
    machining: Any = None
    machining_inputs: str | None = None

    @cached_property
    def cell_key(self) -> str:
        """Fingerprint of the cell (settings and uploaded mesh bytes)."""
        mesh = () if self.mesh is None else (self.mesh[0], self.mesh[1])
        return _digest(json.dumps(asdict(self.cell), sort_keys=True), *mesh)

    @cached_property
    def guides_key(self) -> str:
        """Fingerprint of the guide points (poses and joints)."""
        return _digest(*(a for g in self.guide_points for a in (g.T_base_tcp, g.joints_rad)))

    def tool(self) -> Tool:
        """The cell's tool."""
        return Tool(radius_m=self.cell.tool_radius_m)

    def status(self) -> dict[str, StageStatus]:
        """Per stage (``STAGE_NAMES``): ``"none"``, ``"current"`` or ``"stale"``."""
        out: dict[str, StageStatus] = {
            "guide_points": "current" if self.guide_points else "none",
            "recording": "none",
            "postprocess": "none",
            "machining": "none",
        }
        upstream_ok = True
        if self.learned is not None:
            upstream_ok = self.learned.inputs == recording_inputs_key(self)
            out["recording"] = "current" if upstream_ok else "stale"
        if self.processed is not None:
            ok = (
                upstream_ok
                and self.learned is not None
                and self.processed.inputs
                == processed_inputs_key(self.learned, self.processed.settings)
            )
            out["postprocess"] = "current" if ok else "stale"
            upstream_ok = ok
        else:
            upstream_ok = False
        if self.machining is not None:
            ok = upstream_ok and self.machining_inputs == machining_inputs_key(self)
            out["machining"] = "current" if ok else "stale"
        return out

    def stale_reasons(self) -> dict[str, str]:
        """A sentence per stale stage saying why (for GUIs and error messages)."""
        status = self.status()
        reasons = {}
        if status["recording"] == "stale":
            reasons["recording"] = (
                "the guide points or the cell changed after path learning: learn the path again"
            )
        if status["postprocess"] == "stale":
            reasons["postprocess"] = (
                "post-processed from an out-of-date recording: "
                + ("learn the path again, then " if status["recording"] == "stale" else "")
                + "run post-processing again"
            )
        if status["machining"] == "stale":
            reasons["machining"] = "its program or settings changed: run the machining again"
        return reasons


# --- fingerprints ----------------------------------------------------------------------------


def _settings_json(settings: Any) -> str:
    return json.dumps(asdict(settings), sort_keys=True, default=str)


def _plain(value: Any) -> Any:
    """A JSON-able form of a settings value (a dataclass as a dict, else its repr)."""
    if value is None:
        return None
    try:
        return json.loads(json.dumps(asdict(value), default=str))
    except TypeError:
        return repr(value)


def _digest(*parts: Any) -> str:
    h = hashlib.blake2b(digest_size=12)
    for part in parts:
        if isinstance(part, np.ndarray):
            a = np.ascontiguousarray(part)
            h.update(str((a.dtype.str, a.shape)).encode())
            h.update(a.tobytes())
        elif isinstance(part, bytes):
            h.update(part)
        else:
            h.update(str(part).encode())
        h.update(b"\x00")
    return h.hexdigest()


def recording_inputs_key(project: Project) -> str:
    """What a recording of this project must have been learned from (cell + guide points)."""
    return _digest(project.cell_key, project.guides_key)


def processed_inputs_key(learned: LearnedPath, settings: PostprocessSettings) -> str:
    """What a post-processing result of ``learned`` with ``settings`` is computed from."""
    return _digest(learned.key, _settings_json(settings))


def machining_inputs_key(project: Project) -> str:
    """What a machining result of this project is computed from: the processed path, the
    machining, CMRR and compensation settings. Stamp ``Project.machining_inputs`` with it."""
    processed = project.processed.inputs if project.processed is not None else ""
    return _digest(
        processed,
        json.dumps(_plain(project.machining_settings), sort_keys=True),
        json.dumps(cmrr_document(project), sort_keys=True),
        json.dumps(compensation_document(project), sort_keys=True),
    )


# --- stages ----------------------------------------------------------------------------------


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
    if project.compensation is None:
        return targets, None
    return compensate_program_targets(
        robot, project.learned.recording, targets, project.compensation
    )


def rapid_header(
    project: Project, workpiece_name: str, *, note: str | None = None
) -> tuple[str, ...]:
    """The program's comment lines: cell, learning, reduction, CMRR and compensation."""
    c = project.cell
    processed = require_processed(project)
    learning = project.learned.settings
    lines = [
        f"robomach: {c.robot}, {workpiece_name}, tool radius {c.tool_radius_m * 1e3:g} mm, "
        f"seed {c.seed}",
        f"path learning: force {learning.force_N:g} N, speed {learning.speed_m_s * 1e3:g} mm/s, "
        f"{len(project.guide_points)} guide points",
        f"{len(processed.result.targets)} targets from {processed.samples_raw} samples "
        f"({processed.result.samples_filtered} kept by the force filter), tolerance "
        f"{processed.settings.tolerance_m * 1e3:g} mm",
    ]
    if project.cmrr is not None:
        lines.append(
            f"CMRR: {project.cmrr.controller.kind}, reference {project.cmrr.reference_force_N:g} N"
        )
    if note is not None:
        lines.append(note)
    return tuple(lines)


def fc_module_name(module_name: str) -> str:
    """The Force Control variant's module name (RAPID names are at most 32 characters)."""
    return module_name[:30] + "FC"


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
    from .export.program import rapid_program
    from .export.rapid import rapid_module

    targets, note = program_targets(project, robot)
    header = rapid_header(project, workpiece.name, note=note)
    speed_change = None
    if project.cmrr is not None and not force_control:
        from .cmrr import to_speed_change_settings

        speed_change = to_speed_change_settings(project.cmrr)
    program = rapid_program(
        targets,
        project.tool(),
        workpiece,
        module_name=module_name,
        force_control_N=project.learned.settings.force_N if force_control else None,
        speed_change=speed_change,
        comment=header,
    )
    return rapid_module(program)


def program_files(
    project: Project,
    workpiece: Workpiece,
    robot: Robot,
    *,
    module_name: str = DEFAULT_MODULE_NAME,
    project_name: str | None = None,
    compliance: dict[str, Any] | None = None,
) -> dict[str, str]:
    """The program's files: program.mod, program_fc.mod, targets.csv, samples.csv and
    settings.json (the one writer set of the CLI and the workbench)."""
    from .export.tables import samples_csv, targets_csv

    processed = require_processed(project)
    doc = settings_document(project, workpiece, project_name=project_name, compliance=compliance)
    return {
        "program.mod": rapid_text(project, workpiece, robot, module_name=module_name),
        "program_fc.mod": rapid_text(
            project, workpiece, robot, module_name=fc_module_name(module_name), force_control=True
        ),
        "targets.csv": targets_csv(processed.result.targets),
        "samples.csv": samples_csv(project.learned.recording, processed.result.keep_mask),
        "settings.json": json.dumps(doc, indent=2) + "\n",
    }


def cmrr_document(project: Project) -> dict[str, Any] | None:
    """The CMRR settings as in ``cmrr_settings.json``, or None."""
    if project.cmrr is None:
        return None
    from .cmrr import settings_to_dict

    return settings_to_dict(project.cmrr)


def compensation_document(project: Project) -> dict[str, Any] | None:
    """The compensation settings as in ``compensation_settings.json``, or None."""
    if project.compensation is None:
        return None
    from .stiffness.settings import settings_to_dict

    return settings_to_dict(project.compensation)


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
        },
        "result": None
        if processed is None
        else {
            "samples_raw": processed.samples_raw,
            "samples_filtered": processed.result.samples_filtered,
            "targets": len(processed.result.targets),
            "max_deviation_mm": None if processed.score is None else processed.score.max_m * 1e3,
            "rms_deviation_mm": None if processed.score is None else processed.score.rms_m * 1e3,
        },
        "cmrr": cmrr_document(project),
        "compensation": compensation_document(project),
        "machining": None
        if project.machining_settings is None
        else repr(project.machining_settings),
        "status": project.status(),
    }
    return doc


def compensate_program_targets(
    robot: Robot, recording: Recording, targets: Targets, compensation: Any
) -> tuple[Targets, str]:
    """Targets corrected for the contact wrench learned at each one (offline modes), and a note.

    The process wrench the program will meet is the one measured while learning it (the
    compensated tool-frame wrench at each target's sample, turned into base axes). Online
    compensation happens in the controller at run time, so it leaves the targets as they are.
    """
    from .stiffness import compensate_targets_and_joints
    from .transforms import make_transform, matrix_from_quaternion, quaternions_from_matrices

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
    from .transforms import make_transform, rotation_about

    v = [float(x) for x in values]
    if len(v) not in (3, 4) or not all(np.isfinite(v)):
        raise InvalidInputError("the work object is x,y,z in mm with an optional rz in degrees")
    rz = np.radians(v[3]) if len(v) == 4 else 0.0
    return make_transform(rotation_about("z", rz), np.array(v[:3]) * 1e-3)


def build_workpiece(
    cell: CellSettings, mesh: tuple[str, bytes] | None, *, max_triangles: int | None = None
) -> Workpiece:
    """The project's workpiece: built-in by name, or its mesh bytes; placed at ``wobj_mm_deg``."""
    from .workpiece import MAX_MESH_TRIANGLES, builtin_workpiece, mesh_from_bytes

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
