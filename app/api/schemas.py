"""Request and response bodies of the REST API, in families per resource.

Units at this boundary: mm, N, N*m, s, degrees; quaternions wxyz. Every field name or
description says its unit. ``...Create``/``...Update`` are request bodies, ``...Public`` are
responses; ``from_*`` class methods convert the session's SI dataclasses.
"""

from __future__ import annotations

import math
from pathlib import Path
from typing import Annotated, Any, Literal, get_args

import numpy as np
from pydantic import BaseModel, ConfigDict, Field

from app.session import (
    CellSettings,
    ExportInfo,
    ForceTrace,
    GuidePointEntry,
    JobInfo,
    PostprocessOutcome,
    ProjectInfo,
    RobotSnapshot,
)
from robomach_core import limits
from robomach_core.cell import JOG_SPEED_M_S, ComplianceFrame, ComplianceSelection
from robomach_core.choices import JogFrame
from robomach_core.learning.settings import WallSideSetting
from robomach_core.postprocess import PostprocessSettings
from robomach_core.project import StageStatus

Axis = Literal["x", "y", "z", "rx", "ry", "rz"]
Finite = Annotated[float, Field(allow_inf_nan=False)]
Vector3 = Annotated[list[Finite], Field(min_length=3, max_length=3)]
AXIS_ORDER: tuple[Axis, ...] = get_args(Axis)


class _Request(BaseModel):
    """Request bodies reject unknown fields, so a misspelt field is an error, not ignored."""

    model_config = ConfigDict(extra="forbid")


def _floats(a: np.ndarray, scale: float = 1.0, digits: int = 6) -> list[float]:
    return [round(float(x) * scale, digits) for x in np.asarray(a).ravel()]


# --- health and state --------------------------------------------------------------------


class HealthPublic(BaseModel):
    status: Literal["ok"] = "ok"


class WorkbenchPublic(BaseModel):
    viser_port: int | None = Field(
        description="Port of the viser 3D workbench on this host (null: not running)"
    )


class TcpPublic(BaseModel):
    position_mm: list[float] = Field(description="TCP position in the robot base frame [mm]")
    quaternion_wxyz: list[float] = Field(description="TCP orientation, unit quaternion w, x, y, z")


class WrenchPublic(BaseModel):
    force_N: list[float] = Field(description="measured contact force at the TCP, base axes [N]")
    torque_Nm: list[float] = Field(description="measured contact torque, base axes [N*m]")


class ProjectStatusPublic(BaseModel):
    """Per stage of the project: ``none`` (not run), ``current``, or ``stale`` (kept, but
    computed from inputs that have changed since: out of date; exports refuse it)."""

    guide_points: StageStatus
    recording: StageStatus
    postprocess: StageStatus
    machining: StageStatus
    reasons: dict[str, str] = Field(description="why each stale stage is out of date")

    @classmethod
    def from_project(cls, project: Any) -> ProjectStatusPublic:
        return cls(**project.status(), reasons=project.stale_reasons())


class ProcessSettingsUpdate(_Request):
    cmrr: dict[str, Any] | None = Field(
        default=None,
        description="a cmrr_settings.json object (one controller): the program's machining "
        "moves get an FC SpeedChange block; null removes it",
    )
    compensation: dict[str, Any] | None = Field(
        default=None,
        description="a compensation_settings.json object: the offline modes correct the "
        "targets for the learned contact wrench; null removes it",
    )


class ProcessSettingsFromStudies(_Request):
    controller: str | None = Field(
        default=None,
        max_length=40,
        description="after a CMRR study that compared controllers, the one to use",
    )
    cmrr: bool = Field(default=True, description="take the last CMRR study's controller")
    compensation: bool = Field(
        default=True, description="take the last identification's compensation settings"
    )


class ProcessSettingsPublic(BaseModel):
    cmrr: dict[str, Any] | None
    compensation: dict[str, Any] | None


