"""Work-object calibration by touch: touch the real part, see the CAD registered to the
touches with its residual, accept it (or undo, touch more, start again).

As on a pendant (ABB's 3-point user frame, KUKA's base measurement): each touch is a guarded
move at the set force until the part pushes back, then back to where it started; six or more
touches on three faces (three on a top face, two on a side, one on a side across it) fix the
frame; the fit is point-to-plane least squares. Positions in mm, directions unit vectors.
"""

from __future__ import annotations

from typing import Annotated, Any

import numpy as np
from fastapi import APIRouter, Path, status
from pydantic import BaseModel, Field

from app.api.routes import ERRORS, SessionDep
from app.api.routes.cell import _public as cell_public
from app.api.schemas import CellPublic, Finite, JobCreated, Vector3, WobjPublic, _Request
from app.session.calibration import CalibrationState
from robomach_core.choices import JogFrame
from robomach_core.limits import TOUCH_OFF_FORCE_N, TOUCH_OFF_TRAVEL_MM, WOBJ_POSITION_MM
from robomach_core.teaching import MIN_TOUCHES, Touch, WobjFit

router = APIRouter(prefix="/api/cell/calibration", tags=["calibration"], responses=ERRORS)

Coordinate = Annotated[
    float, Field(allow_inf_nan=False, ge=WOBJ_POSITION_MM.min, le=WOBJ_POSITION_MM.max)
]
ForceN = Annotated[
    float, Field(allow_inf_nan=False, ge=TOUCH_OFF_FORCE_N.min, le=TOUCH_OFF_FORCE_N.max)
]
IndexPath = Annotated[int, Path(ge=0, description="the touch's index, from 0")]


class CalibrationStart(_Request):
    force_N: ForceN | None = Field(
        None,
        description=f"the touch force [N], {TOUCH_OFF_FORCE_N.text()} (default the last one, "
        f"{TOUCH_OFF_FORCE_N.default:g} at first)",
    )


class TouchCreate(_Request):
    direction: Vector3 | None = Field(
        None,
        description="touch from where the robot stands along this direction (any length) of "
        "`frame`; or give `at_wobj_mm`",
    )
    frame: JogFrame = Field(
        "base", description="the frame of `direction`: robot base, work object, or tool"
    )
    at_wobj_mm: Annotated[list[Coordinate], Field(min_length=3, max_length=3)] | None = Field(
        None,
        description="a point of the part's mesh (work-object frame [mm], as a click gives it): "
        "the robot goes to a start off that face along its normal (13 mm off a side, 8 mm above "
        "a top face) and touches along the normal",
    )
    force_N: ForceN | None = Field(None, description="the touch force [N] (default: the set one)")
    max_travel_mm: Finite | None = Field(
        None,
        gt=0.0,
        le=TOUCH_OFF_TRAVEL_MM.max,
        description="the farthest the guarded move searches [mm] (default 20, or the planned "
        "travel of a picked face)",
    )
    feature: str = Field("", max_length=80, description="what is touched, for people")


class TouchPublic(BaseModel):
    index: int
    tcp_mm: list[float] = Field(description="the ball's centre where it touched, base [mm]")
    direction: list[float] = Field(description="unit direction of the move, base frame")
    force_N: float = Field(description="contact force along the move when it stopped [N]")
    tool_radius_mm: float
    feature: str
    residual_mm: float | None = Field(
        None,
        description="its distance from the registered CAD's face minus (radius - press) [mm] "
        "(+: the CAD's face stands short of the real one); null without a fit",
    )
    face: str | None = Field(None, description="the CAD face it met, in the fit")
    surface_mm: list[float] | None = Field(
        None, description="the point of the registered CAD it met, base frame [mm]"
    )


class FitPublic(BaseModel):
    method: str = Field(description="point-to-plane least squares (iterative closest point)")
    wobj: WobjPublic = Field(description="the measured work object: the CAD placed there")
    wobj_mm_deg: list[float] = Field(description="the same six numbers as a list")
    wobj_before: WobjPublic = Field(description="the work object as placed (before)")
    moved_max_mm: float = Field(description="the farthest the fit moved a point of the CAD")
    turned_deg: float = Field(description="how far it turned the CAD")
    touches: int
    redundancy: int = Field(description="touches beyond the six a frame needs")
    rms_mm: float = Field(description="RMS of the residuals [mm]")
    max_mm: float = Field(description="largest residual [mm]")
    std_position_mm: float | None = Field(
        None, description="one-sigma uncertainty of the frame's position (null: 6 touches)"
    )
    std_rotation_deg: float | None = Field(
        None, description="one-sigma uncertainty of its rotation (null: 6 touches)"
    )
    contact_stiffness_N_mm: float = Field(
        description="the stiffness the touches' press into the part was corrected with (the "
        "post-processing setting)"
    )
    message: str

    @classmethod
    def of(cls, fit: WobjFit) -> FitPublic:
        doc = fit.document()
        return cls(
            method=doc["method"],
            wobj=WobjPublic.of(fit.T_base_wobj),
            wobj_mm_deg=doc["wobj_mm_deg"],
            wobj_before=WobjPublic.of(fit.T_base_wobj_before),
            moved_max_mm=doc["moved_max_mm"],
            turned_deg=doc["turned_deg"],
            touches=doc["touches"],
            redundancy=doc["redundancy"],
            rms_mm=doc["rms_mm"],
            max_mm=doc["max_mm"],
            std_position_mm=doc["std_position_mm"],
            std_rotation_deg=doc["std_rotation_deg"],
            contact_stiffness_N_mm=doc["contact_stiffness_N_mm"],
            message=doc["message"],
        )


