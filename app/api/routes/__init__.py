"""One router per resource; the dependencies they share as ``Annotated`` aliases."""

from __future__ import annotations

from typing import Annotated

from fastapi import Depends, Request

from app.api.schemas import ErrorPublic
from app.session import Session
from app.settings import ServerSettings


def get_session(request: Request) -> Session:
    return request.app.state.session


def get_settings(request: Request) -> ServerSettings:
    return request.app.state.settings


SessionDep = Annotated[Session, Depends(get_session)]
SettingsDep = Annotated[ServerSettings, Depends(get_settings)]

# Documented error answers of every route (the handlers in app.api.app produce them).
ERRORS: dict[int | str, dict] = {
    401: {"model": ErrorPublic, "description": "missing or wrong token (mutating calls)"},
    404: {"model": ErrorPublic, "description": "no such item"},
    409: {"model": ErrorPublic, "description": "not possible now (robot busy, nothing to process)"},
    422: {"model": ErrorPublic, "description": "invalid input; the message says what is wrong"},
}
