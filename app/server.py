"""``robomach serve`` in one process: the REST API (uvicorn), the pendant page and the viser
workbench, over one ``Session`` that the GUI and the API share.

Startup: check the viser port is free, lock the data folder (one server per folder), open the
store and the last project, build the app; uvicorn's lifespan starts the viser server and stops
it, the job worker and the store on Ctrl-C or SIGTERM. viser binds loopback only when the API
is served beyond it (``viser_host``), and refuses websockets from other origins.
"""

from __future__ import annotations

import logging
import os
import socket
import sqlite3
from collections.abc import Callable, Iterator
from contextlib import contextmanager
from pathlib import Path
from types import ModuleType
from typing import IO, TYPE_CHECKING
from urllib.parse import urlsplit

from app.settings import ServerSettings, is_loopback_name
from app.store import DB_FILENAME, Store
from robomach_core.errors import InvalidInputError

if TYPE_CHECKING:  # imported when a server is built: a refused start answers before them
    from fastapi import FastAPI

    from app.session import Session

log = logging.getLogger("robomach.server")

LOCK_FILENAME = "robomach.lock"
LOOPBACK_HOST = "127.0.0.1"


def viser_host(settings: ServerSettings) -> str:
    """The interface viser binds: the server's when that is loopback, else 127.0.0.1.

    viser has no authentication, so a scene open beyond loopback would let anyone who reaches
    the port press the workbench's buttons while the REST API asks for the token (issue 10,
    7). Beyond loopback the scene stays on this machine; reach it through an SSH tunnel
    (``ssh -L 8080:127.0.0.1:8080 host``).
    """
    return settings.host if settings.loopback else LOOPBACK_HOST


def check_port_free(
    host: str, port: int, what: str = "viser port", option: str = "--viser-port"
) -> None:
    """``InvalidInputError`` when ``port`` on ``host`` is taken (viser would quietly take the
    next one, and the pendant and ``/api/workbench`` would point at another server; uvicorn
    exited with code 3 after starting everything else) or ``host`` is no address here."""
    family = socket.AF_INET6 if ":" in host else socket.AF_INET
    with socket.socket(family, socket.SOCK_STREAM) as probe:
        # asyncio's servers set SO_REUSEADDR too: a port in TIME_WAIT is free for viser.
        probe.setsockopt(socket.SOL_SOCKET, socket.SO_REUSEADDR, 1)
        try:
            probe.bind((host, port))
        except socket.gaierror as exc:
            raise InvalidInputError(
                f"--host {host}: not an address of this machine ({exc.strerror})"
            ) from None
        except OSError as exc:
            raise InvalidInputError(
                f"the {what} {port} on {host} is not free ({exc.strerror}): stop the program "
                f"using it or pass another {option}"
            ) from None


@contextmanager
def viser_workbench(
    session: Session,
    settings: ServerSettings,
    *,
    on_port: Callable[[int], None] | None = None,
) -> Iterator[object]:
    """The viser server with the workbench GUI (``app.gui.workbench``) when it is installed,
    else an empty scene; stopped on exit. ``on_port`` gets the port viser actually bound."""
    import viser

    if settings.viser_port is None:  # build_app adds the workbench only with a port
        raise ValueError("the viser workbench needs a viser port (settings.viser_port)")
    host = viser_host(settings)
    if host != settings.host:
        log.info(
            "the viser scene listens on %s only (viser has no token check); from other "
            "machines reach it through an SSH tunnel: ssh -L %d:127.0.0.1:%d <this host>",
            host,
            settings.viser_port,
            settings.viser_port,
        )
    server = viser.ViserServer(host=host, port=settings.viser_port, verbose=False)
    refuse_foreign_websockets(server)
    port = server.get_port()
    if port != settings.viser_port:
        log.warning("viser port %d was taken: the scene is on %d", settings.viser_port, port)
    if on_port is not None:
        on_port(port)
    workbench = None
    try:
        try:
            from app.gui.workbench import Workbench
        except ModuleNotFoundError as exc:
            if not (exc.name or "").startswith("app.gui"):
                raise
            log.warning("app.gui.workbench is not installed: the 3D view shows nothing")
        else:
            try:
                workbench = Workbench(server, session)
            except Exception:  # the REST API stays useful without the GUI
                log.exception("the viser workbench failed to build; serving an empty scene")
        shown = _display_host(settings) if host == settings.host else host
        log.info("viser workbench at http://%s:%d", shown, port)
        yield server
    finally:
        close = getattr(workbench, "close", None)
        if close is not None:
            try:
                close()
            except Exception:
                log.exception("closing the workbench failed")
        server.stop()


