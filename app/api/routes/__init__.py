"""One router per resource; the dependencies they share as ``Annotated`` aliases."""

from __future__ import annotations

from pathlib import Path
from typing import Annotated, Any

from fastapi import Depends, Request, Response

from app.api.schemas import ErrorPublic
from app.session import Session
from app.session.machining import MachiningService
from app.settings import ServerSettings
from app.studies import StudyService


# Async: FastAPI runs a plain ``def`` dependency in a worker thread, a hop that costs every
# request time on the event loop; these only read an attribute.
async def get_session(request: Request) -> Session:
    return request.app.state.session


async def get_settings(request: Request) -> ServerSettings:
    return request.app.state.settings


async def get_studies(request: Request) -> StudyService:
    return request.app.state.session.studies


async def get_machining(request: Request) -> MachiningService:
    return request.app.state.session.machining


SessionDep = Annotated[Session, Depends(get_session)]
SettingsDep = Annotated[ServerSettings, Depends(get_settings)]
StudiesDep = Annotated[StudyService, Depends(get_studies)]
MachiningDep = Annotated[MachiningService, Depends(get_machining)]

# Documented error answers of every route (the handlers in app.api.app produce them).
ERRORS: dict[int | str, dict] = {
    401: {"model": ErrorPublic, "description": "missing or wrong token (mutating calls)"},
    404: {"model": ErrorPublic, "description": "no such item"},
    409: {"model": ErrorPublic, "description": "not possible now (robot busy, nothing to process)"},
    422: {"model": ErrorPublic, "description": "invalid input; the message says what is wrong"},
    429: {"model": ErrorPublic, "description": "too many jobs queued or running (job routes)"},
}

# File answers of the study routes.
PNG: dict[int | str, dict[str, Any]] = {
    200: {"content": {"image/png": {}}, "description": "the figure (PNG)"}
}
JSON_FILE: dict[int | str, dict[str, Any]] = {
    200: {"content": {"application/json": {}}, "description": "a JSON file"}
}
MEDIA_TYPES = {
    ".mod": "text/plain; charset=utf-8",
    ".csv": "text/csv; charset=utf-8",
    ".json": "application/json",
    ".zip": "application/zip",
    ".npz": "application/octet-stream",
}


def download(content: str | bytes, filename: str, media_type: str | None = None) -> Response:
    """``content`` as a file download named ``filename`` (media type from its suffix)."""
    suffix = filename[filename.rfind(".") :]
    return Response(
        content,
        media_type=media_type or MEDIA_TYPES.get(suffix, "text/plain; charset=utf-8"),
        headers={"Content-Disposition": f'attachment; filename="{filename}"'},
    )


def relative_folder(folder: Path | None, data_dir: Path | None) -> str | None:
    """A study folder relative to the data folder (None without one: nothing to show)."""
    if folder is None or data_dir is None or not folder.is_relative_to(data_dir):
        return None
    return str(folder.relative_to(data_dir))
