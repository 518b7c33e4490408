"""``robomach serve`` in one process: the REST API (uvicorn), the pendant page and the viser
workbench, over one ``Session`` that the GUI and the API share.

Startup: lock the data folder (one server per folder), open the store and the last project,
build the app; uvicorn's lifespan starts the viser server and stops it, the job worker and the
store on Ctrl-C or SIGTERM.
"""

from __future__ import annotations

import logging
import os
from collections.abc import Iterator
from contextlib import contextmanager
from pathlib import Path
from typing import IO

from fastapi import FastAPI

from app.session import Session
from app.settings import ServerSettings
from app.store import Store
from robomach_core.errors import InvalidInputError

log = logging.getLogger("robomach.server")

LOCK_FILENAME = "robomach.lock"


@contextmanager
def viser_workbench(session: Session, settings: ServerSettings) -> Iterator[object]:
    """The viser server with the workbench GUI (``app.gui.workbench``) when it is installed,
    else an empty scene; stopped on exit."""
    import viser

    server = viser.ViserServer(host=settings.host, port=settings.viser_port, verbose=False)
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
        log.info("viser workbench at http://%s:%d", _display_host(settings), server.get_port())
        yield server
    finally:
        close = getattr(workbench, "close", None)
        if close is not None:
            try:
                close()
            except Exception:
                log.exception("closing the workbench failed")
        server.stop()


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

    services = []
    if settings.viser_port is not None:
        services.append(lambda: viser_workbench(session, settings))
    return create_app(session, settings, services=services)


def serve(settings: ServerSettings) -> int:
    """Run until Ctrl-C or SIGTERM; returns the exit code."""
    import uvicorn

    settings.validate()
    data_dir = settings.data_dir.resolve()
    with data_dir_lock(data_dir):
        session = Session(
            Store.in_data_dir(data_dir),
            data_dir=data_dir,
            max_upload_bytes=settings.max_upload_bytes,
            max_triangles=settings.max_triangles,
        )
        try:
            app = build_app(settings, session)
            host = _display_host(settings)
            log.info("data folder %s, project %r", data_dir, session.current_project().name)
            log.info("REST API at http://%s:%d/docs, pendant at /pendant/", host, settings.port)
            if settings.token:
                log.info("mutating REST calls need the token (Authorization: Bearer ...)")
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
            server.run()
            # uvicorn returns normally when it could not start (e.g. the port is taken).
            return 0 if server.started else 1
        finally:
            session.close()  # idempotent: the lifespan normally closed it already
