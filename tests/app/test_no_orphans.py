"""No process of the machining pool outlives the process it works for (issue 32, point 5):
kill -9 of the server during a comparison left the forkserver and its two workers idle under
init (2.9 GB); SIGTERM to ``robomach machine`` exited at once and left them computing.

Real processes: a ``robomach serve`` over HTTP and a ``robomach machine`` run; every process
under them (the forkserver, its workers, the resource tracker, the isolation helper) must be
gone within 5 s of their end.
"""

from __future__ import annotations

import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import pytest

from tests.api.server_process import Api, descendants, start_server
from tests.demo_project import block_demo_dir

GONE_WITHIN_S = 5.0


def _cmdline(pid: int) -> str:
    try:
        return Path(f"/proc/{pid}/cmdline").read_bytes().replace(b"\0", b" ").decode()
    except OSError:
        return ""


def _running(pid: int) -> bool:
    """Alive and not a zombie (a dead child nobody reaped has ended)."""
    try:
        state = Path(f"/proc/{pid}/stat").read_text().rsplit(")", 1)[1].split()[0]
    except (OSError, IndexError):
        return False
    return state != "Z"


def _wait_for_pool_workers(root: int, timeout_s: float = 120.0) -> list[int]:
    """Every process under ``root`` once the forkserver under it has forked workers."""
    deadline = time.monotonic() + timeout_s
    while time.monotonic() < deadline:
        procs = descendants(root)
        servers = [p for p in procs if "forkserver" in _cmdline(p)]
        workers = [p for p in procs if any(p in descendants(s) for s in servers)]
        if workers:
            return procs
        time.sleep(0.05)
    raise AssertionError(f"no pool worker under {root} within {timeout_s} s")


def _assert_all_end(pids: list[int], what: str) -> None:
    deadline = time.monotonic() + GONE_WITHIN_S
    left = [p for p in pids if _running(p)]
    while left and time.monotonic() < deadline:
        time.sleep(0.1)
        left = [p for p in left if _running(p)]
    try:
        assert not left, (
            f"{len(left)} processes outlived {what} by {GONE_WITHIN_S} s: "
            + "; ".join(f"{p}: {_cmdline(p)[:120]}" for p in left)
        )
    finally:
        _kill(left)  # do not leave them to the rest of the run


def _kill(pids: list[int]) -> None:
    for p in pids:
        if _running(p):
            try:
                os.kill(p, signal.SIGKILL)
            except ProcessLookupError:
                pass


@pytest.mark.slow  # a real server, a comparison
def test_no_pool_process_outlives_a_server_killed_during_a_comparison(tmp_path: Path) -> None:
    server = start_server(tmp_path / "data", env={"ROBOMACH_REAL_TIME": "0"})
    api = Api(server.base_url)
    try:
        api.new_project()
        api.learn()
        api.ok("POST", "/api/postprocess", json={"tolerance_mm": 0.05})
        api.ok("PUT", "/api/machining/settings", json={"variations": 20})  # a long comparison
        api.ok("POST", "/api/machining/compare", 202)
        procs = _wait_for_pool_workers(server.proc.pid)
        server.kill()
        _assert_all_end(procs, "kill -9 of the server")
    finally:
        api.close()
        if server.proc.poll() is None:
            server.kill()
        _kill(descendants(server.proc.pid))


@pytest.mark.slow  # the shared block demo, a machine run
def test_no_pool_process_outlives_sigterm_of_the_cli(tmp_path: Path) -> None:
    proc = subprocess.Popen(
        [sys.executable, "-m", "app.cli", "machine", "--out", str(tmp_path / "o"), "--from",
         str(block_demo_dir()), "--variations", "20", "--no-plot"],
        stdout=subprocess.DEVNULL, stderr=subprocess.PIPE, text=True,
    )  # fmt: skip
    procs: list[int] = []
    try:
        procs = _wait_for_pool_workers(proc.pid)
        proc.send_signal(signal.SIGTERM)
        _, err = proc.communicate(timeout=30)
        _assert_all_end(procs, "SIGTERM of robomach machine")
        assert proc.returncode == 143, err  # stopped as Ctrl-C stops it, 128 + SIGTERM
        assert "interrupted" in err and "Traceback" not in err, err
    finally:
        if proc.poll() is None:
            proc.kill()
        _kill(procs)
