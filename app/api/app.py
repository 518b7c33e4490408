"""The FastAPI application: routers, error mapping, token and same-origin checks, body and
upload limits, lifespan.

Errors: ``RobomachError`` subclasses map to 4xx by their builtin base (ValueError/KeyError ->
422, not found -> 404, state conflicts and RuntimeError -> 409); request validation (malformed
JSON, wrong types, out-of-range values) -> 422 with a one-line summary plus per-field errors;
anything unforeseen -> 503 with a sentence saying what limit it met (``describe_unexpected``),
answered once and logged once by ``UnexpectedErrorMiddleware``, with ``Connection: close`` so
that the client's next request opens a fresh connection; never a bare 500.
"""

from __future__ import annotations

import gc
import hmac
import logging
import sqlite3
from collections.abc import AsyncIterator, Callable, Sequence
from contextlib import AbstractContextManager, ExitStack, asynccontextmanager
from urllib.parse import urlsplit

from fastapi import FastAPI, Request
from fastapi.exceptions import RequestValidationError
from fastapi.responses import JSONResponse, RedirectResponse
from fastapi.staticfiles import StaticFiles
from starlette.datastructures import Headers
from starlette.exceptions import HTTPException as StarletteHTTPException
from starlette.types import ASGIApp, Message, Receive, Scope, Send

from app.api.routes import (
    calibration,
    cell,
    choices,
    cmrr,
    compensation,
    events,
    export,
    guide_points,
    jobs,
    leadthrough,
    machining,
    path_learning,
    placement_preview,
    postprocess,
    projects,
    robot_wiring,
    state,
)
from app.session import ConflictError, NotFoundError, QueueFullError, Session
from app.session.jobs import describe_unexpected
from app.settings import MAX_JSON_BODY_BYTES, ServerSettings, is_loopback_name
from app.studies import StudyQueueFullError
from robomach_core.errors import (
    CancelledError,
    ForceLimitError,
    NotEnoughGuidePointsError,
    RobomachError,
)

log = logging.getLogger(__name__)

SAFE_METHODS = frozenset({"GET", "HEAD", "OPTIONS"})
OPEN_READ_PATHS = frozenset({"/api/health"})  # liveness probes need no token
READ_COOKIE = "robomach_read"
DEFAULT_PORTS = {"http": 80, "https": 443}
UPLOAD_PATHS = frozenset({"/api/cell/workpiece"})
# Multipart boundaries and part headers around the file: a few hundred bytes in practice.
MULTIPART_OVERHEAD_BYTES = 64 * 1024
# One router per resource (each module's prefix is its own).
ROUTERS = (state, leadthrough, guide_points, path_learning, jobs, postprocess, export, projects,
           calibration, cell, cmrr, compensation, robot_wiring, machining, events, choices,
           placement_preview)  # fmt: skip

# A service is started in the lifespan and stopped after it (e.g. the viser workbench).
Service = Callable[[], AbstractContextManager]


