"""The HTTP tests share one real ``robomach serve`` process; each test opens a fresh project."""

from __future__ import annotations

from collections.abc import Iterator

import pytest

from tests.api.server_process import Api, ServerProcess, start_server

# Small limits, so that the limit tests need small files.
UPLOAD_LIMIT_BYTES = 200_000
TRIANGLE_LIMIT = 1000


@pytest.fixture(scope="session")
def server(tmp_path_factory: pytest.TempPathFactory) -> Iterator[ServerProcess]:
    data = tmp_path_factory.mktemp("api") / "data"
    proc = start_server(
        data,
        env={
            "ROBOMACH_MAX_UPLOAD_BYTES": str(UPLOAD_LIMIT_BYTES),
            "ROBOMACH_MAX_TRIANGLES": str(TRIANGLE_LIMIT),
            # These tests drive the robot by script (push_to): unpaced, as fast as the
            # simulation allows. tests/api/test_teach.py runs a paced server of its own.
            "ROBOMACH_REAL_TIME": "0",
        },
    )
    yield proc
    code = proc.stop()
    assert code in (0, 130), proc.log()
    assert "Traceback" not in proc.log(), proc.log()


@pytest.fixture
def api(server: ServerProcess) -> Iterator[Api]:
    """A client on a new, open project (default cell: UR10 + water pump)."""
    client = Api(server.base_url)
    client.new_project()
    yield client
    client.cancel_all()
    client.http.close()
