"""The token: required on mutating calls when configured, and to bind beyond loopback."""

from __future__ import annotations

import os
import subprocess
import sys
from collections.abc import Iterator
from pathlib import Path

import pytest

from tests.api.server_process import ROOT, Api, ServerProcess, free_port, start_server

TOKEN = "test-token-0123456789abcdef"


@pytest.fixture(scope="module")
def guarded(tmp_path_factory: pytest.TempPathFactory) -> Iterator[ServerProcess]:
    proc = start_server(tmp_path_factory.mktemp("token") / "data", env={"ROBOMACH_TOKEN": TOKEN})
    yield proc
    proc.stop()


def test_mutating_calls_need_the_token(guarded: ServerProcess) -> None:
    anonymous = Api(guarded.base_url)
    assert anonymous.get("/api/state").status_code == 200  # reading is open
    for method, path, body in (
        ("POST", "/api/leadthrough/push", {"force_N": [1, 0, 0], "duration_s": 0.1}),
        ("POST", "/api/guide-points", None),
        ("PUT", "/api/cell", {"robot": "ur5"}),
        ("DELETE", "/api/guide-points/0", None),
        ("POST", "/api/projects", {"name": "intruder"}),
    ):
        r = anonymous.http.request(method, path, json=body)
        assert r.status_code == 401 and "token" in r.json()["detail"], (path, r.text)
    wrong = Api(guarded.base_url, headers={"Authorization": "Bearer not-the-token"})
    assert wrong.post("/api/guide-points").status_code == 401
    bearer = Api(guarded.base_url, headers={"Authorization": f"Bearer {TOKEN}"})
    assert bearer.post("/api/guide-points").status_code == 201
    header = Api(guarded.base_url, headers={"X-Robomach-Token": TOKEN})
    assert header.post("/api/guide-points").status_code == 201
    assert len(anonymous.ok("GET", "/api/guide-points")) == 2


def _serve(args: list[str], env: dict[str, str], tmp: Path) -> subprocess.CompletedProcess:
    full_env = {**os.environ, **env}
    if "ROBOMACH_TOKEN" not in env:
        full_env.pop("ROBOMACH_TOKEN", None)
    return subprocess.run(
        [sys.executable, "-m", "app.cli", "serve", "--data", str(tmp / "data"), *args],
        cwd=ROOT, env=full_env, capture_output=True, text=True, timeout=60,
    )  # fmt: skip


def test_binding_beyond_loopback_needs_a_token(tmp_path: Path) -> None:
    port = str(free_port())
    r = _serve(["--host", "0.0.0.0", "--port", port], {}, tmp_path)
    assert r.returncode == 2 and "ROBOMACH_TOKEN" in r.stderr
    r = _serve(["--host", "0.0.0.0", "--port", port], {"ROBOMACH_TOKEN": "short"}, tmp_path)
    assert r.returncode == 2 and "at least 16 characters" in r.stderr


def test_one_server_per_data_folder(guarded: ServerProcess) -> None:
    r = subprocess.run(
        [sys.executable, "-m", "app.cli", "serve", "--data", str(guarded.data_dir),
         "--port", str(free_port()), "--viser-port", str(free_port())],
        cwd=ROOT, capture_output=True, text=True, timeout=60,
    )  # fmt: skip
    assert r.returncode == 2 and "another robomach serve" in r.stderr
