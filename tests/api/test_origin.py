"""Cross-site writes and oversized uploads over real HTTP (issue 10, items 6 and 3), and the
viser websocket's origin check (item 7). The server is the shared ``robomach serve`` of
tests/api/conftest.py (no token, on loopback: the case the issue exploited)."""

from __future__ import annotations

import socket
import time
from urllib.parse import urlsplit

import pytest
import viser
from websockets.exceptions import ConnectionClosed
from websockets.sync.client import connect

from tests.api.conftest import UPLOAD_LIMIT_BYTES
from tests.api.server_process import Api, ServerProcess

# A real server process (sockets, origins, host names): CI runs these, -m 'not slow' does not.
pytestmark = pytest.mark.slow

CUBE_STL = b"""solid cube
facet normal 0 0 -1
outer loop
vertex 0 0 0
vertex 10 0 0
vertex 0 10 0
endloop
endfacet
endsolid cube
"""


@pytest.fixture
def api(http_api: Api) -> Api:
    """Over real HTTP to ``robomach serve``: origins, ports and the viser websocket are
    checked on real sockets."""
    return http_api


def _guide_point_count(api: Api) -> int:
    return len(api.ok("GET", "/api/guide-points"))


def _other_port_origin(server: ServerProcess) -> str:
    """Another port on the same loopback host: the issue's attacker page."""
    port = urlsplit(server.base_url).port
    return f"http://127.0.0.1:{port + 1 if port < 65535 else port - 1}"


@pytest.mark.parametrize(
    "headers",
    [
        {"Origin": "http://127.0.0.1:1"},
        {"Origin": "http://evil.example"},
        {"Origin": "null"},
        {"Referer": "http://evil.example/page.html"},
    ],
)
def test_a_write_from_another_origin_is_refused(api: Api, headers: dict) -> None:
    before = _guide_point_count(api)
    r = api.post("/api/guide-points", headers=headers)
    assert r.status_code == 403, r.text
    assert "cross-site request refused" in r.json()["detail"]
    r = api.put("/api/cell", json={"robot": "ur5"}, headers=headers)
    assert r.status_code == 403, r.text
    assert _guide_point_count(api) == before
    assert api.ok("GET", "/api/cell")["robot"] == "ur10"


def test_a_multipart_upload_from_another_origin_is_refused(api: Api, server: ServerProcess) -> None:
    api.ok("POST", "/api/guide-points", 201)
    files = {"file": ("part.stl", CUBE_STL, "application/octet-stream")}
    r = api.post("/api/cell/workpiece", files=files, headers={"Origin": _other_port_origin(server)})
    assert r.status_code == 403, r.text
    assert api.ok("GET", "/api/cell")["workpiece"] == "water_pump"
    assert _guide_point_count(api) == 1


def test_a_rebound_name_is_not_this_loopback_server(api: Api, server: ServerProcess) -> None:
    """DNS rebinding: evil.example now resolves to 127.0.0.1, so its page is "same origin"
    with the Host it sends; a server on loopback takes browser writes from loopback names only."""
    port = urlsplit(server.base_url).port
    before = _guide_point_count(api)
    rebound = {"Origin": f"http://evil.example:{port}", "Host": f"evil.example:{port}"}
    r = api.post("/api/guide-points", headers=rebound)
    assert r.status_code == 403, r.text
    assert _guide_point_count(api) == before


def test_same_origin_and_scripts_may_write(api: Api, server: ServerProcess) -> None:
    before = _guide_point_count(api)
    api.ok("POST", "/api/guide-points", 201, headers={"Origin": server.base_url})
    api.ok("POST", "/api/guide-points", 201, headers={"Referer": server.base_url + "/pendant/"})
    api.ok("POST", "/api/guide-points", 201)  # no Origin, no Referer: curl, scripts
    port = urlsplit(server.base_url).port
    local = Api(f"http://localhost:{port}")  # the same server by another name
    try:
        local.ok("POST", "/api/guide-points", 201, headers={"Origin": f"http://localhost:{port}"})
    finally:
        local.http.close()
    assert _guide_point_count(api) == before + 4
    # Reads stay open to every origin.
    assert api.get("/api/state", headers={"Origin": "http://evil.example"}).status_code == 200


def test_an_upload_declaring_more_than_the_limit_is_refused_before_it_is_read(
    server: ServerProcess,
) -> None:
    """Only the headers are sent: a server that waited for the body would time out."""
    parts = urlsplit(server.base_url)
    declared = UPLOAD_LIMIT_BYTES * 5
    head = (
        "POST /api/cell/workpiece HTTP/1.1\r\n"
        f"Host: {parts.netloc}\r\n"
        "Content-Type: multipart/form-data; boundary=xyz\r\n"
        f"Content-Length: {declared}\r\n\r\n--xyz\r\n"
    )
    # A server that waited for the body would answer nothing: recv would time out.
    with socket.create_connection((parts.hostname, parts.port), timeout=10.0) as conn:
        conn.sendall(head.encode())
        chunks = []
        while chunk := conn.recv(65536):  # the server closes after its answer
            chunks.append(chunk)
        reply = b"".join(chunks).decode(errors="replace")
    assert reply.startswith("HTTP/1.1 413"), reply
    assert "limit" in reply and "application/json" in reply, reply


def _viser_socket(server: ServerProcess, origin: str | None):
    url = server.viser_url.replace("http://", "ws://")
    return connect(
        url,
        origin=origin,
        subprotocols=[f"viser-v{viser.__version__}"],
        open_timeout=10,
        max_size=None,
    )


def test_viser_refuses_a_websocket_from_another_origin(server: ServerProcess) -> None:
    with _viser_socket(server, "http://evil.example") as ws:
        with pytest.raises(ConnectionClosed) as closed:
            deadline = time.monotonic() + 10.0
            while time.monotonic() < deadline:
                ws.recv(timeout=10)
        assert closed.value.rcvd is not None and closed.value.rcvd.code == 1008
    own = server.viser_url.rstrip("/")
    with _viser_socket(server, own) as ws:  # the viser page itself
        assert ws.recv(timeout=10)
    with _viser_socket(server, None) as ws:  # not a browser
        assert ws.recv(timeout=10)