class StatePublic(BaseModel):
    joints_deg: list[float] = Field(description="motor-side joint angles [deg]")
    tcp: TcpPublic
    wrench: WrenchPublic
    in_contact: bool = Field(description="the tool touches the workpiece")
    time_s: float = Field(description="simulated time [s]")
    busy: bool = Field(description="a job moves the robot; pushes and jogs are refused")
    project_status: ProjectStatusPublic | None = Field(
        default=None, description="which results of the open project are out of date"
    )

    @classmethod
    def from_snapshot(
        cls, s: RobotSnapshot, *, project_status: ProjectStatusPublic | None = None
    ) -> StatePublic:
        return cls(
            joints_deg=_floats(np.degrees(s.joints_rad), digits=5),
            tcp=TcpPublic(
                position_mm=_floats(s.position_m, 1e3, 4),
                quaternion_wxyz=_floats(s.quaternion_wxyz, digits=7),
            ),
            wrench=WrenchPublic(
                force_N=_floats(s.wrench[:3], digits=4), torque_Nm=_floats(s.wrench[3:], digits=5)
            ),
            in_contact=s.in_contact,
            time_s=round(s.time_s, 4),
            busy=s.busy,
            project_status=project_status,
        )


# --- lead-through ------------------------------------------------------------------------


class ComplianceUpdate(_Request):
    axes: list[Axis] = Field(
        description="compliant axes, any subset of x, y, z, rx, ry, rz (the rest are stiff)"
    )
    frame: ComplianceFrame = Field(description="frame of the axes")


class CompliancePublic(BaseModel):
    axes: list[Axis]
    frame: ComplianceFrame

    @classmethod
    def from_selection(cls, s: ComplianceSelection) -> CompliancePublic:
        return cls(axes=[a for a in AXIS_ORDER if a in s.axes], frame=s.frame)


_PUSH_N, _PUSH_NM, _PUSH_S = limits.PUSH_FORCE_N, limits.PUSH_TORQUE_NM, limits.PUSH_DURATION_S


class PushCreate(_Request):
    force_N: Annotated[
        list[Annotated[float, Field(allow_inf_nan=False, ge=-_PUSH_N.max, le=_PUSH_N.max)]],
        Field(min_length=3, max_length=3),
    ] = Field(description=f"push force at the TCP, base axes [N]; magnitude {_PUSH_N.text()}")
    torque_Nm: Annotated[
        list[Annotated[float, Field(allow_inf_nan=False, ge=-_PUSH_NM.max, le=_PUSH_NM.max)]],
        Field(min_length=3, max_length=3),
    ] = Field(
        default_factory=lambda: [0.0, 0.0, 0.0],
        description=f"push torque about the TCP, base axes [N*m]; magnitude {_PUSH_NM.text()}",
    )
    duration_s: Finite = Field(
        ge=_PUSH_S.min, le=_PUSH_S.max, description=f"how long the push lasts, {_PUSH_S.text()}"
    )


class JogCreate(_Request):
    axis: Axis = Field(description="axis to move along (x, y, z) or about (rx, ry, rz)")
    step: Finite = Field(
        description=f"step [mm] along x/y/z (at most {limits.JOG_STEP_MM.max:g}) or [deg] about "
        f"rx/ry/rz (at most {limits.JOG_TURN_DEG.max:g})"
    )
    frame: JogFrame = Field(
        default="tool", description="frame of the axis: tool, robot base or work object"
    )
    speed: Finite | None = Field(
        default=None,
        description=f"[mm/s] along x/y/z ({limits.JOG_SPEED_MM_S.text()}; default "
        f"{JOG_SPEED_M_S * 1e3:g}) or [deg/s] about rx/ry/rz ({limits.JOG_RATE_DEG_S.text()}; "
        f"default {limits.JOG_RATE_DEG_S.default:g})",
    )


# --- guide points ------------------------------------------------------------------------


