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
async def get_state(session: SessionDep) -> StatePublic:
    """Joints, TCP pose, measured contact wrench and contact flag (live while a job runs), and
    which results of the open project are out of date.

    Async on purpose: answered on the event loop, it skips the hop to a worker thread, and it
    never waits (the snapshot does not wait for the session lock; the project is a value). The
    pendant polls it every 200 ms, 45 readers at once in the audit: while a 311k-sample
    recording post-processed, the thread hops alone pushed its p99 over 100 ms."""
    status = ProjectStatusPublic.from_project(session.project())
    return StatePublic.from_snapshot(session.robot.snapshot(wait=False), project_status=status)
