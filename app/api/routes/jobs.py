"""Background jobs: status, progress, cancel (example lead-through, path learning, studies)."""

from __future__ import annotations

from fastapi import APIRouter

from app.api.routes import ERRORS, SessionDep
from app.api.schemas import JobPublic

router = APIRouter(prefix="/api/jobs", tags=["jobs"], responses=ERRORS)


@router.get("")
def list_jobs(session: SessionDep) -> list[JobPublic]:
    """Recent jobs, oldest first."""
    return [JobPublic.from_info(j) for j in session.jobs.list()]


@router.get("/{job_id}")
def get_job(job_id: str, session: SessionDep) -> JobPublic:
    """Status, progress (0-1) and error of a job."""
    return JobPublic.from_info(session.jobs.get(job_id))


@router.post("/{job_id}/cancel")
def cancel_job(job_id: str, session: SessionDep) -> JobPublic:
    """Cancel a queued or running job; the robot stays where the job left it."""
    return JobPublic.from_info(session.jobs.cancel(job_id))
