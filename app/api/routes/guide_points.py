"""Guide points (/api/guide-points): record the robot's pose as one, list, delete, load the
example; teach one by pointing at the part (the robot goes there); propose the guide points of
a whole wall, edit them and accept them before learning; the pointing settings.

Points and normals are in the work-object frame in mm, as a click in the workbench gives them.
The /proposal and /pointing routes come before /{index}: they must not be read as an index.
"""

from __future__ import annotations

from typing import Annotated, Literal

import numpy as np
from fastapi import APIRouter, Path, Response, status
from pydantic import BaseModel, Field

from app.api.routes import ERRORS, SessionDep
from app.api.schemas import Finite, GuidePointPublic, JobCreated, Vector3, _floats, _Request
from app.session import GuidePointEntry
from robomach_core.choices import ClickMode
from robomach_core.limits import MACHINING_HEIGHT_MM, WALL_GAP_MM, WOBJ_POSITION_MM
from robomach_core.teaching.pointing import GuideProposal, ProposedPoint

router = APIRouter(prefix="/api/guide-points", tags=["guide points"], responses=ERRORS)

# A point in the work-object frame: within the work object's own range (the largest arms).
Coordinate = Annotated[
    float, Field(allow_inf_nan=False, ge=WOBJ_POSITION_MM.min, le=WOBJ_POSITION_MM.max)
]
PointMm = Annotated[list[Coordinate], Field(min_length=3, max_length=3)]

WALL_DRAWN_POINTS = 600  # the proposal's wall is sent decimated to about this many points
IndexPath = Annotated[int, Path(ge=0, description="the proposed point's index, from 0")]


class SurfacePointCreate(_Request):
    point_mm: PointMm = Field(description="a point on the part's wall, work-object frame [mm]")
    normal: Vector3 | None = Field(
        default=None,
        description="the surface normal there (out of the material, any length); default: "
        "the normal of the nearest face of the mesh",
    )


class FromSurfaceCreate(SurfacePointCreate):
    index: int | None = Field(
        default=None,
        ge=0,
        description="replace this guide point (from 0) instead of adding one: drag to adjust",
    )


class PointingSettingsUpdate(_Request):
    gap_mm: Finite | None = Field(
        default=None,
        ge=WALL_GAP_MM.min,
        le=WALL_GAP_MM.max,
        description=f"gap between the cutter and the wall [mm], {WALL_GAP_MM.text()}",
    )
    height_above_floor_mm: Finite | None = Field(
        default=None,
        ge=MACHINING_HEIGHT_MM.min,
        le=MACHINING_HEIGHT_MM.max,
        description="the TCP's height above the floor where a picked point's own height "
        "cannot be kept (the cutter would touch the floor, the spindle the part, or the "
        f"cutter miss the wall) [mm], {MACHINING_HEIGHT_MM.text()}",
    )
    click_mode: ClickMode | None = Field(
        default=None,
        description="what a click on the part in the 3-D scene does: propose the wall's guide "
        "points, teach a point, move the selected point there, touch the face clicked (work-"
        "object calibration: /api/cell/calibration), or nothing",
    )


class PointingSettingsPublic(BaseModel):
    gap_mm: float
    height_above_floor_mm: float
    click_mode: ClickMode
    proposal_points: int = Field(
        0,
        description="how many guide points are proposed (0: none; GET /proposal answers 404 "
        "then): a page reads this before it asks for the proposal",
    )


class ProposedPointPublic(BaseModel):
    index: int = Field(description="from 0; G1 is index 0")
    position_mm: list[float] = Field(description="TCP position, base frame [mm]")
    position_wobj_mm: list[float] = Field(description="TCP position, work-object frame [mm]")
    quaternion_wxyz: list[float]
    kind: Literal["run", "outside corner", "wall end", "added", "taught"] = Field(
        description="why it is there: a straight run, an outside corner, an end of an open "
        "wall, or added where a leg would cut towards the wall"
    )
    reach: Literal["ok", "near", "unreachable"] = Field(
        description="the arm reaches it (ok), near a limit (near), or not"
    )
    message: str = Field(description="what is near or wrong there; empty when ok")

    @classmethod
    def of(cls, k: int, p: ProposedPoint) -> ProposedPointPublic:
        from robomach_core.transforms import quaternion_from_matrix

        return cls(
            index=k,
            position_mm=_floats(p.T_base_tcp[:3, 3], 1e3, 3),
            position_wobj_mm=_floats(p.position_wobj_m, 1e3, 3),
            quaternion_wxyz=_floats(quaternion_from_matrix(p.T_base_tcp[:3, :3]), digits=7),
            kind=p.kind,
            reach=p.reach,
            message=p.message,
        )