def status_for(exc: RobomachError) -> int:
    """The HTTP status of a user-caused error, by what kind of error it is."""
    if isinstance(exc, NotFoundError):
        return 404
    if isinstance(exc, (StudyQueueFullError, QueueFullError)):
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
    ``X-Robomach-Token: <token>``); compared in constant time. With ``reads`` every /api/ read
    needs it too, except ``OPEN_READ_PATHS``; a read that sent the token gets a cookie
    (HttpOnly, SameSite=Strict) that stands for it on later reads only, so that the browser's
    ``EventSource`` and downloads work. The cookie holds an HMAC of the token, not the token,
    and never opens a mutating call."""

    def __init__(self, app: ASGIApp, token: str, *, reads: bool = False) -> None:
        self.app = app
        self._token = token.encode()
        self._reads = reads
        self._cookie = hmac.new(self._token, b"robomach reads", "sha256").hexdigest()

    async def __call__(self, scope: Scope, receive: Receive, send: Send) -> None:
        if scope["type"] not in ("http", "websocket") or not scope["path"].startswith("/api/"):
            await self.app(scope, receive, send)
            return
        method = scope.get("method", "GET")
        mutating = method not in SAFE_METHODS
        guarded = mutating or (
            self._reads and method != "OPTIONS" and scope["path"] not in OPEN_READ_PATHS
        )
        if not guarded:
            await self.app(scope, receive, send)
            return
        headers = Headers(scope=scope)
        given = headers.get("x-robomach-token")
        auth = headers.get("authorization", "")
        if given is None and auth.lower().startswith("bearer "):
            given = auth[7:].strip()
        if given is not None and hmac.compare_digest(given.encode(), self._token):
            if mutating or not self._reads:
                await self.app(scope, receive, send)
            else:
                await self.app(scope, receive, self._with_cookie(send))
            return
        if given is None and not mutating and self._has_cookie(headers):
            await self.app(scope, receive, send)
            return
        if given is None:
            what = "this call changes the workbench" if mutating else "this read is guarded"
            detail = (
                f"{what} and needs the server's token: send 'Authorization: Bearer "
                "<ROBOMACH_TOKEN>'"
            )
        else:
            detail = "wrong token"
        response = JSONResponse(
            {"detail": detail}, status_code=401, headers={"WWW-Authenticate": "Bearer"}
        )
        await response(scope, receive, send)

    def _has_cookie(self, headers: Headers) -> bool:
        for part in headers.get("cookie", "").split(";"):
            name, _, value = part.strip().partition("=")
            if name == READ_COOKIE and hmac.compare_digest(value.encode(), self._cookie.encode()):
                return True
        return False

    def _with_cookie(self, send: Send) -> Send:
        cookie = f"{READ_COOKIE}={self._cookie}; Path=/api; HttpOnly; SameSite=Strict".encode()

        async def sending(message: Message) -> None:
            if message["type"] == "http.response.start":
                message = {**message, "headers": [*message.get("headers", []),
                                                  (b"set-cookie", cookie)]}  # fmt: skip
            await send(message)

        return sending


class LoopbackHostMiddleware:
    """On a server bound to loopback, 403 for any request whose ``Host`` is not a loopback
    name (reads too): a page under a name its owner rebound to 127.0.0.1 (DNS rebinding) is
    "same origin" with itself, and could otherwise read the project file and the exports."""

    def __init__(self, app: ASGIApp) -> None:
        self.app = app

    async def __call__(self, scope: Scope, receive: Receive, send: Send) -> None:
        if scope["type"] in ("http", "websocket"):
            host = Headers(scope=scope).get("host", "")
            parsed = _host_port(host, "http")
            if parsed is None or not is_loopback_name(parsed[0]):
                detail = (
                    f"this server listens on loopback only and is not {host[:100]!r}: open it "
                    "as http://127.0.0.1:<port> or http://localhost:<port>"
                )
                if scope["type"] == "websocket":
                    await send({"type": "websocket.close", "code": 1008})
                    return
                await JSONResponse({"detail": detail}, status_code=403)(scope, receive, send)
                return
        await self.app(scope, receive, send)


def _host_port(netloc: str, scheme: str) -> tuple[str, int] | None:
    """(lower-case host, port) of ``netloc``, the scheme's default port when it has none."""
    try:
        parts = urlsplit(f"//{netloc}")
        port = parts.port
    except ValueError:
        return None
    if not parts.hostname:
        return None
    return parts.hostname.lower(), port or DEFAULT_PORTS.get(scheme, 0)


class SameOriginMiddleware:
    """Mutating calls (POST, PUT, PATCH, DELETE: uploads too) from a page of another origin
    get 403: the ``Origin`` header (or, without one, the ``Referer``) must name this server as
    the browser reached it (its ``Host``), or the viser scene on the same host. Calls with
    neither header (curl, scripts, the Python client) pass: browsers send ``Origin`` on every
    cross-origin POST and every ``fetch`` that is not a GET or HEAD, and a script that can
    forge headers is not a web page riding on the user's browser."""

    def __init__(self, app: ASGIApp, *, loopback_only: bool = False) -> None:
        self.app = app
        self.loopback_only = loopback_only

    async def __call__(self, scope: Scope, receive: Receive, send: Send) -> None:
        if scope["type"] == "http" and scope["method"] not in SAFE_METHODS:
            headers = Headers(scope=scope)
            source, header = headers.get("origin"), "Origin"
            if source is None and headers.get("referer"):
                source, header = headers["referer"], "Referer"
            if source is not None and not self._same_origin(source, headers, scope):
                host = headers.get("host", "this server")
                detail = (
                    f"cross-site request refused: the {header} {source[:200]!r} is not this "
                    f"server ({scope.get('scheme', 'http')}://{host}); change the workbench "
                    "from its own pages (/pendant/, the viser scene) or from a script"
                )
                await JSONResponse({"detail": detail}, status_code=403)(scope, receive, send)
                return
        await self.app(scope, receive, send)

    def _same_origin(self, source: str, headers: Headers, scope: Scope) -> bool:
        try:
            parts = urlsplit(source)
        except ValueError:
            return False
        scheme = scope.get("scheme", "http")
        if parts.scheme != scheme or not parts.netloc:
            return False  # "null" (sandboxed frames, file://) and other schemes
        given = _host_port(parts.netloc, parts.scheme)
        own = _host_port(headers.get("host", ""), scheme)
        if given is None or own is None:
            return False
        if self.loopback_only and not is_loopback_name(own[0]):
            # A page whose name was rebound to 127.0.0.1 (DNS rebinding) is "same origin"
            # with its own name: a server on loopback is only ever called by a loopback name.
            return False
        if given == own:
            return True
        app = scope.get("app")
        viser_port = getattr(getattr(app, "state", None), "viser_port", None)
        return viser_port is not None and given == (own[0], viser_port)