class GuidePointPublic(BaseModel):
    index: int = Field(description="position in the list, from 0")
    position_mm: list[float] = Field(description="TCP position, base frame [mm]")
    quaternion_wxyz: list[float]
    joints_deg: list[float]
    time_s: float = Field(description="simulated time of recording [s]")
    force_N: list[float] = Field(description="measured contact force at recording, base axes [N]")

    @classmethod
    def from_entry(cls, e: GuidePointEntry) -> GuidePointPublic:
        p = e.point
        return cls(
            index=e.index,
            position_mm=_floats(p.position_m, 1e3, 4),
            quaternion_wxyz=_floats(p.quaternion_wxyz, digits=7),
            joints_deg=_floats(np.degrees(p.joints_rad), digits=5),
            time_s=round(float(p.time_s), 4),
            force_N=_floats(p.force_N, digits=4),
        )


# --- jobs --------------------------------------------------------------------------------


class JobCreated(BaseModel):
    job_id: str
    warnings: list[str] = Field(
        default_factory=list,
        description="guide points that break an operator rule (docs/guide_points.md)",
    )
    findings: list[FindingPublic] = Field(
        default_factory=list,
        description="the same, one per rule with its severity (as GET /api/path-learning/check)",
    )


class FindingPublic(BaseModel):
    """One finding of the check before a run (``learning.checks``), in the person's words."""

    rule: str = Field(description="the rule (docs/guide_points.md's table)")
    severity: Literal["refusal", "warning", "info"] = Field(
        description="refusal: learning will not start; warning: it runs, look first; info: a note"
    )
    message: str = Field(description="what was found and what to do, in whole sentences")
    also_at: list[int] = Field(
        default_factory=list,
        description="the other guide points (1-based) where the same rule holds (GET "
        "/api/path-learning/check lists one finding per rule)",
    )

    @classmethod
    def from_group(cls, g: Any) -> FindingPublic:
        """One rule's findings (``app.findings.FindingGroup``)."""
        return cls(
            rule=g.rule, severity=g.severity, message=g.first.message, also_at=list(g.also_at)
        )


class GuideCheckPublic(BaseModel):
    """The check before a run: what the run will do with the guide points, said before it."""

    findings: list[FindingPublic] = Field(
        description="one per rule (its other points in also_at), refusals first, then "
        "warnings, then notes (docs/guide_points.md)"
    )
    wall_side: str = Field(
        description="the wall the run will follow and what decided it ('follows the wall on "
        "the right: ...'), or why it cannot tell; empty with fewer than two guide points"
    )


class PlacementPreviewUpdate(_Request):
    wobj_mm_deg: Annotated[list[Finite], Field(min_length=6, max_length=6)] = Field(
        description="the work object being tried: x, y, z [mm], rx, ry, rz [deg] about the "
        "base's fixed x, then y, then z axes (the numbers of robomach demo --wobj)"
    )


class PlacementPreviewPublic(BaseModel):
    wobj_mm_deg: list[float] | None = Field(
        description="the work object being tried (x, y, z mm, rx, ry, rz deg), drawn in the 3D "
        "scene; null: nothing is tried, the part is drawn where it is placed"
    )
    placed_wobj_mm_deg: list[float] = Field(
        description="where the part is placed now (x, y, z mm, rx, ry, rz deg)"
    )


class JobPublic(BaseModel):
    job_id: str
    kind: str = Field(description="example, path_learning, ...")
    status: Literal["queued", "running", "done", "failed", "cancelled"]
    progress: float = Field(ge=0.0, le=1.0)
    error: str | None = Field(description="why the job failed or was cancelled")
    created_s: float = Field(description="Unix time")
    started_s: float | None
    finished_s: float | None

    @classmethod
    def from_info(cls, j: JobInfo) -> JobPublic:
        return cls(
            job_id=j.id,
            kind=j.kind,
            status=j.status,
            progress=round(j.progress, 4),
            error=j.error,
            created_s=j.created_s,
            started_s=j.started_s,
            finished_s=j.finished_s,
        )


# --- path learning -----------------------------------------------------------------------


