"""The cell: robot, tool radius, workpiece (built-in or an uploaded mesh) and where it is
placed (the work object); its calibration by touch is ``calibration.py``'s."""

from __future__ import annotations

from typing import Any

from fastapi import APIRouter, HTTPException, UploadFile, status
from starlette.concurrency import run_in_threadpool

from app.api.routes import ERRORS, SessionDep, SettingsDep
from app.api.schemas import CellPublic, CellUpdate
from robomach_core.cell import ROBOT_NAMES
from robomach_core.part import MAX_MESH_BYTES, WORKPIECE_NAMES

router = APIRouter(prefix="/api/cell", tags=["cell"], responses=ERRORS)

UPLOAD_CHUNK_BYTES = 1024 * 1024
# The body may hold the largest mesh plus the multipart headers; the handler applies the
# server's own (smaller or equal) limit to the file itself.
UPLOAD_BODY_LIMIT_BYTES = MAX_MESH_BYTES + 1024 * 1024


def _public(session: SessionDep) -> CellPublic:
    view = session.view()
    cell = view.project.cell
    uploaded = [] if cell.robot in ROBOT_NAMES else [cell.robot]  # the user's own arm
    part = view.cell.workpiece
    placed = part.unregistered if part.unregistered is not None else part.cad()
    public = CellPublic.from_settings(
        cell, [*ROBOT_NAMES, *uploaded], list(WORKPIECE_NAMES), T_base_wobj=placed.T_base_wobj
    )
    public.note = session.cell_note()
    return public


@router.get("")
def get_cell(session: SessionDep) -> CellPublic:
    """The cell settings and the choices."""
    return _public(session)


@router.put("")
def put_cell(body: CellUpdate, session: SessionDep) -> CellPublic:
    """Change robot, tool radius, workpiece, its placement (``wobj_mm_deg``; null: the
    built-in one) or the realistic preset (omitted ones stay). A change sends the robot home
    and clears the guide points (poses in the old cell); moving or changing the part also
    drops its work-object calibration. The recording and results stay, marked out of date."""
    extra: dict[str, Any] = {}
    if body.realistic is not None:
        from robomach_core.part import PartDeviation

        seed = session.project().cell.seed
        extra["part_deviation"] = PartDeviation.realistic(seed) if body.realistic else None
    if "wobj_mm_deg" in body.model_fields_set:  # null is a value: the built-in placement
        extra["wobj_mm_deg"] = None if body.wobj_mm_deg is None else tuple(body.wobj_mm_deg)
    session.set_cell(
        robot=body.robot,
        tool_radius_m=None if body.tool_radius_mm is None else body.tool_radius_mm * 1e-3,
        workpiece=body.workpiece,
        **extra,
    )
    return _public(session)


@router.post(
    "/workpiece",
    max_body_size=UPLOAD_BODY_LIMIT_BYTES,
    responses={413: {"description": "the file is larger than the upload limit"}},
)
async def upload_workpiece(
    file: UploadFile, session: SessionDep, settings: SettingsDep
) -> CellPublic:
    """Upload a workpiece mesh (STL, OBJ or PLY, in mm; multipart field ``file``) within the
    upload limit (50 MB by default, else 413) and 500 000 triangles (else 422). Clears the
    guide points, recording and result like PUT /api/cell."""
    limit = settings.max_upload_bytes
    chunks, size = [], 0
    while chunk := await file.read(UPLOAD_CHUNK_BYTES):
        size += len(chunk)
        if size > limit:
            raise HTTPException(
                status.HTTP_413_REQUEST_ENTITY_TOO_LARGE,
                f"{file.filename}: the upload exceeds the {limit / 1e6:g} MB limit",
            )
        chunks.append(chunk)
    data = b"".join(chunks)
    if not data:
        raise HTTPException(status.HTTP_422_UNPROCESSABLE_ENTITY, "the uploaded file is empty")
    await run_in_threadpool(session.upload_workpiece, data, file.filename or "uploaded.stl")
    return _public(session)