class UnexpectedErrorMiddleware:
    """The one handler of errors no route foresaw: a 503 whose message says what limit the
    request met, logged once with its traceback, sent with ``Connection: close`` (the request
    body may be unread, so the connection is closed properly rather than reused).

    Starlette's own handler for ``Exception`` answers and then re-raises to the server, which
    logged the error a second time and dropped the keep-alive connection without saying so:
    the client's next request on it failed (issue 19, R6). A response already started cannot
    be replaced: that error goes on to the server, which closes the connection.
    """

    def __init__(self, app: ASGIApp) -> None:
        self.app = app

    async def __call__(self, scope: Scope, receive: Receive, send: Send) -> None:
        if scope["type"] != "http":
            await self.app(scope, receive, send)
            return
        started = False

        async def tracked(message: Message) -> None:
            nonlocal started
            if message["type"] == "http.response.start":
                started = True
            await send(message)

        try:
            await self.app(scope, receive, tracked)
        except Exception as exc:
            if started:
                raise
            log.error(
                "unexpected error on %s %s", scope.get("method"), scope.get("path"), exc_info=exc
            )
            response = JSONResponse(
                {"detail": describe_unexpected(exc)},
                status_code=503,
                headers={"Connection": "close"},
            )
            await response(scope, receive, send)


class UploadSizeMiddleware:
    """413 for a mesh upload whose declared size (``Content-Length``) is over the server's
    limit, before a byte of it is read; the route still counts the bytes of an upload that
    declares none (chunked)."""

    def __init__(self, app: ASGIApp, limit_bytes: int) -> None:
        self.app = app
        self.limit_bytes = limit_bytes

    async def __call__(self, scope: Scope, receive: Receive, send: Send) -> None:
        if (
            scope["type"] == "http"
            and scope["method"] == "POST"
            and (scope["path"].rstrip("/") in UPLOAD_PATHS)
        ):
            declared = Headers(scope=scope).get("content-length")
            detail = None
            if declared is not None:
                try:
                    size = int(declared)
                except ValueError:
                    size, detail = -1, f"Content-Length {declared[:40]!r} is not a byte count"
                if size > self.limit_bytes + MULTIPART_OVERHEAD_BYTES:
                    detail = (
                        f"the upload is {size / 1e6:.1f} MB, more than the "
                        f"{self.limit_bytes / 1e6:g} MB limit of this server"
                    )
            if detail is not None:
                status = 400 if detail.startswith("Content-Length") else 413
                response = JSONResponse({"detail": detail}, status_code=status)
                response.headers["Connection"] = "close"
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
            # Startup built a large long-lived heap (robot models, compiled kernels, viser);
            # leave it out of the full collections, which walked it with the interpreter lock
            # held, stalling every request 0.1-0.4 s at a time under load. Collect first:
            # garbage frozen now would never be freed.
            gc.collect()
            gc.freeze()
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
    app.add_middleware(UnexpectedErrorMiddleware)  # innermost: every route's error
    if settings.token:
        app.add_middleware(TokenMiddleware, token=settings.token, reads=settings.reads_need_token)
    app.add_middleware(UploadSizeMiddleware, limit_bytes=settings.max_upload_bytes)
    # outermost: a foreign page learns nothing more
    app.add_middleware(SameOriginMiddleware, loopback_only=settings.loopback)
    if settings.loopback and settings.refuse_foreign_hosts:
        app.add_middleware(LoopbackHostMiddleware)  # outermost: DNS rebinding, reads too
    app.state.viser_port = None  # the port viser bound, set by the workbench service
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
        # An operational condition (another program holds the file's lock), not a fault here:
        # one line, no traceback. Nothing was applied (the session saves before it applies).
        log.warning("storage error on %s %s: %s", request.method, request.url.path, exc)
        return JSONResponse(
            {"detail": f"the project database is unavailable ({exc}); try again"}, status_code=503
        )

    # Errors no handler above maps: UnexpectedErrorMiddleware (answers once, logs once).
