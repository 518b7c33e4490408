"""Projects as files: import a ``project.npz`` from ``robomach demo`` / ``robomach machine``,
download the open project as one."""

from __future__ import annotations

from typing import Annotated

from fastapi import APIRouter, HTTPException, Query, Response, UploadFile, status
from starlette.concurrency import run_in_threadpool

from app.api.routes import ERRORS, SessionDep, download
from app.api.schemas import ProjectPublic
from app.session.project_file import export_project, import_project

router = APIRouter(prefix="/api/projects", tags=["projects"], responses=ERRORS)

MAX_PROJECT_FILE_BYTES = 200_000_000
UPLOAD_CHUNK_BYTES = 1024 * 1024


@router.post(
    "/import",
    status_code=status.HTTP_201_CREATED,
    max_body_size=MAX_PROJECT_FILE_BYTES + 1024 * 1024,
    responses={413: {"description": "the file is larger than the upload limit"}},
)
async def import_project_file(
    file: UploadFile,
    session: SessionDep,
    name: Annotated[str, Query(min_length=1, max_length=64, description="the new project's name")],
) -> ProjectPublic:
    """A new project from a ``project.npz`` (multipart field ``file``), opened at once: the
    cell, guide points, recording, post-processing and process settings it holds."""
    chunks, size = [], 0
    while chunk := await file.read(UPLOAD_CHUNK_BYTES):
        size += len(chunk)
        if size > MAX_PROJECT_FILE_BYTES:
            raise HTTPException(
                status.HTTP_413_REQUEST_ENTITY_TOO_LARGE,
                f"{file.filename}: the upload exceeds {MAX_PROJECT_FILE_BYTES / 1e6:g} MB",
            )
        chunks.append(chunk)
    info = await run_in_threadpool(import_project, session, b"".join(chunks), name)
    return ProjectPublic.from_info(info)


@router.get(
    "/current/project.npz",
    response_class=Response,
    responses={200: {"content": {"application/octet-stream": {}}}},
)
def download_project_file(session: SessionDep) -> Response:
    """The open project as ``project.npz`` (``robomach machine --from`` reads it)."""
    return download(export_project(session), "project.npz")
