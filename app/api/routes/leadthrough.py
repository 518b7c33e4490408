"""Lead-through: compliance selection, pushes, force-control jogging."""

from __future__ import annotations

import math

import numpy as np
from fastapi import APIRouter

from app.api.routes import ERRORS, SessionDep
from app.api.schemas import CompliancePublic, ComplianceUpdate, JogCreate, PushCreate, StatePublic

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
