"""Post-processing: force-threshold filter and deviation-height reduction."""

from __future__ import annotations

from fastapi import APIRouter

from app.api.routes import ERRORS, SessionDep
from app.api.schemas import (
    PostprocessPublic,
    PostprocessSettingsPublic,
    PostprocessStatePublic,
    PostprocessUpdate,
)

router = APIRouter(prefix="/api/postprocess", tags=["post-processing"], responses=ERRORS)


@router.post("")
def run_postprocess(body: PostprocessUpdate, session: SessionDep) -> PostprocessPublic:
    """Filter and reduce the last recording (omitted settings keep their value)."""
    outcome = session.learning.run_postprocess(
        force_min_N=body.force_min_N,
        force_max_N=body.force_max_N,
        tolerance_m=None if body.tolerance_mm is None else body.tolerance_mm * 1e-3,
        arcs=body.arcs,
        arc_tolerance_m=None if body.arc_tolerance_mm is None else body.arc_tolerance_mm * 1e-3,
    )
    return PostprocessPublic.from_outcome(outcome)


@router.get("")
def get_postprocess(session: SessionDep) -> PostprocessStatePublic:
    """The settings and the last result (null before any)."""
    outcome = session.project().processed
    return PostprocessStatePublic(
        settings=PostprocessSettingsPublic.from_settings(session.project().post_settings),
        result=None if outcome is None else PostprocessPublic.from_outcome(outcome),
        status=session.project().status()["postprocess"],
    )
