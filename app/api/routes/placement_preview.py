"""A work-object placement being tried: the part drawn there in the 3D scene, nothing applied
(``app.session.preview``). Placing the part is ``PUT /api/cell``."""

from __future__ import annotations

from fastapi import APIRouter

from app.api.routes import ERRORS, SessionDep
from app.api.schemas import PlacementPreviewPublic, PlacementPreviewUpdate

router = APIRouter(prefix="/api/cell/placement-preview", tags=["cell"], responses=ERRORS)


def _public(session: SessionDep) -> PlacementPreviewPublic:
    tried = session.preview.values()
    return PlacementPreviewPublic(
        wobj_mm_deg=None if tried is None else list(tried),
        placed_wobj_mm_deg=list(session.preview.placed()),
    )


@router.get("")
def get_placement_preview(session: SessionDep) -> PlacementPreviewPublic:
    """The placement being tried (null when none) and where the part is placed."""
    return _public(session)


@router.put("")
def put_placement_preview(
    body: PlacementPreviewUpdate, session: SessionDep
) -> PlacementPreviewPublic:
    """Draw the part at these numbers in the 3D scene (both pages), without placing it: a cell
    change clears it, and so does ``DELETE``. 422 names a number out of range."""
    session.preview.set(body.wobj_mm_deg)
    return _public(session)


@router.delete("")
def delete_placement_preview(session: SessionDep) -> PlacementPreviewPublic:
    """Nothing tried: the part is drawn where it is placed."""
    session.preview.clear()
    return _public(session)
