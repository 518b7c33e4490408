"""Health and the robot state."""

from __future__ import annotations

from fastapi import APIRouter, Request

from app.api.routes import SessionDep
from app.api.schemas import HealthPublic, ProjectStatusPublic, StatePublic, WorkbenchPublic

router = APIRouter(prefix="/api", tags=["state"])


@router.get("/health")
async def health() -> HealthPublic:
    """Liveness: answers as soon as the server accepts requests. Async on purpose: it runs on
    the event loop, so it never queues for a worker thread behind blocked or slow routes."""
    return HealthPublic()


@router.get("/workbench")
def get_workbench(request: Request) -> WorkbenchPublic:
    """Where the viser 3D workbench listens, so the pendant page can embed it."""
    return WorkbenchPublic(viser_port=request.app.state.settings.viser_port)


@router.get("/state")
def get_state(session: SessionDep) -> StatePublic:
    """Joints, TCP pose, measured contact wrench and contact flag (live while a job runs), and
    which results of the open project are out of date."""
    status = ProjectStatusPublic.from_project(session.project())
    return StatePublic.from_snapshot(session.snapshot(), project_status=status)
