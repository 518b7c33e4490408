"""The app ``robomach serve`` builds, run inside the test process: the same ``open_session``
(a real SQLite file in a data folder, locked as ``serve`` locks it) and ``build_app`` (the REST
API, the pendant page and the viser workbench on a free port), driven through ``TestClient``.

What needs a process of its own (a restart, the data-folder lock between two servers, origins
and rebinding over real sockets, surviving native crashes, memory, connection handling) runs
``robomach serve`` instead (``tests/api/server_process.py``).
"""

from __future__ import annotations

import logging
from collections.abc import Iterator
from contextlib import contextmanager
from dataclasses import dataclass
from pathlib import Path

from fastapi.testclient import TestClient

from app.server import build_app, data_dir_lock, open_session
from app.session import Session
from app.settings import ServerSettings
from tests.api.server_process import Api, free_port


@dataclass
class InProcessServer:
    """The in-process app: its client, data folder, session and the viser scene's URL."""

    client: TestClient
    data_dir: Path
    session: Session
    viser_url: str

    @property
    def base_url(self) -> str:
        return str(self.client.base_url)

    def api(self) -> Api:
        """A client with the tests' moves, over the shared ``TestClient``."""
        return Api(self.client)


@contextmanager
def serve_in_process(data_dir: Path, **settings: object) -> Iterator[InProcessServer]:
    """``robomach serve``'s app on ``data_dir``, with ``settings`` over the CLI's defaults (no
    environment variables: they are the test's to set, tests/conftest.py). The app's lifespan
    runs on entry and exit: the viser workbench starts and stops, the session closes."""
    port = free_port()
    values = {"port": port, "viser_port": free_port(), "data_dir": data_dir, **settings}
    config = ServerSettings.from_env(**values)  # tests/conftest.py cleared the variables
    data_dir = data_dir.resolve()
    with data_dir_lock(data_dir):
        session = open_session(config, data_dir)
        app = build_app(config, session)
        # The Host the browser sends to a loopback server; the server refuses any other name.
        with TestClient(app, base_url=f"http://127.0.0.1:{port}") as client:
            yield InProcessServer(
                client, data_dir, session, f"http://127.0.0.1:{app.state.viser_port}/"
            )


class TracebackWatch(logging.Handler):
    """Every record logged with a traceback while it is installed on the root logger: the
    in-process counterpart of a server log that must hold no ``Traceback``."""

    def __init__(self) -> None:
        super().__init__(level=logging.ERROR)
        self.records: list[logging.LogRecord] = []

    def emit(self, record: logging.LogRecord) -> None:
        if record.exc_info or record.exc_text:
            self.records.append(record)

    def report(self) -> str:
        formatter = logging.Formatter("%(name)s: %(message)s")
        return "\n".join(formatter.format(r) for r in self.records)


@contextmanager
def no_tracebacks() -> Iterator[TracebackWatch]:
    """Fail when anything logs a traceback inside the block (the app's error handler, a job)."""
    watch = TracebackWatch()
    root = logging.getLogger()
    root.addHandler(watch)
    try:
        yield watch
    finally:
        root.removeHandler(watch)
    assert not watch.records, watch.report()
