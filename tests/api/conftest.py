"""The API tests share one app built as ``robomach serve`` builds it, run in this process
(``app_server``); each test opens a fresh project on it (``api``).

The few tests that need a real process (origins and rebinding over real sockets, surviving
native crashes, memory) use ``server``, one real ``robomach serve``, and ``http_api`` on it.
"""

from __future__ import annotations

from collections.abc import Iterator

import pytest

from tests.api.in_process import InProcessServer, no_tracebacks, serve_in_process
from tests.api.server_process import Api, ServerProcess, start_server

# Small limits, so that the limit tests need small files.
UPLOAD_LIMIT_BYTES = 200_000
TRIANGLE_LIMIT = 1000


@pytest.fixture(scope="session")
def app_server(tmp_path_factory: pytest.TempPathFactory) -> Iterator[InProcessServer]:
    """The app of ``robomach serve`` in this process, on its own data folder."""
    with serve_in_process(
        tmp_path_factory.mktemp("api-in-process") / "data",
        max_upload_bytes=UPLOAD_LIMIT_BYTES,
        max_triangles=TRIANGLE_LIMIT,
        # These tests drive the robot by script (push_to): unpaced, as fast as the simulation
        # allows. tests/api/test_teach.py runs a paced server of its own.
        real_time=False,
    ) as served:
        yield served


@pytest.fixture
def api(app_server: InProcessServer) -> Iterator[Api]:
    """A client on a new, open project of the in-process app (default cell: UR10 + water
    pump); the test fails if the app logged a traceback meanwhile."""
    client = app_server.api()
    with no_tracebacks():
        client.new_project()
        yield client
        client.cancel_all()
    client.close()


@pytest.fixture(scope="session")
def server(tmp_path_factory: pytest.TempPathFactory) -> Iterator[ServerProcess]:
    """A real ``robomach serve`` process, with the same limits as ``app_server``."""
    data = tmp_path_factory.mktemp("api") / "data"
    proc = start_server(
        data,
        env={
            "ROBOMACH_MAX_UPLOAD_BYTES": str(UPLOAD_LIMIT_BYTES),
            "ROBOMACH_MAX_TRIANGLES": str(TRIANGLE_LIMIT),
            "ROBOMACH_REAL_TIME": "0",
        },
    )
    yield proc
    code = proc.stop()
    assert code in (0, 130), proc.log()
    assert "Traceback" not in proc.log(), proc.log()


@pytest.fixture
def http_api(server: ServerProcess) -> Iterator[Api]:
    """A client over real HTTP on a new, open project of ``server``."""
    client = Api(server.base_url)
    client.new_project()
    yield client
    client.cancel_all()
    client.close()