def refuse_foreign_websockets(server: object) -> bool:
    """Close viser websockets opened by a page of another origin, and drop their messages.

    A browser lets any page open a websocket to any port, sending its own ``Origin``; without
    this, a page on another site could click the workbench's buttons through viser. viser
    1.1 has no public hook, so this wraps two of its internals (checked here: when they are
    missing, it logs a warning and returns False). A connection passes when its ``Host`` is a
    loopback name (viser only listens there: a name rebound to 127.0.0.1 by DNS is refused)
    and it sends no ``Origin`` (not a browser) or one equal to that ``Host`` (the viser page,
    also inside the pendant's frame).
    """
    infra = getattr(server, "_websock_server", None)
    live = getattr(infra, "_live_connections", None)
    dispatch = getattr(infra, "_handle_incoming_message", None)
    if infra is None or not isinstance(live, dict) or dispatch is None:
        log.warning("this viser version offers no websocket hook: origins are not checked")
        return False
    refused: set[object] = set()

    async def dispatch_known(client_id: object, message: object) -> None:
        if client_id not in refused:
            await dispatch(client_id, message)

    async def check_origin(connection: object) -> None:
        client_id = getattr(connection, "client_id", None)
        request = getattr(live.get(client_id), "request", None)
        if request is None:
            return
        hosts, origins = _all(request.headers, "Host"), _all(request.headers, "Origin")
        origin = origins[0] if len(origins) == 1 else None
        host = hosts[0] if len(hosts) == 1 else ""
        if len(hosts) != 1 or len(origins) > 1:
            # Two Host (or Origin) headers: which one a proxy or the browser meant cannot be
            # told, so the connection is refused (reading one raised and logged a traceback).
            reason = "several Host or Origin headers refused"
            shown = f"{len(hosts)} Host and {len(origins)} Origin headers"
        elif not _loopback_host(host):
            # viser listens on loopback only (viser_host): a page under another name that
            # resolves here (DNS rebinding) is "same origin" with itself; refuse its name.
            reason, shown = "a non-loopback Host refused", f"host {host[:200]!r}"
        elif origin is None or _same_origin(origin, host):
            return
        else:
            reason, shown = "cross-origin connection refused", f"origin {origin[:200]!r}"
        refused.add(client_id)  # before the first message is read: the consumer starts later
        log.warning("viser: refused a websocket from %s", shown)
        await live[client_id].close(1008, reason)

    infra._handle_incoming_message = dispatch_known
    infra.on_client_connect(check_origin)
    return True


def _all(headers: object, name: str) -> list[str]:
    """Every value of header ``name`` (a websockets ``Headers`` raises on ``get`` when there
    are several)."""
    get_all = getattr(headers, "get_all", None)
    if get_all is not None:
        return [str(v) for v in get_all(name)]
    value = headers.get(name)  # type: ignore[attr-defined]
    return [] if value is None else [str(value)]


def _loopback_host(host: str) -> bool:
    """True when a ``Host`` header (``name[:port]``) names this machine's loopback."""
    try:
        name = urlsplit(f"//{host}").hostname
    except ValueError:
        return False
    return name is not None and is_loopback_name(name)


def _same_origin(origin: str, host: str) -> bool:
    """True when ``origin`` (``http://host:port``) names ``host`` (a ``Host`` header)."""
    try:
        given, own = urlsplit(origin), urlsplit(f"//{host}")
        default = {"http": 80, "https": 443}.get(given.scheme, 0)
        return (
            given.scheme in ("http", "https")
            and given.hostname is not None
            and (given.hostname, given.port or default) == (own.hostname, own.port or default)
        )
    except ValueError:
        return False


