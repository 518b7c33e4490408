"""Lead-through (/api/leadthrough): the compliance selection, pushes, force-control jogging and
going home; the guarded touch-off move, letting go of a motion, and the tool's view."""

from __future__ import annotations

import math
from typing import Literal

import numpy as np
from fastapi import APIRouter
from pydantic import BaseModel, Field

from app.api.routes import ERRORS, SessionDep
from app.api.schemas import (
    CompliancePublic,
    ComplianceUpdate,
    Finite,
    JogCreate,
    ProjectStatusPublic,
    PushCreate,
    StatePublic,
    _floats,
    _Request,
)
from robomach_core import limits
from robomach_core.choices import JogFrame, NearestFace, TouchAxis

TouchDirection = Literal[1, -1]
router = APIRouter(prefix="/api/leadthrough", tags=["lead-through"], responses=ERRORS)


@router.get("/compliance")
def get_compliance(session: SessionDep) -> CompliancePublic:
    """The compliant axes and their frame."""
    return CompliancePublic.from_selection(session.robot.selection)


@router.put("/compliance")
def put_compliance(body: ComplianceUpdate, session: SessionDep) -> CompliancePublic:
    """Select the compliant axes; the others are stiff."""
    return CompliancePublic.from_selection(session.robot.select(body.axes, body.frame))


@router.post("/push")
def push(body: PushCreate, session: SessionDep) -> StatePublic:
    """Push the tool with a constant force (and torque) for a while; answers the new state."""
    wrench = np.array(body.force_N + body.torque_Nm, dtype=float)
    return StatePublic.from_snapshot(session.teach.push(wrench, body.duration_s))


@router.post("/jog")
def jog(body: JogCreate, session: SessionDep) -> StatePublic:
    """Force-control jogging: a step along (mm) or about (deg) an axis of the tool, base or
    work-object frame, at wall-clock speed."""
    to_si = math.radians if body.axis.startswith("r") else (lambda v: v * 1e-3)
    speed = None if body.speed is None else to_si(body.speed)
    snapshot = session.teach.jog(body.axis, to_si(body.step), frame=body.frame, speed=speed)
    return StatePublic.from_snapshot(snapshot)


@router.post("/home")
def home(session: SessionDep) -> StatePublic:
    """Reset the robot to its home pose (a simulation reset, not a move)."""
    return StatePublic.from_snapshot(session.learning.go_home())


# --- quick teaching ---


class TouchOffCreate(_Request):
    axis: TouchAxis = Field(description="axis of the frame to move along")
    direction: TouchDirection = Field(description="+1 or -1: which way along the axis")
    force_N: Finite = Field(
        default=limits.TOUCH_OFF_FORCE_N.default_value(),
        ge=limits.TOUCH_OFF_FORCE_N.min,
        le=limits.TOUCH_OFF_FORCE_N.max,
        description="contact force to stop at [N]",
    )
    max_travel_mm: Finite = Field(
        default=limits.TOUCH_OFF_TRAVEL_MM.default_value(),
        gt=limits.TOUCH_OFF_TRAVEL_MM.min,
        le=limits.TOUCH_OFF_TRAVEL_MM.max,
        description="give up after this travel [mm]",
    )
    frame: JogFrame = Field(
        default="base", description="frame of the axis: robot base, tool or work object"
    )


class ToolViewPublic(BaseModel):
    gap_mm: float = Field(description="distance of the cutter to the nearest face of the part "
                          "[mm]; negative while in contact (the penetration)")  # fmt: skip
    normal: list[float] = Field(description="unit vector from that face towards the cutter, base")
    force_N: list[float] = Field(description="measured contact force at the TCP, base axes [N]")
    force_magnitude_N: float = Field(description="|force| [N]")
    table_gap_mm: float = Field(description="height of the cutter above the table [mm]")
    in_contact: bool
    nearest_face: NearestFace = Field("wall", description="what the nearest face of the part is")
    wall_gap_mm: float | None = Field(
        None,
        description="gap of the cutter to the nearest wall at the tool's height [mm] (across, "
        "as a touch-off towards it goes); null above the part",
    )


@router.post("/touch-off")
def touch_off(body: TouchOffCreate, session: SessionDep) -> StatePublic:
    """Guarded move: go along an axis until the wall pushes back with ``force_N``, then stay
    there in contact (record the guide point next). 409 when nothing is touched within
    ``max_travel_mm`` or supervision refuses the motion (the message says why)."""
    snapshot = session.teach.touch_off(
        body.axis, body.direction, body.force_N, body.max_travel_mm * 1e-3, frame=body.frame
    )
    status = ProjectStatusPublic.from_project(session.project())
    return StatePublic.from_snapshot(snapshot, project_status=status)


@router.post("/stop", status_code=204)
def stop(session: SessionDep) -> None:
    """Let go: the running push, jog or touch-off stops within one control period."""
    session.teach.stop()


@router.get("/tool")
def tool_view(session: SessionDep) -> ToolViewPublic:
    """The gap from the cutter to the nearest face (and which kind it is) and to the nearest
    wall at the tool's height, the contact force and the table clearance."""
    v = session.teach.tool_view()
    return ToolViewPublic(
        gap_mm=round(v.gap_m * 1e3, 4),
        normal=_floats(v.normal, digits=5),
        force_N=_floats(v.force_N, digits=3),
        force_magnitude_N=round(float((v.force_N @ v.force_N) ** 0.5), 3),
        table_gap_mm=round(v.table_gap_m * 1e3, 3),
        in_contact=v.in_contact,
        nearest_face=v.face,
        wall_gap_mm=None if v.wall_gap_m is None else round(v.wall_gap_m * 1e3, 4),
    )
