"""Persistence: state written, the process killed (SIGKILL), restarted, state back."""

from __future__ import annotations

import random
import sqlite3
import threading
import time
from pathlib import Path

import numpy as np
import pytest

from app.store import DB_FILENAME
from tests.api.server_process import Api, start_server


def _snapshot(api: Api) -> dict:
    """Everything a user would expect to find again after a restart."""
    return {
        "project": api.ok("GET", "/api/projects/current"),
        "projects": api.ok("GET", "/api/projects"),
        "cell": api.ok("GET", "/api/cell"),
        "compliance": api.ok("GET", "/api/leadthrough/compliance"),
        "guide_points": api.ok("GET", "/api/guide-points"),
        "postprocess": api.ok("GET", "/api/postprocess"),
        "exports": api.ok("GET", "/api/exports"),
        "rapid": api.get("/api/export/rapid").text,
        "targets": api.get("/api/export/targets.csv").text,
        "samples": api.get("/api/export/samples.csv").text,
        "joints_deg": api.ok("GET", "/api/state")["joints_deg"],
    }


@pytest.mark.slow  # three real servers, one killed
def test_state_survives_kill_and_restart(tmp_path: Path) -> None:
    data = tmp_path / "data"
    # Unpaced: the guide points are taught by scripted pushes, which pacing made 30 s long.
    server = start_server(data, env={"ROBOMACH_REAL_TIME": "0"})
    try:
        api = Api(server.base_url)
        first = api.new_project()
        api.ok("PATCH", f"/api/projects/{first['id']}", json={"name": "pump job"})
        api.new_project()  # the last opened project is the one to come back
        api.learn()
        api.ok("POST", "/api/postprocess", json={"force_min_N": 4, "tolerance_mm": 0.05})
        api.ok("POST", "/api/exports", 201, json={"name": "before_kill"})
        api.compliance(["x", "z", "rz"], "tool")
        api.ok("POST", "/api/leadthrough/push", json={"force_N": [0, 0, 10], "duration_s": 0.5})
        before = _snapshot(api)
        api.http.close()
    finally:
        server.kill()  # no shutdown code runs: no checkpoint, no close

    server = start_server(data, log_name="server2.log")
    try:
        api = Api(server.base_url)
        after = _snapshot(api)
        joints_before = np.array(before.pop("joints_deg"))
        joints_after = np.array(after.pop("joints_deg"))
        before["project"].pop("updated_s")
        after["project"].pop("updated_s")
        for p in before["projects"] + after["projects"]:
            p.pop("updated_s")
        assert after == before
        # The robot is back where it was pushed (re-tared on start, so within noise).
        assert np.allclose(joints_after, joints_before, atol=1e-3)
        assert before["postprocess"]["result"]["targets"] >= 2
        assert len(before["guide_points"]) == 2
        assert "pump job" in {p["name"] for p in after["projects"]}
    finally:
        server.stop()


def _write_until_killed(server, acked: int, rng: random.Random) -> int:
    """Add, push and delete guide points from a thread, kill the server (SIGKILL) at a random
    moment of it; returns how many guide points the server last acknowledged."""
    api = Api(server.base_url)
    stop = threading.Event()

    def writer() -> None:
        nonlocal acked
        while not stop.is_set():
            try:
                r = api.post("/api/guide-points")
                if r.status_code == 201:
                    acked = r.json()["index"] + 1
                api.post("/api/leadthrough/push", json={"force_N": [2, 0, 0], "duration_s": 0.05})
                if rng.random() < 0.3 and acked:
                    if api.delete(f"/api/guide-points/{acked - 1}").status_code == 204:
                        acked -= 1
            except Exception:  # the server died mid-request
                return

    thread = threading.Thread(target=writer)
    thread.start()
    time.sleep(rng.uniform(0.5, 1.5))
    server.kill()
    stop.set()
    thread.join(10)
    return acked


@pytest.mark.slow
def test_killing_during_writes_never_corrupts_the_file(tmp_path: Path) -> None:
    """Kill the server at random moments of a stream of writes: the file stays sound and every
    acknowledged guide point is there (give or take the one in flight). The server that checks
    one round's file writes the next round's."""
    data = tmp_path / "data"
    rng = random.Random(1)
    acked = None
    for round_ in range(3):
        server = start_server(data, log_name=f"round{round_}.log")
        try:
            count = len(Api(server.base_url).ok("GET", "/api/guide-points"))
            if acked is not None:  # what the killed server acknowledged is here
                assert abs(count - acked) <= 1, (count, acked)
                assert acked > 0
            if round_ == 2:
                break
            acked = _write_until_killed(server, count, rng)
        finally:
            server.stop()  # a killed server has nothing left to stop

        with sqlite3.connect(data / DB_FILENAME) as db:
            assert db.execute("PRAGMA integrity_check").fetchone()[0] == "ok"
            assert db.execute("PRAGMA journal_mode").fetchone()[0] == "wal"
