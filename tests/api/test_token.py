"""The token: required on mutating calls when configured, and to bind beyond loopback."""

from __future__ import annotations

import os
import subprocess
import sys
from collections.abc import Iterator
from pathlib import Path

import pytest
from fastapi.testclient import TestClient

from app.api import create_app
from app.server import data_dir_lock
from app.session import Session
from app.settings import ServerSettings
from robomach_core.errors import InvalidInputError
from tests.api.server_process import ROOT, free_port

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


def test_settings_refuse_an_open_bind_without_a_token() -> None:
    with pytest.raises(InvalidInputError, match="ROBOMACH_TOKEN"):
        ServerSettings.from_env({}, host="0.0.0.0")
    with pytest.raises(InvalidInputError, match="at least 16"):
        ServerSettings.from_env({"ROBOMACH_TOKEN": "short"}, host="0.0.0.0")
    with pytest.raises(InvalidInputError, match="must differ"):
        ServerSettings.from_env({}, port=8000, viser_port=8000)
    settings = ServerSettings.from_env({"ROBOMACH_TOKEN": TOKEN, "ROBOMACH_HOST": "0.0.0.0"})
    assert settings.token == TOKEN and not settings.loopback
    assert ServerSettings.from_env({}).loopback


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