class PathLearningCreate(_Request):
    force_N: Finite = Field(
        ge=limits.LEARNING_FORCE_N.min,
        le=limits.LEARNING_FORCE_N.max,
        description=f"contact force reference [N], {limits.LEARNING_FORCE_N.text()}",
    )
    speed_mm_s: Finite = Field(
        ge=limits.LEARNING_SPEED_MM_S.min,
        le=limits.LEARNING_SPEED_MM_S.max,
        description=f"learning speed [mm/s], {limits.LEARNING_SPEED_MM_S.text()}",
    )
    closed: bool = Field(True, description="the path returns from the last guide point to the 1st")
    wall_side: WallSideSetting = Field(
        "auto",
        description="side of the wall to follow, left or right of travel looking along the tool "
        "into the part; auto decides from a clear push at the guide points or the part's mesh, "
        "and is refused (422) when neither tells",
    )
    floor_clearance_mm: Finite = Field(
        limits.FLOOR_CLEARANCE_MM.default_value(),
        ge=limits.FLOOR_CLEARANCE_MM.min,
        le=limits.FLOOR_CLEARANCE_MM.max,
        description="machining height: the cutter this far above a floor the run meets or a "
        "guide point rests on [mm], 0-5",
    )


class ForceTracePublic(BaseModel):
    source: Literal["live", "recording", "none"] = Field(
        description="live: a job runs (the force across the path every 20 ms, time since "
        "the job started); "
        "recording: the last recording (force along the path normal); none: nothing yet"
    )
    time_s: list[float]
    force_N: list[float]
    force_reference_N: list[float] | None = Field(description="null while live")
    samples_total: int = Field(description="samples before decimation")
    stop_reason: str | None = Field(description="why the last recording ended")
    completed: bool | None = Field(description="the last recording reached its last guide point")
    force_min_N: list[float] | None = Field(
        default=None, description="smallest force of the samples each point stands for [N]"
    )
    force_max_N: list[float] | None = Field(
        default=None, description="largest force of the samples each point stands for [N]"
    )

    @classmethod
    def from_trace(
        cls, t: ForceTrace, stop_reason: str | None, completed: bool | None
    ) -> ForceTracePublic:
        ref = None
        if t.source == "recording":
            ref = _floats(t.force_reference_N, digits=3)
        return cls(
            source=t.source,
            time_s=_floats(t.time_s, digits=3),
            force_N=_floats(t.force_N, digits=3),
            force_reference_N=ref,
            samples_total=t.samples_total,
            stop_reason=stop_reason,
            completed=completed,
            force_min_N=None if t.force_min_N is None else _floats(t.force_min_N, digits=3),
            force_max_N=None if t.force_max_N is None else _floats(t.force_max_N, digits=3),
        )


# --- post-processing ---------------------------------------------------------------------


class PostprocessUpdate(_Request):
    force_min_N: Finite | None = Field(
        None,
        ge=limits.FORCE_THRESHOLD_N.min,
        le=limits.FORCE_THRESHOLD_N.max,
        description=f"drop samples below, {limits.FORCE_THRESHOLD_N.text()}",
    )
    force_max_N: Finite | None = Field(
        None,
        gt=limits.FORCE_THRESHOLD_N.min,
        le=limits.FORCE_THRESHOLD_N.max,
        description=f"drop samples above, {limits.FORCE_THRESHOLD_N.text()}",
    )
    tolerance_mm: Finite | None = Field(
        None,
        ge=limits.TOLERANCE_MM.min,
        le=limits.TOLERANCE_MM.max,
        description=f"deviation-height tolerance, {limits.TOLERANCE_MM.text()}",
    )
    arcs: bool | None = Field(
        None, description="fit circular moves (MoveC / movec) where the contour is an arc"
    )
    arc_tolerance_mm: Finite | None = Field(
        None,
        ge=limits.TOLERANCE_MM.min,
        le=limits.TOLERANCE_MM.max,
        description=f"arc fitting tolerance, {limits.TOLERANCE_MM.text()}; default the tolerance",
    )


