"""The FastAPI application: routers, error mapping, token check, body limits, lifespan.

Errors: ``RobomachError`` subclasses map to 4xx by their builtin base (ValueError/KeyError ->
422, not found -> 404, state conflicts and RuntimeError -> 409); request validation (malformed
JSON, wrong types, out-of-range values) -> 422 with a one-line summary plus per-field errors;
anything unforeseen -> 503 with its message (and a logged traceback), never a bare 500.
"""

from __future__ import annotations

import hmac
import logging
import sqlite3
from collections.abc import AsyncIterator, Callable, Sequence
from contextlib import AbstractContextManager, ExitStack, asynccontextmanager

from fastapi import FastAPI, Request
from fastapi.exceptions import RequestValidationError
from fastapi.responses import JSONResponse, RedirectResponse
from fastapi.staticfiles import StaticFiles
from starlette.datastructures import Headers
from starlette.exceptions import HTTPException as StarletteHTTPException
from starlette.types import ASGIApp, Receive, Scope, Send

from app.api.routes import (
    cell,
    cmrr,
    compensation,
    export,
    guide_points,
    jobs,
    leadthrough,
    path_learning,
    postprocess,
    projects,
    state,
)
from app.session import ConflictError, NotFoundError, Session
from app.settings import MAX_JSON_BODY_BYTES, ServerSettings
from app.studies import StudyQueueFullError
from robomach_core.errors import (
    CancelledError,
    ForceLimitError,
    NotEnoughGuidePointsError,
    RobomachError,
)

log = logging.getLogger(__name__)

SAFE_METHODS = frozenset({"GET", "HEAD", "OPTIONS"})
ROUTERS = (state, leadthrough, guide_points, path_learning, jobs, postprocess, export, projects,
           cell, cmrr, compensation)  # fmt: skip

# A service is started in the lifespan and stopped after it (e.g. the viser workbench).
Service = Callable[[], AbstractContextManager]


def status_for(exc: RobomachError) -> int:
    """The HTTP status of a user-caused error, by what kind of error it is."""
    if isinstance(exc, NotFoundError):
        return 404
    if isinstance(exc, StudyQueueFullError):
        return 429
    if isinstance(exc, (ConflictError, CancelledError, ForceLimitError, NotEnoughGuidePointsError)):
        return 409
    if isinstance(exc, (ValueError, KeyError)):
        return 422
    if isinstance(exc, RuntimeError):
        return 409
    return 400


def _field(loc: Sequence) -> str:
    parts = [str(p) for p in loc if p not in ("body", "query", "path")]
    return ".".join(parts) or "body"


def validation_message(errors: Sequence[dict]) -> tuple[str, list[dict]]:
    """A one-line summary and JSON-safe per-field errors of a request validation failure."""
    items, lines = [], []
    for e in errors:
        loc = tuple(e.get("loc", ()))
        if e.get("type") == "json_invalid":
            error = (e.get("ctx") or {}).get("error", "cannot parse")
            msg = f"the body is not valid JSON ({error})"
            lines.append(msg)
            items.append({"loc": ["body"], "msg": msg, "type": "json_invalid"})
            continue
        where = _field(loc)
        msg = str(e.get("msg", "invalid"))
        if e.get("type") == "missing" and loc in (("body",), ()):
            msg = "a JSON body is required"
        lines.append(f"{where}: {msg}" if where != "body" else msg)
        items.append({"loc": [str(p) for p in loc], "msg": msg, "type": str(e.get("type", ""))})
    return "; ".join(lines) or "invalid request", items


class TokenMiddleware:
    """Every mutating /api/ call must carry the token (``Authorization: Bearer <token>`` or
    ``X-Robomach-Token: <token>``); compared in constant time."""

    def __init__(self, app: ASGIApp, token: str) -> None:
        self.app = app
        self._token = token.encode()

    async def __call__(self, scope: Scope, receive: Receive, send: Send) -> None:
        if (
            scope["type"] == "http"
            and scope["method"] not in SAFE_METHODS
            and scope["path"].startswith("/api/")
        ):
            headers = Headers(scope=scope)
            given = headers.get("x-robomach-token")
            auth = headers.get("authorization", "")
            if given is None and auth.lower().startswith("bearer "):
                given = auth[7:].strip()
            if given is None or not hmac.compare_digest(given.encode(), self._token):
                detail = (
                    "this call changes the workbench and needs the server's token: send "
                    "'Authorization: Bearer <ROBOMACH_TOKEN>'"
                    if given is None
                    else "wrong token"
                )
                response = JSONResponse(
                    {"detail": detail}, status_code=401, headers={"WWW-Authenticate": "Bearer"}
                )
                await response(scope, receive, send)
                return
        await self.app(scope, receive, send)


