"""The token: required on mutating calls when configured, and to bind beyond loopback."""

from __future__ import annotations

import os
import socket
import subprocess
import sys
from collections.abc import Iterator
from pathlib import Path
from urllib.parse import urlsplit

import pytest
from fastapi.testclient import TestClient

from app.api import create_app
from app.server import build_app, data_dir_lock
from app.session import Session
from app.settings import ServerSettings
from robomach_core.errors import InvalidInputError
from tests.api.server_process import ROOT, free_port, start_server

TOKEN = "test-token-0123456789abcdef"


@pytest.fixture(scope="module")
def guarded() -> Iterator[TestClient]:
    """The app with a token, in process (the middleware is the same as over the network)."""
    settings = ServerSettings(viser_port=None, token=TOKEN)
    with TestClient(create_app(Session(), settings), raise_server_exceptions=False) as client:
        yield client


@pytest.mark.parametrize(
    ("method", "path", "body"),
    [
        ("POST", "/api/leadthrough/push", {"force_N": [1, 0, 0], "duration_s": 0.1}),
        ("POST", "/api/guide-points", None),
        ("PUT", "/api/cell", {"robot": "ur5"}),
        ("DELETE", "/api/guide-points/0", None),
        ("POST", "/api/projects", {"name": "intruder"}),
        ("PATCH", "/api/projects/1", {"name": "intruder"}),
    ],
)
def test_mutating_calls_need_the_token(
    guarded: TestClient, method: str, path: str, body: dict | None
) -> None:
    r = guarded.request(method, path, json=body)
    assert r.status_code == 401 and "token" in r.json()["detail"], r.text
    assert r.headers["www-authenticate"] == "Bearer"
    r = guarded.request(method, path, json=body, headers={"Authorization": "Bearer wrong"})
    assert r.status_code == 401 and r.json()["detail"] == "wrong token"


def test_the_token_opens_them_and_reads_stay_open(guarded: TestClient) -> None:
    assert guarded.get("/api/state").status_code == 200
    before = len(guarded.get("/api/guide-points").json())
    r = guarded.post("/api/guide-points", headers={"Authorization": f"Bearer {TOKEN}"})
    assert r.status_code == 201
    r = guarded.post("/api/guide-points", headers={"X-Robomach-Token": TOKEN})
    assert r.status_code == 201
    assert len(guarded.get("/api/guide-points").json()) == before + 2


def test_settings_refuse_an_open_bind_without_a_token(monkeypatch) -> None:
    with pytest.raises(InvalidInputError, match="ROBOMACH_TOKEN"):
        ServerSettings.from_env(host="0.0.0.0")
    with pytest.raises(InvalidInputError, match="must differ"):
        ServerSettings.from_env(port=8000, viser_port=8000)
    assert ServerSettings.from_env().loopback
    monkeypatch.setenv("ROBOMACH_TOKEN", "short")
    with pytest.raises(InvalidInputError, match="at least 16"):
        ServerSettings.from_env(host="0.0.0.0")
    monkeypatch.setenv("ROBOMACH_TOKEN", TOKEN)
    monkeypatch.setenv("ROBOMACH_HOST", "0.0.0.0")
    settings = ServerSettings.from_env()
    assert settings.token == TOKEN and not settings.loopback


@pytest.mark.parametrize(
    ("name", "value"),
    [("ROBOMACH_PORT", "80x"), ("ROBOMACH_REAL_TIME", "maybe"), ("ROBOMACH_TOKEN_READS", "2")],
)
def test_a_variable_of_the_wrong_type_is_named(monkeypatch, name: str, value: str) -> None:
    monkeypatch.setenv(name, value)
    with pytest.raises(InvalidInputError, match=f"{name}: .*, not '{value}'"):
        ServerSettings.from_env()