def _display_host(settings: ServerSettings) -> str:
    return "localhost" if settings.host in ("0.0.0.0", "::") else settings.host


@contextmanager
def data_dir_lock(data_dir: Path) -> Iterator[None]:
    """Hold an exclusive lock on the data folder so that two servers never share it.

    The operating system drops the lock when the process dies, even on SIGKILL.
    """
    data_dir.mkdir(parents=True, exist_ok=True)
    handle: IO[str] = open(data_dir / LOCK_FILENAME, "a+")  # noqa: SIM115 (held until exit)
    try:
        fcntl: ModuleType | None
        try:
            import fcntl
        except ImportError:  # Windows: no advisory lock, accept the risk
            fcntl = None
        if fcntl is not None:
            try:
                fcntl.flock(handle.fileno(), fcntl.LOCK_EX | fcntl.LOCK_NB)
            except BlockingIOError:
                raise InvalidInputError(
                    f"another robomach serve is using the data folder {data_dir}; stop it or "
                    "pass another --data"
                ) from None
        handle.seek(0)
        handle.truncate()
        handle.write(f"{os.getpid()}\n")
        handle.flush()
        yield
    finally:
        handle.close()


def build_app(settings: ServerSettings, session: Session) -> FastAPI:
    """The full app: the REST API, the pendant page and (when a viser port is set) the viser
    workbench as a lifespan service."""
    from app.api.app import create_app

    def bound(port: int) -> None:
        # The routes read the port from the settings: make them say the one viser bound.
        app.state.viser_port = port
        if port != app.state.settings.viser_port:
            app.state.settings = app.state.settings.model_copy(update={"viser_port": port})

    services = []
    if settings.viser_port is not None:
        services.append(lambda: viser_workbench(session, settings, on_port=bound))
    app = create_app(session, settings, services=services)
    return app


def open_session(settings: ServerSettings, data_dir: Path) -> Session:
    """The session ``serve`` runs: the store of ``data_dir`` (SQLite), its last project, and the
    settings' upload limits and pacing. The in-process API tests build theirs here too."""
    from app.session import Session

    return Session(
        Store.in_data_dir(data_dir),
        data_dir=data_dir,
        max_upload_bytes=settings.max_upload_bytes,
        max_triangles=settings.max_triangles,
        real_time=settings.real_time,
    )


def serve(settings: ServerSettings) -> int:
    """Run until Ctrl-C or SIGTERM; returns the exit code. The settings, ports and data
    folder are checked before the server's libraries (fastapi, uvicorn, viser, the session)
    are imported: a refused start does not wait for them."""
    from app.cli import writable_folder

    settings.check()
    check_port_free(settings.host, settings.port, "port", "--port")
    if settings.viser_port is not None:
        check_port_free(viser_host(settings), settings.viser_port)
    data_dir = writable_folder(settings.data_dir.resolve(), "--data")
    import uvicorn

    with data_dir_lock(data_dir):
        try:
            session = open_session(settings, data_dir)
        except sqlite3.DatabaseError as exc:  # a user's file, not a fault here: exit 2
            raise InvalidInputError(
                f"--data {data_dir}: {DB_FILENAME} there is not a readable robomach database "
                f"({exc}); move it away or pass another --data"
            ) from None
        try:
            app = build_app(settings, session)
            host = _display_host(settings)
            log.info("data folder %s, project %r", data_dir, session.current_project().name)
            log.info("REST API at http://%s:%d/docs, pendant at /pendant/", host, settings.port)
            if settings.token:
                which = (
                    "every REST call but /api/health"
                    if settings.reads_need_token
                    else ("mutating REST calls")
                )
                log.info("%s need the token (Authorization: Bearer ...)", which)
            config = uvicorn.Config(
                app,
                host=settings.host,
                port=settings.port,
                log_level="info",
                lifespan="on",
                timeout_graceful_shutdown=5,
                access_log=False,
            )
            server = uvicorn.Server(config)
            app.state.should_exit = lambda: server.should_exit  # ends event streams on stop
            server.run()
            # uvicorn returns normally when it could not start (e.g. the port is taken).
            return 0 if server.started else 1
        finally:
            session.close()  # idempotent: the lifespan normally closed it already