class CalibrationPublic(BaseModel):
    force_N: float = Field(description="the touch force [N]")
    min_touches: int = Field(MIN_TOUCHES, description="touches a frame needs at least")
    touches: list[TouchPublic]
    fit: FitPublic | None = Field(None, description="the CAD registered to the touches")
    fit_error: str = Field("", description="why there is no fit yet (empty with one)")
    accepted: bool = Field(description="the project's work object is calibrated")

    @classmethod
    def of(cls, state: CalibrationState) -> CalibrationPublic:
        fit = state.fit
        return cls(
            force_N=round(state.force_N, 3),
            touches=[_touch(k, t, fit) for k, t in enumerate(state.touches)],
            fit=None if fit is None else FitPublic.of(fit),
            fit_error=state.fit_error,
            accepted=state.registration is not None,
        )


def _touch(k: int, touch: Touch, fit: WobjFit | None) -> TouchPublic:
    doc = touch.document()
    extra: dict[str, Any] = {}
    if fit is not None and k < len(fit.residuals_m):
        extra = {
            "residual_mm": round(float(fit.residuals_m[k]) * 1e3, 4),
            "face": fit.faces[k],
            "surface_mm": [round(float(v) * 1e3, 3) for v in fit.surface_base_m[k]],
        }
    return TouchPublic(index=k, **doc, **extra)


class PlannedTouchPublic(BaseModel):
    feature: str
    start_mm: list[float] = Field(description="where the ball's centre starts, base [mm]")
    start_wobj_mm: list[float] = Field(description="the same in the work object [mm]")
    direction: list[float] = Field(description="unit direction into the face, base frame")
    direction_wobj: list[float] = Field(description="the same in the work object")
    travel_mm: float
    aim_mm: list[float] = Field(description="the CAD point it aims at, base [mm]")


class TouchPlanPublic(BaseModel):
    touches: list[PlannedTouchPublic]
    safe_z_mm: float = Field(description="the tool travels between touches at this height")


@router.get("")
def get_calibration(session: SessionDep) -> CalibrationPublic:
    """The touches made, the CAD registered to them (or why not yet) and whether the project's
    work object is calibrated."""
    return CalibrationPublic.of(session.calibration.state())


@router.get("/plan")
def get_plan(session: SessionDep) -> TouchPlanPublic:
    """The features to touch on this part (what the example operator touches: four on the top
    face, three and two on two sides facing across each other), for a GUI to show."""
    plan = session.calibration.plan()
    T = session.robot.workpiece.cad().T_base_wobj
    return TouchPlanPublic(
        touches=[PlannedTouchPublic(**t.document(T)) for t in plan.touches],
        safe_z_mm=round(plan.safe_z_m * 1e3, 3),
    )


@router.post("/start")
def start(body: CalibrationStart, session: SessionDep) -> CalibrationPublic:
    """Start again: no touches, and the touch force (the accepted calibration stays until a
    new one is accepted)."""
    session.calibration.clear(force_N=body.force_N)
    return CalibrationPublic.of(session.calibration.state())


@router.post("/touches")
def add_touch(body: TouchCreate, session: SessionDep) -> CalibrationPublic:
    """Touch the part: a guarded move at the touch force from where the robot stands along
    ``direction``, or from the start off a picked face (``at_wobj_mm``), recorded, and back to
    where it started. 409 when nothing was touched within the travel (the robot stays where
    the search ended), a limit stopped it, or the robot is busy."""
    session.calibration.touch(
        direction=None if body.direction is None else np.asarray(body.direction, dtype=float),
        frame=body.frame,
        at_wobj_m=None if body.at_wobj_mm is None else np.asarray(body.at_wobj_mm) * 1e-3,
        force_N=body.force_N,
        max_travel_m=None if body.max_travel_mm is None else body.max_travel_mm * 1e-3,
        feature=body.feature,
    )
    return CalibrationPublic.of(session.calibration.state())


@router.delete("/touches/last")
def undo_touch(session: SessionDep) -> CalibrationPublic:
    """Undo the last touch (404 when there is none)."""
    session.calibration.undo()
    return CalibrationPublic.of(session.calibration.state())


@router.delete("/touches/{index}")
def delete_touch(index: IndexPath, session: SessionDep) -> CalibrationPublic:
    """Delete one touch; later ones move down by one."""
    session.calibration.delete(index)
    return CalibrationPublic.of(session.calibration.state())


@router.delete("/touches")
def clear_touches(session: SessionDep) -> CalibrationPublic:
    """Delete every touch."""
    session.calibration.clear()
    return CalibrationPublic.of(session.calibration.state())


@router.post("/auto", status_code=status.HTTP_202_ACCEPTED)
def touch_automatically(body: CalibrationStart, session: SessionDep) -> JobCreated:
    """Job: the example operator touches the planned features (GET /plan); the touches replace
    the ones made. Follow it at /api/jobs/{job_id}; the robot is busy until it ends."""
    return JobCreated(job_id=session.calibration.start_auto(body.force_N))


@router.post("/accept")
def accept(session: SessionDep) -> CellPublic:
    """The fit becomes the project's work object: the cell is rebuilt with the CAD where the
    touches found it (the robot stays where it stands); what was learned becomes out of date.
    422 when the touches do not fix a frame (the message says what to touch)."""
    session.calibration.accept()
    return cell_public(session)


@router.delete("")
def remove(session: SessionDep) -> CellPublic:
    """Drop the accepted calibration: the CAD goes back to the placement (the touches stay)."""
    session.calibration.remove()
    return cell_public(session)