def test_the_variables_are_read_empty_ones_unset(monkeypatch, tmp_path: Path) -> None:
    for name, value in [("PORT", "8123"), ("VISER_PORT", ""), ("DATA", str(tmp_path)),
                        ("REAL_TIME", "off"), ("MAX_TRIANGLES", "1000")]:  # fmt: skip
        monkeypatch.setenv(f"ROBOMACH_{name}", value)
    s = ServerSettings.from_env(port=8124)  # a flag wins over its variable
    got = (s.port, s.viser_port, s.data_dir, s.real_time, s.max_triangles)
    assert got == (8124, 8080, tmp_path, False, 1000)
    assert s.refuse_foreign_hosts and not ServerSettings().refuse_foreign_hosts


@pytest.mark.slow  # a real server process
def test_cli_refuses_an_open_bind_without_a_token(tmp_path: Path) -> None:
    env = {k: v for k, v in os.environ.items() if k != "ROBOMACH_TOKEN"}
    r = subprocess.run(
        [sys.executable, "-m", "app.cli", "serve", "--host", "0.0.0.0", "--port",
         str(free_port()), "--data", str(tmp_path / "data")],
        cwd=ROOT, env=env, capture_output=True, text=True, timeout=60,
    )  # fmt: skip
    assert r.returncode == 2 and "ROBOMACH_TOKEN" in r.stderr


def test_one_server_per_data_folder(tmp_path: Path) -> None:
    with data_dir_lock(tmp_path / "data"):
        with pytest.raises(InvalidInputError, match="another robomach serve"):
            with data_dir_lock(tmp_path / "data"):
                pass
    with data_dir_lock(tmp_path / "data"):  # released on exit
        pass


# --- issue 10: the viser port must not get round the token, and must be the one reported ----


def _outward_address() -> str | None:
    """This machine's address on its main interface (no packet is sent), None without one."""
    try:
        with socket.socket(socket.AF_INET, socket.SOCK_DGRAM) as probe:
            probe.connect(("10.255.255.255", 1))
            address = probe.getsockname()[0]
    except OSError:
        return None
    return None if address.startswith("127.") or address == "0.0.0.0" else address


def _reachable(host: str, port: int) -> bool:
    try:
        with socket.create_connection((host, port), timeout=2.0):
            return True
    except OSError:
        return False


@pytest.mark.slow  # a real server process
def test_with_the_token_beyond_loopback_viser_stays_on_loopback(tmp_path: Path) -> None:
    outward = _outward_address()
    if outward is None:
        pytest.skip("this machine has no non-loopback interface to test from")
    server = start_server(
        tmp_path / "data", env={"ROBOMACH_TOKEN": TOKEN}, args=("--host", "0.0.0.0")
    )
    try:
        rest_port = urlsplit(server.base_url).port
        viser_port = urlsplit(server.viser_url).port
        assert _reachable(outward, rest_port)  # the API is served beyond loopback, with a token
        assert not _reachable(outward, viser_port)  # the scene is not: it has no token check
        assert _reachable("127.0.0.1", viser_port)
        assert "127.0.0.1 only" in server.log()
    finally:
        assert server.stop() in (0, 130)


@pytest.mark.slow  # a real server process
def test_serve_stops_with_one_line_when_the_viser_port_is_taken(tmp_path: Path) -> None:
    with socket.socket() as taken:
        taken.bind(("127.0.0.1", 0))
        taken.listen()
        port = taken.getsockname()[1]
        env = {k: v for k, v in os.environ.items() if k != "ROBOMACH_TOKEN"}
        r = subprocess.run(
            [sys.executable, "-m", "app.cli", "serve", "--port", str(free_port()),
             "--viser-port", str(port), "--data", str(tmp_path / "data")],
            cwd=ROOT, env=env, capture_output=True, text=True, timeout=60,
        )  # fmt: skip
    assert r.returncode == 2, r.stderr
    lines = [line for line in r.stderr.splitlines() if "error" in line]
    assert len(lines) == 1 and f"viser port {port}" in lines[0], r.stderr
    assert "Traceback" not in r.stderr