class PostprocessSettingsPublic(BaseModel):
    force_min_N: float
    force_max_N: float
    tolerance_mm: float
    speed_mean_mm_s: float
    speed_min_mm_s: float
    arcs: bool = False
    arc_tolerance_mm: float | None = None

    @classmethod
    def from_settings(cls, s: PostprocessSettings) -> PostprocessSettingsPublic:
        return cls(
            force_min_N=s.force_min_N,
            force_max_N=s.force_max_N,
            tolerance_mm=round(s.tolerance_m * 1e3, 9),
            speed_mean_mm_s=round(s.speed_mean_m_s * 1e3, 9),
            speed_min_mm_s=round(s.speed_min_m_s * 1e3, 9),
            arcs=s.arcs,
            arc_tolerance_mm=None if s.arc_tolerance_m is None else s.arc_tolerance_m * 1e3,
        )


def _mm_or_none(x: float | None) -> float | None:
    return None if x is None or not math.isfinite(x) else round(x * 1e3, 5)


class PostprocessPublic(BaseModel):
    samples_raw: int = Field(description="samples recorded")
    samples_filtered: int = Field(description="samples kept by the force-threshold filter")
    targets: int = Field(description="targets after deviation-height reduction")
    max_deviation_mm: float | None = Field(
        description="largest deviation of the target path from the true tool path [mm]; "
        "null for an uploaded mesh (no known truth)"
    )
    rms_deviation_mm: float | None = Field(description="RMS deviation along the path [mm]")
    mesh_max_deviation_mm: float | None = Field(
        None,
        description="largest deviation of the program from the part's walls minus the tool "
        "radius, signed inside the material [mm], every part (built-in or uploaded)",
    )
    mesh_rms_deviation_mm: float | None = Field(None, description="its RMS along the path [mm]")
    mesh_overcut_mm: float | None = Field(
        None, description="deepest the program's cutter goes into the part's walls [mm]"
    )
    mesh_air_mm: float | None = Field(
        None, description="farthest the program's cutter stays off the part's walls [mm]"
    )
    follows_taught_wall: bool | None = Field(
        None,
        description="the program follows the wall the guide points were taught on; null "
        "when the recording is out of date (the points or the cell changed after learning: "
        "it is judged by no other points)",
    )
    taught_wall: str | None = Field(None, description="the taught-wall check in words")
    problems: list[str] = Field(
        default_factory=list,
        description="what makes the program unfit to machine with (a partial run, the wrong "
        "wall, an overcut); empty when none",
    )
    moves: int | None = Field(None, description="motion instructions of the program")
    circular_moves: int | None = Field(None, description="of which circular (MoveC / movec)")
    straight_moves: int | None = Field(None, description="instructions of the straight program")
    cad_comparison: dict[str, Any] | None = Field(
        None,
        description="the program a CAD/CAM tool would make from the mesh alone (the wall "
        "offset by the tool radius, reduced to the same tolerance) and the learned one, both "
        "against the real wall: max, RMS, overcut and air [mm], where the worst error sits "
        "(work object, mm; fraction along); null when the path follows no wall of the mesh",
    )
    settings: PostprocessSettingsPublic

    @classmethod
    def from_outcome(cls, o: PostprocessOutcome) -> PostprocessPublic:
        from robomach_core.project import result_extras

        extras = result_extras(o)
        return cls(
            mesh_max_deviation_mm=extras["mesh_max_deviation_mm"],
            mesh_rms_deviation_mm=extras["mesh_rms_deviation_mm"],
            mesh_overcut_mm=extras["mesh_overcut_mm"],
            mesh_air_mm=extras["mesh_air_mm"],
            follows_taught_wall=extras["follows_taught_wall"],
            taught_wall=extras["taught_wall"],
            problems=extras["problems"],
            moves=extras["moves"],
            circular_moves=extras["circular_moves"],
            straight_moves=extras["straight_moves"],
            cad_comparison=extras.get("cad_comparison"),
            samples_raw=o.samples_raw,
            samples_filtered=o.result.samples_filtered,
            targets=len(o.result.targets),
            max_deviation_mm=_mm_or_none(o.score.max_m if o.score else None),
            rms_deviation_mm=_mm_or_none(o.score.rms_m if o.score else None),
            settings=PostprocessSettingsPublic.from_settings(o.settings),
        )


