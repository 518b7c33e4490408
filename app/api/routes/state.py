"""Health and the robot state."""

from __future__ import annotations

from fastapi import APIRouter

from app.api.routes import SessionDep
from app.api.schemas import HealthPublic, StatePublic

router = APIRouter(prefix="/api", tags=["state"])


@router.get("/health")
def health() -> HealthPublic:
    """Liveness: answers as soon as the server accepts requests."""
    return HealthPublic()


@router.get("/state")
def get_state(session: SessionDep) -> StatePublic:
    """Joints, TCP pose, measured contact wrench and contact flag (live while a job runs)."""
    return StatePublic.from_snapshot(session.snapshot())