def test_the_workbench_reports_the_port_viser_bound(tmp_path: Path) -> None:
    """viser moves to the next port when its own is taken after serve's check: the app
    reports the port viser bound, not the one asked for."""
    with socket.socket() as taken:
        taken.bind(("127.0.0.1", 0))
        taken.listen()
        asked = taken.getsockname()[1]
        settings = ServerSettings(viser_port=asked, data_dir=tmp_path / "data")
        session = Session()
        app = build_app(settings, session)
        with TestClient(app) as client:
            reported = client.get("/api/workbench").json()["viser_port"]
            assert reported != asked and _reachable("127.0.0.1", reported)
            assert app.state.viser_port == reported


# --- issue 19, R13: reads need the token too (on by default beyond loopback) -----------------

GUARDED_READS = (
    "/api/projects/current/project.npz",  # the customer's part and robot files
    "/api/state",
    "/api/exports",
    "/api/guide-points",
    "/api/cell",
)


@pytest.fixture(scope="module")
def beyond_loopback() -> Iterator[TestClient]:
    """The app as ``--host 0.0.0.0`` with a token serves it: reads guarded by default."""
    settings = ServerSettings(viser_port=None, token=TOKEN, host="0.0.0.0")
    assert settings.reads_need_token
    with TestClient(create_app(Session(), settings), raise_server_exceptions=False) as client:
        yield client


@pytest.mark.parametrize("path", GUARDED_READS)
def test_reads_need_the_token_beyond_loopback(beyond_loopback: TestClient, path: str) -> None:
    beyond_loopback.cookies.clear()
    r = beyond_loopback.get(path)
    assert r.status_code == 401, r.text[:200]
    assert "this read is guarded" in r.json()["detail"]
    r = beyond_loopback.get(path, headers={"Authorization": "Bearer wrong-token-0123456789"})
    assert r.status_code == 401 and r.json()["detail"] == "wrong token"
    r = beyond_loopback.get(path, headers={"Authorization": f"Bearer {TOKEN}"})
    assert r.status_code == 200, r.text[:200]


def test_health_stays_open_for_liveness_probes(beyond_loopback: TestClient) -> None:
    beyond_loopback.cookies.clear()
    assert beyond_loopback.get("/api/health").status_code == 200


def test_a_read_with_the_token_leaves_a_cookie_for_reads_only(beyond_loopback: TestClient) -> None:
    """The browser's EventSource and downloads cannot send a header: the cookie stands in for
    the token on reads (HttpOnly, SameSite=Strict), never on a mutating call."""
    beyond_loopback.cookies.clear()
    r = beyond_loopback.get("/api/state", headers={"X-Robomach-Token": TOKEN})
    cookie = r.headers["set-cookie"]
    assert "HttpOnly" in cookie and "SameSite=Strict" in cookie and TOKEN not in cookie
    assert beyond_loopback.get("/api/projects/current/project.npz").status_code == 200
    r = beyond_loopback.post("/api/guide-points")
    assert r.status_code == 401 and "changes the workbench" in r.json()["detail"]
    beyond_loopback.cookies.clear()
    beyond_loopback.cookies.set("robomach_read", "0" * 64)  # a forged cookie
    assert beyond_loopback.get("/api/state").status_code == 401


def test_reads_on_loopback_are_open_unless_asked(guarded: TestClient, monkeypatch) -> None:
    assert guarded.get("/api/projects/current/project.npz").status_code == 200
    settings = ServerSettings(viser_port=None, token=TOKEN, token_reads=True)
    with TestClient(create_app(Session(), settings)) as client:
        assert client.get("/api/state").status_code == 401
    with pytest.raises(InvalidInputError, match="only when ROBOMACH_TOKEN is set"):
        ServerSettings.from_env(token_reads=True)
    for name, value in [("TOKEN", TOKEN), ("HOST", "0.0.0.0"), ("TOKEN_READS", "0")]:
        monkeypatch.setenv(f"ROBOMACH_{name}", value)
    settings = ServerSettings.from_env()
    assert not settings.reads_need_token