class ProposalPublic(BaseModel):
    points: list[ProposedPointPublic]
    closed: bool = Field(description="learn a closed contour (false: an open wall)")
    wall_side: Literal["left", "right"] = Field(description="the side path learning uses")
    height_above_floor_mm: float = Field(
        description="the points' height above the floor under each [mm]: the picked point's "
        "own, or where the notes say why it changed"
    )
    height_wobj_mm: float = Field(description="the TCP's height at G1, work-object z [mm]")
    floor_wobj_mm: float = Field(description="the floor under G1, work-object z [mm]")
    floor_tilt_deg: float = Field(
        description="the floor's tilt from the work object's x-y plane [deg]: the wall is cut "
        "parallel to the floor"
    )
    wall_length_mm: float
    wall_wobj_mm: list[list[float]] = Field(
        description="the wall followed at the machining height, x-y-z points in the "
        "work-object frame [mm] (decimated)"
    )
    notes: list[str] = Field(
        description="what was changed or needs a look: a height that could not be kept and "
        "why, an open wall, a centred tool, a leg that leaves the wall"
    )

    @classmethod
    def of(cls, p: GuideProposal) -> ProposalPublic:
        from robomach_core.teaching.pointing import proposal_summary

        wall = p.wall_wobj_m()
        step = max(1, len(wall) // WALL_DRAWN_POINTS)
        drawn = wall[::step]
        if p.closed:
            drawn = np.vstack([drawn, wall[:1]])
        summary = proposal_summary(p)
        up = float(p.pick.T_wobj_floor[2, 2])
        return cls(
            points=[ProposedPointPublic.of(k, q) for k, q in enumerate(p.points)],
            closed=p.closed,
            wall_side=p.wall_side,
            height_above_floor_mm=summary["height_above_floor_mm"],
            height_wobj_mm=summary["height_wobj_mm"],
            floor_wobj_mm=round(summary["height_wobj_mm"] - p.height_above_floor_m * 1e3 * up, 3),
            floor_tilt_deg=summary["floor_tilt_deg"],
            wall_length_mm=summary["wall_length_mm"],
            wall_wobj_mm=[_floats(xyz, 1e3, 3) for xyz in drawn],
            notes=list(p.notes),
        )


class TaughtPointPublic(BaseModel):
    guide_point: GuidePointPublic
    planned: ProposedPointPublic = Field(description="where the tool was sent")
    reached: bool = Field(description="the tool stopped at the planned place")
    force_N: float = Field(description="contact force where it stopped [N]")
    notice: str = Field(
        description="what to know: the height changed from the picked point's and why, "
        "stopped by contact (the part is not where its mesh is), centred in a narrow groove, "
        "near a limit; empty when all went as planned"
    )


def _si(v: list[float] | None) -> np.ndarray | None:
    return None if v is None else np.asarray(v, dtype=float)


@router.post("/from-surface", status_code=status.HTTP_201_CREATED)
def from_surface(body: FromSurfaceCreate, session: SessionDep) -> TaughtPointPublic:
    """Click to teach: the tool goes beside the wall at the picked point (the set gap off it,
    on the free side, at the point's height when the tool can work there, else changed with
    the reason in ``notice``; the job's tool orientation) by a supervised motion, and the
    point is recorded there (or replaces ``index``). 422 off a wall (a floor, a top, the
    air) or between two walls (both named), 409 when a limit or the part stops the motion."""
    point = np.asarray(body.point_mm, dtype=float) * 1e-3
    taught = session.pointing.teach_at_surface(point, _si(body.normal), replace_index=body.index)
    from app.session import GuidePointEntry

    return TaughtPointPublic(
        guide_point=GuidePointPublic.from_entry(GuidePointEntry(taught.entry.index,
                                                                taught.entry.point)),
        planned=ProposedPointPublic.of(taught.entry.index, taught.planned),
        reached=taught.arrival.reached,
        force_N=round(taught.arrival.force_N, 3),
        notice=taught.notice,
    )  # fmt: skip


@router.post("/propose")
def propose(body: SurfacePointCreate, session: SessionDep) -> ProposalPublic:
    """Propose guide points for the whole wall through the picked point (nothing moves):
    fewest that bracket every corner, one at each outside corner, the set gap off the wall at
    the point's height above the floor under each (the wall is cut parallel to the floor;
    ``notes`` say when the height changed and why), each with its reachability. 422 off a
    wall or between two walls. It replaces a pending proposal; accept it with POST
    /api/guide-points/proposal/accept."""
    point = np.asarray(body.point_mm, dtype=float) * 1e-3
    return ProposalPublic.of(session.pointing.propose(point, _si(body.normal)))


@router.get("/proposal")
def get_proposal(session: SessionDep) -> ProposalPublic:
    """The pending proposal (404 when there is none: a cell change drops it)."""
    from app.session import NotFoundError

    proposal = session.pointing.proposal()
    if proposal is None:
        raise NotFoundError("no proposed guide points: POST /api/guide-points/propose first")
    return ProposalPublic.of(proposal)


class ProposedPointUpdate(_Request):
    point_mm: PointMm = Field(
        description="where to move the point, work-object frame [mm]: it slides to the "
        "nearest place beside the wall"
    )


@router.patch("/proposal/points/{index}")
def move_proposed(
    index: IndexPath, body: ProposedPointUpdate, session: SessionDep
) -> ProposalPublic:
    """Move a proposed point along the wall (it stays the gap off it)."""
    point = np.asarray(body.point_mm, dtype=float) * 1e-3
    return ProposalPublic.of(session.pointing.move_proposed(index, point))


@router.delete("/proposal/points/{index}")
def delete_proposed(index: IndexPath, session: SessionDep) -> ProposalPublic:
    """Delete a proposed point."""
    return ProposalPublic.of(session.pointing.delete_proposed(index))


@router.delete("/proposal", status_code=status.HTTP_204_NO_CONTENT)
def discard_proposal(session: SessionDep) -> Response:
    """Drop the pending proposal."""
    session.pointing.discard()
    return Response(status_code=status.HTTP_204_NO_CONTENT)


@router.post("/proposal/accept", status_code=status.HTTP_202_ACCEPTED)
def accept_proposal(session: SessionDep) -> JobCreated:
    """Job: the operator leads the robot by pushes to each proposed point and touches the
    wall there (not at outside corners); the recorded points replace the guide points, and
    path learning follows the proposal's wall side. Follow it at /api/jobs/{job_id}."""
    return JobCreated(job_id=session.pointing.accept())


@router.get("/pointing")
def get_pointing(session: SessionDep) -> PointingSettingsPublic:
    """The gap to the wall and the height above the floor of taught and proposed points, what
    a click on the part does, and how many points are proposed."""
    s = session.pointing.settings
    proposal = session.pointing.proposal()
    return PointingSettingsPublic(
        gap_mm=round(s.gap_m * 1e3, 4),
        height_above_floor_mm=round(s.height_above_floor_m * 1e3, 4),
        click_mode=session.pointing.click_mode,
        proposal_points=0 if proposal is None else len(proposal.points),
    )


@router.put("/pointing")
def put_pointing(body: PointingSettingsUpdate, session: SessionDep) -> PointingSettingsPublic:
    """Change the gap or the height (omitted ones stay)."""
    session.pointing.set_settings(
        gap_m=None if body.gap_mm is None else body.gap_mm * 1e-3,
        height_above_floor_m=None
        if body.height_above_floor_mm is None
        else body.height_above_floor_mm * 1e-3,
        click_mode=body.click_mode,
    )
    return get_pointing(session)


# --- the guide points themselves (after the paths above: {index} is any other segment) ---


@router.get("")
def list_guide_points(session: SessionDep) -> list[GuidePointPublic]:
    """Every guide point in order."""
    return [
        GuidePointPublic.from_entry(GuidePointEntry(i, p))
        for i, p in enumerate(list(session.project().guide_points))
    ]


@router.post("", status_code=status.HTTP_201_CREATED)
def record_guide_point(session: SessionDep) -> GuidePointPublic:
    """Record the robot's current pose as the next guide point."""
    return GuidePointPublic.from_entry(session.record_guide_point())


@router.delete("/{index}", status_code=status.HTTP_204_NO_CONTENT)
def delete_guide_point(
    index: Annotated[int, Path(description="from 0")], session: SessionDep
) -> Response:
    """Delete one guide point; the later ones move down by one."""
    session.delete_guide_point(index)
    return Response(status_code=status.HTTP_204_NO_CONTENT)


@router.delete("", status_code=status.HTTP_204_NO_CONTENT)
def delete_all_guide_points(session: SessionDep) -> Response:
    """Delete every guide point."""
    session.clear_guide_points()
    return Response(status_code=status.HTTP_204_NO_CONTENT)


@router.post("/example", status_code=status.HTTP_202_ACCEPTED)
def load_example(session: SessionDep) -> JobCreated:
    """Job: a scripted operator leads the robot by pushes to the example guide points of the
    built-in workpiece (they replace the guide points). Follow it at /api/jobs/{job_id}."""
    return JobCreated(job_id=session.learning.start_example())
