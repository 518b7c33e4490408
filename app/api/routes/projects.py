"""Projects (/api/projects): list, create, open, rename, delete (each holds a cell and its
work); the open project's status and process settings; projects as files: import a
``project.npz`` from ``robomach demo`` / ``robomach machine``, download the open project as
one."""

from __future__ import annotations

from typing import Annotated

from fastapi import APIRouter, HTTPException, Path, Query, Response, UploadFile, status
from starlette.concurrency import run_in_threadpool

from app.api.routes import ERRORS, SessionDep, StudiesDep, download
from app.api.schemas import (
    ProcessSettingsFromStudies,
    ProcessSettingsPublic,
    ProcessSettingsUpdate,
    ProjectCreate,
    ProjectPublic,
    ProjectStatusPublic,
    ProjectUpdate,
)
from robomach_core import project as core

router = APIRouter(prefix="/api/projects", tags=["projects"], responses=ERRORS)

MAX_PROJECT_FILE_BYTES = 200_000_000
UPLOAD_CHUNK_BYTES = 1024 * 1024

ProjectId = Annotated[int, Path(ge=1, le=2**63 - 1, description="the project's id")]


@router.get("")
def list_projects(session: SessionDep) -> list[ProjectPublic]:
    """Every project, most recently changed first."""
    return [ProjectPublic.from_info(p) for p in session.projects.list_projects()]


@router.get("/current")
def current_project(session: SessionDep) -> ProjectPublic:
    """The open project."""
    return ProjectPublic.from_info(session.current_project())


@router.get("/current/status")
def project_status(session: SessionDep) -> ProjectStatusPublic:
    """Per stage of the open project: none, current or stale (out of date), with reasons."""
    return ProjectStatusPublic.from_project(session.project())


@router.get("/current/process-settings")
def get_process_settings(session: SessionDep) -> ProcessSettingsPublic:
    """The CMRR and compensation settings the exported program carries (null: none)."""
    project = session.project()
    return ProcessSettingsPublic(
        cmrr=core.cmrr_document(project), compensation=core.compensation_document(project)
    )


@router.put("/current/process-settings")
def put_process_settings(body: ProcessSettingsUpdate, session: SessionDep) -> ProcessSettingsPublic:
    """Choose the CMRR controller (``cmrr_settings.json`` of one controller, e.g. from
    ``GET /api/cmrr/settings?controller=NAME``) and the compensation settings
    (``compensation_settings.json``); RAPID exports then carry them."""
    from robomach_core.cmrr import settings_from_dict as cmrr_from_dict
    from robomach_core.stiffness.settings import settings_from_dict as compensation_from_dict

    cmrr = None if body.cmrr is None else cmrr_from_dict(body.cmrr)
    compensation = None if body.compensation is None else compensation_from_dict(body.compensation)
    project = session.programs.set_process_settings(cmrr=cmrr, compensation=compensation)
    return ProcessSettingsPublic(
        cmrr=core.cmrr_document(project), compensation=core.compensation_document(project)
    )


@router.post("/current/process-settings/from-studies")
def process_settings_from_studies(
    body: ProcessSettingsFromStudies, session: SessionDep, studies: StudiesDep
) -> ProcessSettingsPublic:
    """Adopt the open project's last CMRR study (its controller, or ``controller`` after a
    comparison) and compensation identification as the settings RAPID exports carry."""
    from app.session.process_settings import settings_from_studies

    project = session.project()
    cmrr, compensation = settings_from_studies(
        studies, controller=body.controller, cmrr=body.cmrr, compensation=body.compensation
    )
    project = session.programs.set_process_settings(
        cmrr=cmrr if body.cmrr else project.cmrr,
        compensation=compensation if body.compensation else project.compensation,
    )
    return ProcessSettingsPublic(
        cmrr=core.cmrr_document(project), compensation=core.compensation_document(project)
    )


@router.post("", status_code=status.HTTP_201_CREATED)
def create_project(body: ProjectCreate, session: SessionDep) -> ProjectPublic:
    """A new project with the default cell; it is opened at once."""
    return ProjectPublic.from_info(session.projects.create_project(body.name))


@router.post("/{project_id}/open")
def open_project(project_id: ProjectId, session: SessionDep) -> ProjectPublic:
    """Open a project: its cell, robot pose, guide points, recording and results."""
    return ProjectPublic.from_info(session.projects.open_project(project_id))


@router.patch("/{project_id}")
def rename_project(
    project_id: ProjectId, body: ProjectUpdate, session: SessionDep
) -> ProjectPublic:
    """Rename a project."""
    return ProjectPublic.from_info(session.projects.rename_project(project_id, body.name))


@router.delete("/{project_id}", status_code=status.HTTP_204_NO_CONTENT)
def delete_project(project_id: ProjectId, session: SessionDep) -> Response:
    """Delete a project and its saved exports; deleting the open one opens another."""
    session.projects.delete_project(project_id)
    return Response(status_code=status.HTTP_204_NO_CONTENT)


# --- projects as files ---


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
    info = await run_in_threadpool(session.projects.import_project, b"".join(chunks), name)
    return ProjectPublic.from_info(info)


@router.get(
    "/current/project.npz",
    response_class=Response,
    responses={200: {"content": {"application/octet-stream": {}}}},
)
def download_project_file(session: SessionDep) -> Response:
    """The open project as ``project.npz`` (``robomach machine --from`` reads it)."""
    return download(session.projects.export_project(), "project.npz")
