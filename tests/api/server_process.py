"""Start ``robomach serve`` as a real process for the HTTP tests, and a small client on it."""

from __future__ import annotations

import os
import signal
import socket
import subprocess
import sys
import time
import uuid
from dataclasses import dataclass
from pathlib import Path

import httpx
import numpy as np

ROOT = Path(__file__).resolve().parents[2]
START_TIMEOUT_S = 60.0
POLL_S = 0.02  # how often a start or a job is looked at


_HANDED_OUT: set[int] = set()


def free_port() -> int:
    """A free port on 127.0.0.1 that this process has not handed out before.

    The kernel may give a port just closed again, so two calls in a row (a server's REST and
    viser ports) could answer the same one, and the server refuses to start (CI run, 2026-12-05).
    """
    while True:
        with socket.socket() as s:
            s.bind(("127.0.0.1", 0))
            port = s.getsockname()[1]
        if port not in _HANDED_OUT:
            _HANDED_OUT.add(port)
            return port


@dataclass
class ServerProcess:
    """A running ``robomach serve``: its REST base URL, viser URL, data folder and log."""

    proc: subprocess.Popen
    base_url: str
    data_dir: Path
    log_path: Path
    viser_url: str = ""

    def log(self) -> str:
        return self.log_path.read_text(errors="replace")

    def stop(self, timeout_s: float = 20.0, *, kill_on_timeout: bool = False) -> int:
        """Ctrl-C and wait; returns the exit code (SIGKILL after the wait if asked)."""
        if self.proc.poll() is None:
            self.proc.send_signal(signal.SIGINT)
        try:
            return self.proc.wait(timeout_s)
        except subprocess.TimeoutExpired:
            if not kill_on_timeout:
                raise
            self.proc.kill()
            return self.proc.wait(10)

    def kill(self) -> None:
        """SIGKILL: no shutdown code runs."""
        self.proc.kill()
        self.proc.wait(10)


def start_server(
    data_dir: Path,
    *,
    env: dict[str, str] | None = None,
    args: tuple[str, ...] = (),
    log_name: str = "server.log",
    start_timeout_s: float = START_TIMEOUT_S,
    port: int | None = None,
    viser_port: int | None = None,
) -> ServerProcess:
    """``robomach serve`` with ``data_dir`` on the given ports (free ones by default: a restart
    gives the first start's); returns once /api/health answers."""
    port, viser_port = port or free_port(), viser_port or free_port()
    log_path = data_dir.parent / f"{data_dir.name}-{log_name}"
    full_env = {**os.environ, "PYTHONUNBUFFERED": "1", **(env or {})}
    if "ROBOMACH_TOKEN" not in (env or {}):
        full_env.pop("ROBOMACH_TOKEN", None)
    with open(log_path, "ab") as log:
        proc = subprocess.Popen(
            [sys.executable, "-m", "app.cli", "serve", "--port", str(port), "--viser-port",
             str(viser_port), "--data", str(data_dir), *args],
            cwd=ROOT, env=full_env, stdout=log, stderr=subprocess.STDOUT,
            # Ctrl-C reaches it as from a terminal, even from a suite run in the background
            preexec_fn=lambda: signal.signal(signal.SIGINT, signal.SIG_DFL),
        )  # fmt: skip
    server = ServerProcess(
        proc, f"http://127.0.0.1:{port}", data_dir, log_path, f"http://127.0.0.1:{viser_port}/"
    )
    deadline = time.monotonic() + start_timeout_s
    # One client for every poll: ``httpx.get`` made a client, and loaded the CA certificates
    # into its SSL context (0.05-0.1 s of CPU), per poll, while the server started.
    with httpx.Client(timeout=1.0) as client:
        while time.monotonic() < deadline:
            if proc.poll() is not None:
                raise RuntimeError(f"robomach serve exited with {proc.returncode}:\n{server.log()}")
            try:
                if client.get(server.base_url + "/api/health").status_code == 200:
                    return server
            except httpx.TransportError:
                pass
            time.sleep(POLL_S)
    server.kill()
    raise RuntimeError(f"robomach serve did not answer within {start_timeout_s} s:\n{server.log()}")


