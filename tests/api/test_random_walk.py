"""A random walk over the workbench's stateful operations on a real ``robomach serve``: cell
changes and uploads, the example and proposed guide points, clicks, recorded and deleted
points, path learning, post-processing, machining, exports, calibration, pushes and jogs,
projects opened and deleted, and the reads a page makes, in a fresh order each run (the seed
is printed; ``ROBOMACH_SEED`` replays it). No answer is a server error and the server's log
holds no traceback, whatever came before.

The request fuzzer (``test_fuzz.py``) sends each operation alone to a server at rest, so it
never sees one result made stale by another: this walk found post-processing answering 503
after a guide point recorded past the learning (the taught-wall check paired the project's
points with the recording's).
"""

from __future__ import annotations

import io
import random
import time
from collections import Counter
from collections.abc import Callable
from pathlib import Path

import pytest
import trimesh

from tests.api.server_process import Api, start_server
from tests.envelope import replay, run_seed

pytestmark = pytest.mark.slow  # a server of its own, a few hundred requests and jobs

STEPS = 200
JOB_WAIT_S = 120.0
PUMP_WALLS_MM = [(0.0, -65.0, 17.0), (-100.0, 0.0, 17.0), (0.0, 65.0, 17.0)]


class Walk:
    """The walk's state: the API, its random draws, what it was answered and what failed."""

    def __init__(self, api: Api, rng: random.Random) -> None:
        self.api, self.rng = api, rng
        self.failures: list[str] = []
        self.answers: Counter[tuple[str, int]] = Counter()
        self.action = ""

    def call(self, method: str, path: str, **kw):
        r = getattr(self.api, method.lower())(path, **kw)
        self.answers[(self.action, r.status_code)] += 1
        if r.status_code >= 500:
            self.failures.append(f"{method} {path} {kw.get('json')}: {r.status_code} {r.text}")
        return r

    def job(self, r) -> None:
        """Wait for the job ``r`` started (``Api.wait_job``), or cancel it at a random moment (a
        third of them)."""
        if r.status_code != 202:
            return
        job = r.json()["job_id"]
        if self.rng.random() < 0.3:
            time.sleep(self.rng.uniform(0.0, 0.5))
            self.call("POST", f"/api/jobs/{job}/cancel")
            return
        self.api.wait_job(job, JOB_WAIT_S)  # any end; a job that never ends fails the walk

    def some_project(self) -> str | None:
        listed = self.call("GET", "/api/projects").json()
        return self.rng.choice(listed)["id"] if listed else None


def _box_stl(rng: random.Random) -> bytes:
    mesh = trimesh.creation.box(
        extents=(rng.uniform(60, 300), rng.uniform(40, 200), rng.uniform(15, 60))
    )
    mesh.apply_translation([0.0, 0.0, mesh.extents[2] / 2])
    buf = io.BytesIO()
    mesh.export(buf, file_type="stl")
    return buf.getvalue()


