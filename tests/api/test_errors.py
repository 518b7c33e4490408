"""An error no route foresaw: answered once, logged once, the connection closed properly
(issue 19, R6).

Starlette's handler for ``Exception`` answered 503 and then re-raised to uvicorn, which logged
the error a second time and dropped the keep-alive connection without ``Connection: close``:
the client's next request on that connection failed. The route here raises the kinds of
error the audit met (OverflowError from a number beyond range, MemoryError).
"""

from __future__ import annotations

import logging
import threading
import time
from collections.abc import Iterator

import httpx
import pytest
import uvicorn
from fastapi import FastAPI
from fastapi.testclient import TestClient

from app.api.app import create_app
from app.session import Session
from app.settings import ServerSettings
from tests.api.server_process import free_port

ERRORS = {"overflow": OverflowError("(34, 'Numerical result out of range')"),
          "memory": MemoryError(), "key": KeyError("x")}  # fmt: skip


def failing_app() -> FastAPI:
    app = create_app(Session(), ServerSettings(viser_port=None))

    @app.get("/api/test/fail/{kind}")
    def fail(kind: str) -> dict:
        raise ERRORS[kind]

    return app


@pytest.fixture(scope="module")
def failing() -> Iterator[TestClient]:
    with TestClient(failing_app()) as c:
        yield c


@pytest.mark.parametrize(
    ("kind", "needle"),
    [
        ("overflow", "outside what the simulation can compute"),
        ("memory", "not enough memory"),
        ("key", "could not do this"),
    ],
)
def test_an_unexpected_error_is_a_503_with_a_physical_message(
    failing: TestClient, caplog: pytest.LogCaptureFixture, kind: str, needle: str
) -> None:
    caplog.set_level(logging.ERROR)
    r = failing.get(f"/api/test/fail/{kind}")
    assert r.status_code == 503
    assert needle in r.json()["detail"]
    assert r.headers["connection"] == "close"
    records = [rec for rec in caplog.records if rec.levelno >= logging.ERROR]
    assert len(records) == 1, [rec.getMessage() for rec in records]
    assert records[0].exc_info is not None  # the traceback, once


@pytest.fixture(scope="module")
def live_url() -> Iterator[str]:
    """The failing app served by uvicorn in a thread: real HTTP, real keep-alive."""
    port = free_port()
    server = uvicorn.Server(
        uvicorn.Config(failing_app(), host="127.0.0.1", port=port, log_level="error")
    )
    thread = threading.Thread(target=server.run, daemon=True)
    thread.start()
    deadline = time.monotonic() + 30
    while not server.started and time.monotonic() < deadline:
        time.sleep(0.05)
    yield f"http://127.0.0.1:{port}"
    server.should_exit = True
    thread.join(10)


def test_the_next_request_on_the_client_succeeds_and_the_error_is_logged_once(
    live_url: str, caplog: pytest.LogCaptureFixture
) -> None:
    caplog.set_level(logging.ERROR)
    with httpx.Client(base_url=live_url, timeout=10) as http:
        for _ in range(3):
            assert http.get("/api/health").status_code == 200
            r = http.get("/api/test/fail/overflow")
            assert r.status_code == 503 and r.headers["connection"] == "close"
            assert http.get("/api/health").status_code == 200  # a fresh connection, no error
    logged = [rec.getMessage() for rec in caplog.records if rec.levelno >= logging.ERROR]
    assert len(logged) == 3, logged
    assert not any("Exception in ASGI application" in m for m in logged), logged
