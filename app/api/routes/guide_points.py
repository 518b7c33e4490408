"""Guide points: record the current pose, list, delete, load the example."""

from __future__ import annotations

from typing import Annotated

from fastapi import APIRouter, Path, Response, status

from app.api.routes import ERRORS, SessionDep
from app.api.schemas import GuidePointPublic, JobCreated
from app.session import GuidePointEntry

router = APIRouter(prefix="/api/guide-points", tags=["guide points"], responses=ERRORS)


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