class PostprocessStatePublic(BaseModel):
    settings: PostprocessSettingsPublic = Field(description="the settings the next run uses")
    result: PostprocessPublic | None = Field(description="the last result; null before any")
    status: StageStatus = Field(
        default="none",
        description="the result is current, or stale (computed from a recording or guide "
        "points that changed since: out of date, exports refuse it), or none",
    )


# --- exports -----------------------------------------------------------------------------


class ExportCreate(_Request):
    name: str = Field(
        description="1-64 letters, digits, '_', '.', '-'; starts with a letter or digit",
        examples=["pump_v1"],
    )


class ExportPublic(BaseModel):
    name: str
    created_s: float = Field(description="Unix time")
    files: list[str]
    folder: str | None = Field(description="where the files are, relative to the data folder")

    @classmethod
    def from_info(cls, e: ExportInfo, data_dir: Path | None) -> ExportPublic:
        folder = None
        if e.folder is not None and data_dir is not None:
            folder = str(e.folder.relative_to(data_dir))
        return cls(name=e.name, created_s=e.created_s, files=e.files, folder=folder)


class ProgramLanguagePublic(BaseModel):
    """A program language of ``robomach_core.export.languages`` and whether the cell's arm is
    offered it (its controller runs it)."""

    name: str = Field(description="the {language} of GET /api/export/program/{language}")
    title: str
    files: list[str] = Field(description="the program's files")
    force_control_files: list[str] | None = Field(
        description="the force-controlled variant's files (force_control=true), if it has one"
    )
    families: list[str] = Field(description="arm families whose controllers run it")
    offered: bool = Field(description="the cell's arm runs it")


# --- projects ----------------------------------------------------------------------------


class ProjectCreate(_Request):
    name: str = Field(min_length=1, max_length=80)


class ProjectUpdate(_Request):
    name: str = Field(min_length=1, max_length=80)


class ProjectPublic(BaseModel):
    id: int
    name: str
    created_s: float = Field(description="Unix time")
    updated_s: float = Field(description="Unix time of the last change")
    is_open: bool
    notice: str = Field(
        "",
        description="what the open project's user must know, e.g. that its stored arm was "
        "refused and it opened on the default arm (empty when nothing)",
    )

    @classmethod
    def from_info(cls, p: ProjectInfo) -> ProjectPublic:
        return cls(
            id=p.id, name=p.name, created_s=p.created_s, updated_s=p.updated_s,
            is_open=p.is_open, notice=p.notice,
        )  # fmt: skip


# --- cell --------------------------------------------------------------------------------


WobjNumber = Annotated[
    float,
    Field(
        allow_inf_nan=False,
        ge=min(limits.WOBJ_POSITION_MM.min, limits.WOBJ_ROTATION_DEG.min),
        le=max(limits.WOBJ_POSITION_MM.max, limits.WOBJ_ROTATION_DEG.max),
    ),
]


class CellUpdate(_Request):
    robot: str | None = Field(
        None, description="a built-in arm (robots in GET /api/cell) or an uploaded one"
    )
    wobj_mm_deg: Annotated[list[WobjNumber], Field(min_length=3, max_length=6)] | None = Field(
        None,
        description="where the part is placed: the work-object frame x, y, z [mm] in the robot "
        f"base frame ({limits.WOBJ_POSITION_MM.text()}), then an optional rz, or rx, ry, rz "
        f"[deg] ({limits.WOBJ_ROTATION_DEG.text()}) about the fixed base axes x, then y, then "
        "z (robomach demo --wobj's numbers); 3, 4 or 6 numbers; null: the built-in placement "
        "in front of the arm. A change moves the part, sends the robot home and clears the "
        "guide points and the work-object calibration",
    )
    tool_radius_mm: Finite | None = Field(
        None, description=f"ball cutter radius [mm], {limits.TOOL_RADIUS_MM.text()}"
    )
    workpiece: str | None = Field(None, description="water_pump, block, or the uploaded mesh")
    realistic: bool | None = Field(
        None,
        description="the realistic preset: the part in the cell differs from its mesh by a "
        "fixture error and casting deviations drawn from the cell's seed (teaching uses the "
        "mesh, learning meets the real part); false: the part is its mesh",
    )