def create_app(
    session: Session,
    settings: ServerSettings | None = None,
    *,
    services: Sequence[Service] = (),
    close_session: bool = True,
) -> FastAPI:
    """The REST API over ``session``.

    Args:
        session: The workbench session the routes act on.
        settings: Token, upload limit, static folder; defaults when None.
        services: Context-manager factories entered at startup and left at shutdown, in
            reverse order (the viser workbench).
        close_session: Close the session (cancel jobs, close the store) at shutdown.
    """
    settings = settings or ServerSettings(viser_port=None)

    @asynccontextmanager
    async def lifespan(app: FastAPI) -> AsyncIterator[None]:
        with ExitStack() as stack:
            if close_session:
                stack.callback(session.close)
            for service in services:
                stack.enter_context(service())
            log.info("robomach API ready (project %r)", session.current_project().name)
            yield

    app = FastAPI(
        title="robomach",
        version="0.1.0",
        description=(
            "Programming robotic machining by demonstration on a simulated force-controlled "
            "robot: lead-through, guide points, automatic path learning, post-processing and "
            "RAPID export. Units: mm, N, N*m, s, degrees; quaternions w, x, y, z."
        ),
        lifespan=lifespan,
        max_body_size=MAX_JSON_BODY_BYTES,
    )
    app.state.session = session
    app.state.settings = settings
    for module in ROUTERS:
        app.include_router(module.router)
    _add_error_handlers(app)
    if settings.token:
        app.add_middleware(TokenMiddleware, token=settings.token)
    _mount_pendant(app, settings)
    return app


def _mount_pendant(app: FastAPI, settings: ServerSettings) -> None:
    static = settings.static_dir
    has_page = static.is_dir() and (static / "index.html").is_file()
    if static.is_dir():
        app.mount("/pendant", StaticFiles(directory=static, html=True), name="pendant")

    @app.get("/", include_in_schema=False)
    def root() -> RedirectResponse:
        return RedirectResponse("/pendant/" if has_page else "/docs")


def _add_error_handlers(app: FastAPI) -> None:
    @app.exception_handler(RobomachError)
    async def robomach_error(request: Request, exc: RobomachError) -> JSONResponse:
        return JSONResponse({"detail": str(exc)}, status_code=status_for(exc))

    @app.exception_handler(RequestValidationError)
    async def validation_error(request: Request, exc: RequestValidationError) -> JSONResponse:
        message, items = validation_message(exc.errors())
        return JSONResponse({"detail": message, "errors": items}, status_code=422)

    @app.exception_handler(StarletteHTTPException)
    async def http_error(request: Request, exc: StarletteHTTPException) -> JSONResponse:
        detail = exc.detail if isinstance(exc.detail, str) else str(exc.detail)
        if exc.status_code == 404 and detail == "Not Found":
            detail = f"no route {request.method} {request.url.path}; see /docs"
        elif exc.status_code == 413 and detail == "Content Too Large":
            detail = "the request body is larger than this route accepts"
        return JSONResponse(
            {"detail": detail}, status_code=exc.status_code, headers=getattr(exc, "headers", None)
        )

    @app.exception_handler(sqlite3.Error)
    async def storage_error(request: Request, exc: sqlite3.Error) -> JSONResponse:
        log.exception("storage error on %s %s", request.method, request.url.path)
        return JSONResponse(
            {"detail": f"the project database is unavailable ({exc}); try again"}, status_code=503
        )

    @app.exception_handler(Exception)
    async def unexpected(request: Request, exc: Exception) -> JSONResponse:
        log.error("unexpected error on %s %s", request.method, request.url.path, exc_info=exc)
        return JSONResponse(
            {"detail": f"the server could not do this: {exc.__class__.__name__}: {exc}"},
            status_code=503,
        )
