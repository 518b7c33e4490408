"""A page under a name that resolves to 127.0.0.1 (DNS rebinding) gets nothing from a server on
loopback (issue 19, R8): a browser page under another host name recorded guide points through
viser with no token, its websocket being "same origin" with its own name.

The names here (``rebound.example``) are what such a page's requests carry in ``Host`` and
``Origin``; the TCP connection goes to 127.0.0.1 as the rebound DNS would send it.
"""

from __future__ import annotations

import socket
from urllib.parse import urlsplit

import httpx
import pytest
import viser
from websockets.exceptions import ConnectionClosed
from websockets.sync.client import connect

from tests.api.server_process import Api, ServerProcess

# A real server process (sockets, origins, host names): CI runs these, -m 'not slow' does not.
pytestmark = pytest.mark.slow

REBOUND = "rebound.example"


@pytest.fixture
def api(http_api: Api) -> Api:
    """Over real HTTP to ``robomach serve``: the rebound name reaches real sockets."""
    return http_api


def _websocket(port: int, name: str):
    """A websocket to 127.0.0.1:``port`` as a page served under ``name`` opens it."""
    sock = socket.create_connection(("127.0.0.1", port), timeout=10)
    return connect(
        f"ws://{name}:{port}/",
        sock=sock,
        origin=f"http://{name}:{port}",
        subprotocols=[f"viser-v{viser.__version__}"],  # what viser's own page asks for
        open_timeout=10,
        max_size=None,  # the scene (robot meshes) comes in large messages
        close_timeout=2,
    )


def _closed_code(ws) -> int | None:
    """The close code once the server has closed the socket, None while it stays open."""
    try:
        while True:
            ws.recv(timeout=3)
    except TimeoutError:
        return None
    except ConnectionClosed as exc:
        return exc.rcvd.code if exc.rcvd is not None else -1


def test_viser_refuses_a_websocket_under_a_rebound_name(server: ServerProcess, api: Api) -> None:
    port = urlsplit(server.viser_url).port
    try:
        ws = _websocket(port, REBOUND)
    except Exception as exc:  # noqa: BLE001 - a refused handshake is a refusal too
        assert "1008" in str(exc) or "403" in str(exc), exc
    else:
        with ws:
            assert _closed_code(ws) == 1008
    with _websocket(port, "127.0.0.1") as ws:  # the workbench's own page still connects
        assert _closed_code(ws) is None
    assert "refused a websocket from host 'rebound.example" in server.log()


def test_viser_refuses_a_websocket_with_two_host_headers(server: ServerProcess, api: Api) -> None:
    """Issue 32: reading the Host of such a handshake raised, and the server logged a
    traceback; which of two names was meant cannot be told, so it is refused."""
    port = urlsplit(server.viser_url).port
    sock = socket.create_connection(("127.0.0.1", port), timeout=10)
    try:
        ws = connect(
            f"ws://127.0.0.1:{port}/", sock=sock,
            additional_headers=[("Host", f"{REBOUND}:{port}")],
            subprotocols=[f"viser-v{viser.__version__}"], open_timeout=10, max_size=None,
            close_timeout=2,
        )  # fmt: skip
    except Exception as exc:  # noqa: BLE001 - a refused handshake is a refusal too
        assert "1008" in str(exc) or "400" in str(exc) or "403" in str(exc), exc
    else:
        with ws:
            assert _closed_code(ws) == 1008
    api.ok("GET", "/api/health")
    assert "Traceback" not in server.log()
    assert "refused a websocket from 2 Host and 0 Origin headers" in server.log()


@pytest.mark.parametrize(
    "path", ["/api/projects/current/project.npz", "/api/state", "/pendant/", "/api/events"]
)
def test_rest_refuses_reads_under_a_rebound_name(server: ServerProcess, path: str) -> None:
    port = urlsplit(server.base_url).port
    with httpx.Client(base_url=server.base_url, timeout=10) as http:
        r = http.get(path, headers={"Host": f"{REBOUND}:{port}"})
        assert r.status_code == 403, r.text[:300]
        assert "loopback only" in r.json()["detail"]
        if path != "/api/events":
            assert http.get(path, headers={"Host": f"localhost:{port}"}).status_code == 200