class WobjPublic(BaseModel):
    """A work-object frame in the robot base frame: x, y, z [mm], then rotations rx, ry, rz
    [deg] about the fixed base axes x, then y, then z (R = Rz Ry Rx)."""

    x_mm: float
    y_mm: float
    z_mm: float
    rx_deg: float
    ry_deg: float
    rz_deg: float

    @classmethod
    def of(cls, T_base_wobj: np.ndarray) -> WobjPublic:
        from robomach_core.teaching import mm_deg_from_transform

        v = [round(x, 4) for x in mm_deg_from_transform(T_base_wobj)]
        return cls(x_mm=v[0], y_mm=v[1], z_mm=v[2], rx_deg=v[3], ry_deg=v[4], rz_deg=v[5])


class RegistrationPublic(BaseModel):
    """An accepted work-object calibration."""

    wobj: WobjPublic = Field(description="the measured work object (the CAD placed there)")
    wobj_mm_deg: list[float] = Field(description="the same six numbers as a list")
    touches: int
    rms_mm: float = Field(description="RMS of the touches' residuals [mm]")
    max_mm: float = Field(description="largest residual [mm]")
    method: str = Field(description="the fit: point-to-plane least squares")


class CellPublic(BaseModel):
    robot: str
    tool_radius_mm: float
    workpiece: str
    workpiece_builtin: bool
    seed: int
    robots: list[str] = Field(description="robots to choose from")
    workpieces: list[str] = Field(description="built-in workpieces")
    realistic: bool = Field(False, description="the part differs from its mesh (the preset)")
    part_deviation: dict[str, Any] | None = Field(
        None, description="how the part differs from its mesh: fixture and casting (mm, deg)"
    )
    note: str = Field(
        "",
        description="what the last cell change cleared and why (a machining choice the new "
        "cell's controller cannot run); empty when nothing was",
    )
    wobj_mm_deg: list[float] | None = Field(
        None,
        description="the placement as set (3, 4 or 6 numbers, PUT /api/cell's), null for the "
        "built-in placement",
    )
    wobj: WobjPublic | None = Field(
        None, description="where the part is placed (the built-in placement when not set)"
    )
    registration: RegistrationPublic | None = Field(
        None,
        description="the accepted work-object calibration: teaching, the checks, learning's "
        "route and the CAD-only program use the CAD placed there; null: at the placement",
    )

    @classmethod
    def from_settings(
        cls,
        s: CellSettings,
        robots: list[str],
        workpieces: list[str],
        *,
        T_base_wobj: np.ndarray | None = None,
    ) -> CellPublic:
        d = s.part_deviation
        reg = s.registration
        return cls(
            realistic=d is not None,
            part_deviation=None if d is None else d.as_dict(),
            wobj_mm_deg=None if s.wobj_mm_deg is None else list(s.wobj_mm_deg),
            wobj=None if T_base_wobj is None else WobjPublic.of(T_base_wobj),
            registration=None
            if reg is None
            else RegistrationPublic(
                wobj=WobjPublic.of(reg.T_base_wobj),
                wobj_mm_deg=[round(v, 6) for v in reg.wobj_mm_deg],
                touches=len(reg.touches),
                rms_mm=round(reg.rms_mm, 4),
                max_mm=round(reg.max_mm, 4),
                method=reg.method,
            ),
            robot=s.robot,
            tool_radius_mm=round(s.tool_radius_m * 1e3, 9),
            workpiece=s.workpiece,
            workpiece_builtin=s.workpiece_builtin,
            seed=s.seed,
            robots=robots,
            workpieces=workpieces,
        )


class ErrorPublic(BaseModel):
    """Every 4xx and 503 answer."""

    detail: str = Field(description="what is wrong, in one or a few sentences")
    errors: list[dict] | None = Field(None, description="per-field problems of a request body")