def _actions(w: Walk) -> dict[str, tuple[float, Callable[[], object]]]:
    """Each operation (its weight, what it sends), with valid random settings: an answer of
    409 or 422 is the server saying why not, and the walk goes on."""
    rng, call = w.rng, w.call

    def cell() -> None:
        body = {
            "robot": rng.choice(["ur10", "ur5", "irb4400", "irb2400", "kr270"]),
            "workpiece": rng.choice(["water_pump", "block"]),
            "realistic": rng.random() < 0.3,
            "tool_radius_mm": rng.choice([0.5, 1.0, 2.0, 5.0]),
        }
        call("PUT", "/api/cell", json={k: v for k, v in body.items() if rng.random() < 0.7})

    def open_project() -> None:
        if (pid := w.some_project()) is not None:
            call("POST", f"/api/projects/{pid}/open")

    def delete_project() -> None:
        if rng.random() < 0.3 and (pid := w.some_project()) is not None:
            call("DELETE", f"/api/projects/{pid}")

    def reads() -> None:
        for path in ("/api/state", "/api/projects/current/status", "/api/path-learning/check",
                     "/api/cell/calibration", "/api/machining/result", "/api/postprocess",
                     "/api/guide-points/proposal", "/api/cell/calibration/plan"):  # fmt: skip
            call("GET", path)

    def slid() -> dict:
        return {"point_mm": [rng.uniform(-100, 100), rng.choice([-65.0, 65.0]), 17.0]}

    return {
        "cell": (0.7, cell),
        "placement": (1.0, lambda: call("PUT", "/api/cell", json={"wobj_mm_deg": [
            rng.uniform(700, 900), rng.uniform(80, 240), 0.0, rng.uniform(-30, 30)]})),
        "upload": (0.3, lambda: call("POST", "/api/cell/workpiece", files={
            "file": ("part.stl", _box_stl(rng), "application/octet-stream")})),
        "example": (3.0, lambda: w.job(call("POST", "/api/guide-points/example"))),
        "propose": (2.0, lambda: call("POST", "/api/guide-points/propose",
                                      json={"point_mm": list(rng.choice(PUMP_WALLS_MM))})),
        "slide": (1.0, lambda: call("PATCH", f"/api/guide-points/proposal/points/"
                                    f"{rng.randrange(12)}", json=slid())),
        "drop": (1.0, lambda: call("DELETE",
                                   f"/api/guide-points/proposal/points/{rng.randrange(12)}")),
        "accept": (2.0, lambda: w.job(call("POST", "/api/guide-points/proposal/accept"))),
        "click": (1.0, lambda: call("POST", "/api/guide-points/from-surface", json={
            "point_mm": [rng.uniform(-90, 90), -65.0, rng.uniform(14, 20)]})),
        "record": (1.0, lambda: call("POST", "/api/guide-points")),
        "delete": (0.5, lambda: call("DELETE", f"/api/guide-points/{rng.randrange(16)}")),
        "clear": (0.3, lambda: call("DELETE", "/api/guide-points")),
        "learn": (5.0, lambda: w.job(call("POST", "/api/path-learning", json={
            "force_N": rng.uniform(10, 20), "speed_mm_s": rng.choice([5, 10, 20, 50]),
            "closed": rng.random() < 0.8}))),
        "post": (4.0, lambda: call("POST", "/api/postprocess", json={
            "tolerance_mm": rng.choice([0.01, 0.05, 0.2, 1.0]), "arcs": rng.random() < 0.5})),
        "machine": (2.0, lambda: w.job(call("POST", "/api/machining/run"))),
        "compare": (1.0, lambda: w.job(call("POST", "/api/machining/compare"))),
        "export": (2.0, lambda: call("POST", "/api/exports",
                                     json={"name": f"e{rng.randrange(100)}"})),
        "program": (2.0, lambda: call("GET", "/api/export/program/"
                                      + rng.choice(["rapid", "urscript", "krl"]))),
        "calibrate": (1.0, lambda: w.job(call("POST", "/api/cell/calibration/auto"))),
        "accept_calibration": (1.0, lambda: call("POST", "/api/cell/calibration/accept")),
        "drop_calibration": (1.0, lambda: call("DELETE", "/api/cell/calibration")),
        "touch": (1.0, lambda: call("POST", "/api/cell/calibration/touches", json={
            "at_wobj_mm": [rng.uniform(-120, 120), rng.uniform(-80, 80), 20.0]})),
        "undo_touch": (1.0, lambda: call("DELETE", "/api/cell/calibration/touches/last")),
        "push": (1.0, lambda: call("POST", "/api/leadthrough/push", json={
            "force_N": [rng.uniform(-20, 20) for _ in range(3)],
            "duration_s": rng.uniform(0.0, 0.5)})),
        "jog": (1.0, lambda: call("POST", "/api/leadthrough/jog", json={
            "axis": rng.choice("xyz"), "step": rng.uniform(-30, 30),
            "frame": rng.choice(["base", "tool", "wobj"])})),
        "home": (1.0, lambda: call("POST", "/api/leadthrough/home")),
        "new_project": (0.5, lambda: call("POST", "/api/projects",
                                          json={"name": f"p{rng.randrange(1000)}"})),
        "open_project": (1.0, open_project),
        "delete_project": (0.3, delete_project),
        "reads": (1.0, reads),
    }  # fmt: skip


def test_a_random_walk_over_the_workbench_gets_no_server_error(tmp_path: Path) -> None:
    seed = run_seed()
    rng = random.Random(seed)
    server = start_server(tmp_path / "data", env={"ROBOMACH_REAL_TIME": "0"})
    api = Api(server.base_url)
    walk = Walk(api, rng)
    actions = _actions(walk)
    names = list(actions)
    weights = [actions[n][0] for n in names]
    done: list[str] = []
    try:
        for _ in range(STEPS):
            walk.action = rng.choices(names, weights)[0]
            done.append(walk.action)
            actions[walk.action][1]()
            if walk.failures:
                break
    finally:
        api.close()
        stopped = server.stop()
    print(f"{replay(seed)}: {len(done)} steps; answers {sorted(walk.answers.items())}")
    where = f"{replay(seed)}, after {done[-8:]}"
    assert not walk.failures, f"{where}:\n" + "\n".join(walk.failures)
    assert stopped in (0, 130), server.log()[-3000:]
    assert "Traceback" not in server.log(), f"{where}:\n{server.log()[-5000:]}"
