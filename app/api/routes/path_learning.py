"""Automatic path learning (a job) and its force recording."""

from __future__ import annotations

from typing import Annotated

from fastapi import APIRouter, Query, status

from app.api.routes import ERRORS, SessionDep
from app.api.schemas import FindingPublic, ForceTracePublic, JobCreated, PathLearningCreate
from app.findings import grouped_findings
from robomach_core.limits import TRACE_POINTS

router = APIRouter(prefix="/api/path-learning", tags=["path learning"], responses=ERRORS)


@router.post("", status_code=status.HTTP_202_ACCEPTED)
def start_path_learning(body: PathLearningCreate, session: SessionDep) -> JobCreated:
    """Job: follow the wall along the guide points at constant contact force and record it.
    Follow it at /api/jobs/{job_id}; the recording replaces the last one when it is done.
    422 when the wall side is "auto" and the guide points do not tell it."""
    found = session.learning.guide_findings(
        body.force_N, closed=body.closed, wall_side=body.wall_side
    )
    job_id = session.learning.start_path_learning(
        body.force_N,
        body.speed_mm_s * 1e-3,
        closed=body.closed,
        wall_side=body.wall_side,
        floor_clearance_m=body.floor_clearance_mm * 1e-3,
    )
    return JobCreated(
        job_id=job_id,
        warnings=[w.message for w in found],
        findings=[FindingPublic.from_group(g) for g in grouped_findings(found)],
    )


@router.get("/recording")
def get_recording(
    session: SessionDep,
    max_points: Annotated[
        int,
        Query(ge=TRACE_POINTS.min, le=TRACE_POINTS.max, description="decimate to this"),
    ] = 2000,
) -> ForceTracePublic:
    """Force against time for plots: live while a job runs, else the last recording."""
    rec = session.project().recording
    return ForceTracePublic.from_trace(
        session.learning.force_trace(max_points),
        rec.stop_reason if rec is not None else None,
        rec.completed if rec is not None else None,
    )