class Api:
    """An HTTP client with the multi-step moves the tests share (mm, N, s).

    Over a server's URL (a client of its own), or over a given client such as the
    ``TestClient`` of the in-process app (shared: ``close`` leaves it open).
    """

    def __init__(
        self, server: str | httpx.Client, *, headers: dict[str, str] | None = None
    ) -> None:
        if isinstance(server, httpx.Client):
            assert headers is None, "set headers on the shared client's requests"
            self.http, self._owns_http = server, False
        else:
            self.http = httpx.Client(base_url=server, timeout=60.0, headers=headers)
            self._owns_http = True

    def close(self) -> None:
        if self._owns_http:
            self.http.close()

    def get(self, path: str, **kw) -> httpx.Response:
        return self.http.get(path, **kw)

    def post(self, path: str, **kw) -> httpx.Response:
        return self.http.post(path, **kw)

    def put(self, path: str, **kw) -> httpx.Response:
        return self.http.put(path, **kw)

    def patch(self, path: str, **kw) -> httpx.Response:
        return self.http.patch(path, **kw)

    def delete(self, path: str, **kw) -> httpx.Response:
        return self.http.delete(path, **kw)

    def ok(self, method: str, path: str, status: int = 200, **kw) -> dict | list | None:
        """Call and insist on ``status``; returns the JSON body (None for 204)."""
        r = self.http.request(method, path, **kw)
        assert r.status_code == status, f"{method} {path}: {r.status_code} {r.text}"
        return None if r.status_code == 204 else r.json()

    def new_project(self) -> dict:
        return self.ok("POST", "/api/projects", 201, json={"name": f"test-{uuid.uuid4().hex[:8]}"})

    def position_mm(self) -> np.ndarray:
        return np.array(self.ok("GET", "/api/state")["tcp"]["position_mm"])

    def push_to(self, goal_mm: list[float], *, tolerance_mm: float = 1.0) -> np.ndarray:
        """Push the tool to ``goal_mm`` with the admittance (damping 500 N*s/m): f = D e / T."""
        for _ in range(40):
            p = self.position_mm()
            err = np.asarray(goal_mm, dtype=float) - p
            if np.linalg.norm(err) < tolerance_mm:
                return p
            f = np.clip(500.0 * err * 1e-3 / 0.5, -25.0, 25.0)
            body = {"force_N": f.tolist(), "duration_s": 0.5}
            self.ok("POST", "/api/leadthrough/push", json=body)
        raise AssertionError(f"the tool did not reach {goal_mm}; it is at {p}")

    def compliance(self, axes: list[str], frame: str = "base") -> None:
        self.ok("PUT", "/api/leadthrough/compliance", json={"axes": axes, "frame": frame})

    def block_guide_points(self, xs_mm: tuple[float, ...] = (760.0, 840.0)) -> list[dict]:
        """On the block (front wall at y = 135 mm), guide points pressed gently against the wall
        at z = 30 mm, recorded by pushes only."""
        self.ok("PUT", "/api/cell", json={"workpiece": "block"})
        self.compliance(["x", "y", "z"])
        self.push_to([xs_mm[0], 120.0, 80.0])
        points = []
        for x in xs_mm:
            self.compliance(["x", "y", "z"])
            self.push_to([x, 131.0, 30.0])
            self.compliance(["x", "y"])
            self.ok("POST", "/api/leadthrough/push", json={"force_N": [0, 6, 0], "duration_s": 1.5})
            points.append(self.ok("POST", "/api/guide-points", 201))
        self.compliance(["x", "y", "z"])
        return points

    def wait_job(self, job_id: str, timeout_s: float = 60.0) -> dict:
        deadline = time.monotonic() + timeout_s
        while time.monotonic() < deadline:
            job = self.ok("GET", f"/api/jobs/{job_id}")
            if job["status"] not in ("queued", "running"):
                return job
            time.sleep(POLL_S)
        raise AssertionError(f"job {job_id} did not end within {timeout_s} s")

    def learn(self, *, speed_mm_s: float = 20.0) -> dict:
        """Two guide points on the block and a short open path-learning run (~1 s compute)."""
        self.block_guide_points()
        body = {"force_N": 10, "speed_mm_s": speed_mm_s, "closed": False}
        job_id = self.ok("POST", "/api/path-learning", 202, json=body)["job_id"]
        job = self.wait_job(job_id)
        assert job["status"] == "done", job
        return job

    def cancel_all(self) -> None:
        for job in self.ok("GET", "/api/jobs"):
            if job["status"] in ("queued", "running"):
                self.http.post(f"/api/jobs/{job['job_id']}/cancel")
                self.wait_job(job["job_id"])


# --- memory of a running server (Linux /proc) ----------------------------------------------


def _status_kb(pid: int, field: str) -> int:
    with open(f"/proc/{pid}/status") as status:
        for line in status:
            if line.startswith(f"{field}:"):
                return int(line.split()[1])
    return 0


def _children(pid: int) -> list[int]:
    """The children of every thread of ``pid`` (a process started from a worker thread is
    listed under that thread, not under the main one)."""
    kids: list[int] = []
    try:
        tasks = os.listdir(f"/proc/{pid}/task")
    except OSError:
        return kids
    for task in tasks:
        try:
            with open(f"/proc/{pid}/task/{task}/children") as f:
                kids += [int(k) for k in f.read().split()]
        except OSError:
            continue
    return kids


def descendants(pid: int) -> list[int]:
    """Every live process under ``pid`` (the isolation helper, the machining pool's
    forkserver and workers, and their children)."""
    found, frontier = [], [pid]
    while frontier:
        kids = _children(frontier.pop())
        found += kids
        frontier += kids
    return found


def reset_peak_rss(pid: int) -> None:
    """Start a new peak: the kernel sets ``VmHWM`` back to the current RSS (clear_refs 5)."""
    for p in (pid, *descendants(pid)):
        try:
            with open(f"/proc/{p}/clear_refs", "w") as f:
                f.write("5")
        except OSError:
            pass


def peak_rss_bytes(pid: int) -> int:
    """Peak resident memory (``VmHWM``) of ``pid`` since start or ``reset_peak_rss``."""
    return _status_kb(pid, "VmHWM") * 1024


def rss_bytes(pid: int) -> int:
    return _status_kb(pid, "VmRSS") * 1024
