"""Browser tests: a real ``robomach serve`` process and Debian's chromium driven by Playwright.

Playwright's own browser download cannot work here, so the tests launch ``/usr/bin/chromium``
(apt: ``chromium``); without it they skip locally and fail under CI. viser's WebGL scene
renders headless through SwiftShader.
"""

from __future__ import annotations

import os
import shutil
import signal
import socket
import subprocess
import sys
import time
import uuid
from collections.abc import Iterator
from dataclasses import dataclass
from pathlib import Path

import httpx
import pytest

ROOT = Path(__file__).resolve().parents[2]
CHROMIUM = Path("/usr/bin/chromium")
CHROMIUM_ARGS = [
    "--headless=new",
    "--no-sandbox",
    "--disable-gpu",
    "--use-angle=swiftshader",
    "--disable-background-networking",
    "--disable-component-update",
    "--disable-sync",
    "--no-first-run",
]
START_TIMEOUT_S = 90.0
VIEWPORT = {"width": 1400, "height": 900}


def free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


@dataclass
class Served:
    """A running ``robomach serve``: its REST base URL, viser URL and log."""

    proc: subprocess.Popen
    base_url: str
    viser_url: str
    log_path: Path

    def log(self) -> str:
        return self.log_path.read_text(errors="replace")

    def stop(self, timeout_s: float = 20.0) -> int:
        if self.proc.poll() is None:
            self.proc.send_signal(signal.SIGINT)
        try:
            return self.proc.wait(timeout_s)
        except subprocess.TimeoutExpired:
            self.proc.kill()
            return self.proc.wait(10)


def start_serve(data_dir: Path, *, env: dict[str, str] | None = None) -> Served:
    """``robomach serve`` on free ports with ``data_dir``; returns once /api/health answers
    (the viser workbench starts in the app's lifespan, before the API answers)."""
    port, viser_port = free_port(), free_port()
    log_path = data_dir.parent / f"{data_dir.name}-serve.log"
    full_env = {**os.environ, "PYTHONUNBUFFERED": "1", **(env or {})}
    if "ROBOMACH_TOKEN" not in (env or {}):
        full_env.pop("ROBOMACH_TOKEN", None)
    with open(log_path, "ab") as log:
        proc = subprocess.Popen(
            [sys.executable, "-m", "app.cli", "serve", "--port", str(port), "--viser-port",
             str(viser_port), "--data", str(data_dir)],
            cwd=ROOT, env=full_env, stdout=log, stderr=subprocess.STDOUT,
        )  # fmt: skip
    served = Served(proc, f"http://127.0.0.1:{port}", f"http://127.0.0.1:{viser_port}/", log_path)
    deadline = time.monotonic() + START_TIMEOUT_S
    while time.monotonic() < deadline:
        if proc.poll() is not None:
            raise RuntimeError(f"robomach serve exited with {proc.returncode}:\n{served.log()}")
        try:
            if httpx.get(served.base_url + "/api/health", timeout=1.0).status_code == 200:
                return served
        except httpx.TransportError:
            pass
        time.sleep(0.2)
    served.stop()
    raise RuntimeError(f"robomach serve did not answer within {START_TIMEOUT_S} s:\n{served.log()}")


@pytest.fixture(scope="session")
def served(tmp_path_factory: pytest.TempPathFactory) -> Iterator[Served]:
    """One server for the browser tests (each test opens its own project)."""
    server = start_serve(tmp_path_factory.mktemp("browser") / "data")
    yield server
    code = server.stop()
    assert code in (0, 130), server.log()
    assert "Traceback" not in server.log(), server.log()


@pytest.fixture
def api(served: Served) -> Iterator[httpx.Client]:
    """A REST client on a new, open project: each test starts from the default cell."""
    client = httpx.Client(base_url=served.base_url, timeout=60.0)
    r = client.post("/api/projects", json={"name": f"browser-{uuid.uuid4().hex[:8]}"})
    assert r.status_code == 201, r.text
    yield client
    for job in client.get("/api/jobs").json():
        if job["status"] in ("queued", "running"):
            client.post(f"/api/jobs/{job['job_id']}/cancel")
    client.close()


@pytest.fixture(scope="session")
def browser():
    """Headless chromium (Debian's), shared by the tests."""
    if not CHROMIUM.exists() and shutil.which("chromium") is None:
        message = "chromium is not installed (apt-get install chromium chromium-driver)"
        if os.environ.get("CI"):
            pytest.fail(message)
        pytest.skip(message)
    from playwright.sync_api import sync_playwright

    with sync_playwright() as p:
        executable = str(CHROMIUM) if CHROMIUM.exists() else shutil.which("chromium")
        b = p.chromium.launch(executable_path=executable, args=CHROMIUM_ARGS)
        yield b
        b.close()


@pytest.fixture
def page(browser):
    """A fresh browser context (own localStorage, downloads accepted) and page."""
    context = browser.new_context(viewport=VIEWPORT, accept_downloads=True)
    context.set_default_timeout(30_000)
    pg = context.new_page()
    yield pg
    context.close()
