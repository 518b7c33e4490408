"""Path-learning jobs, the job resource, and the recording for plots."""

from __future__ import annotations

import numpy as np
import pytest

from tests.api.server_process import Api

PL = "/api/path-learning"


def test_needs_two_guide_points(api: Api) -> None:
    r = api.post(PL, json={"force_N": 10, "speed_mm_s": 5})
    assert r.status_code == 409 and "at least 2 guide points" in r.json()["detail"]
    api.ok("POST", "/api/guide-points", 201)
    assert api.post(PL, json={"force_N": 10, "speed_mm_s": 5}).status_code == 409


@pytest.mark.parametrize(
    ("body", "needle"),
    [
        ({"force_N": 0.5, "speed_mm_s": 5}, "force_N"),
        ({"force_N": 80, "speed_mm_s": 5}, "force_N"),
        ({"force_N": 10, "speed_mm_s": 0}, "speed_mm_s"),
        ({"force_N": 10, "speed_mm_s": 500}, "speed_mm_s"),
        ({"force_N": 10}, "speed_mm_s"),
        ({"force_N": "ten", "speed_mm_s": 5}, "force_N"),
        ({"force_N": 10, "speed_mm_s": 5, "closed": "maybe"}, "closed"),
    ],
)
def test_rejects_bad_settings(api: Api, body: dict, needle: str) -> None:
    r = api.post(PL, json=body)
    assert r.status_code == 422 and needle in r.json()["detail"], r.text


def test_learns_the_block_wall(api: Api) -> None:
    trace = api.ok("GET", f"{PL}/recording")
    assert trace["source"] == "none" and trace["time_s"] == []
    points = api.block_guide_points()
    assert len(points) == 2
    # Pressed against the front wall (y = 135 mm minus the 1 mm tool radius): force along -y.
    for p in points:
        assert 133.0 < p["position_mm"][1] < 135.0
        assert p["force_N"][1] < -4.0
    job_id = api.ok("POST", PL, 202, json={"force_N": 10, "speed_mm_s": 20, "closed": False})[
        "job_id"
    ]
    job = api.wait_job(job_id)
    assert job["status"] == "done" and job["progress"] == 1.0 and job["error"] is None
    assert job["kind"] == "path_learning" and job["finished_s"] >= job["started_s"]

    trace = api.ok("GET", f"{PL}/recording", params={"max_points": 100})
    assert trace["source"] == "recording" and trace["completed"] is True
    assert 50 <= len(trace["time_s"]) <= 101 and trace["samples_total"] > 500
    f = np.array(trace["force_N"])
    assert abs(np.median(f) - 10.0) < 1.5  # the force loop holds the reference
    assert trace["force_reference_N"][0] == 10.0
    assert np.all(np.diff(trace["time_s"]) > 0)
    assert api.ok("GET", "/api/state")["busy"] is False


@pytest.mark.parametrize("max_points", ["1", "0", "x", "1000000"])
def test_recording_rejects_bad_max_points(api: Api, max_points: str) -> None:
    r = api.get(f"{PL}/recording", params={"max_points": max_points})
    assert r.status_code == 422 and "max_points" in r.json()["detail"]


def test_unknown_jobs_are_404(api: Api) -> None:
    for method, path in (("GET", "/api/jobs/nope"), ("POST", "/api/jobs/nope/cancel")):
        r = api.http.request(method, path)
        assert r.status_code == 404 and "no job" in r.json()["detail"]
    assert isinstance(api.ok("GET", "/api/jobs"), list)


def test_cancel_while_learning_keeps_the_last_recording(api: Api) -> None:
    api.block_guide_points()
    # 80 mm at 0.5 mm/s: minutes of simulated time, long enough to cancel mid-run.
    body = {"force_N": 10, "speed_mm_s": 0.5, "closed": False}
    job_id = api.ok("POST", PL, 202, json=body)["job_id"]
    t0 = api.ok("GET", "/api/state")["time_s"]
    while api.ok("GET", "/api/state")["time_s"] < t0 + 2.0:
        assert api.ok("GET", f"/api/jobs/{job_id}")["status"] in ("queued", "running")
    state = api.ok("GET", "/api/state")
    assert state["busy"] is True
    live = api.ok("GET", f"{PL}/recording")
    assert live["source"] == "live" and live["force_reference_N"] is None
    assert api.ok("POST", f"/api/jobs/{job_id}/cancel")["job_id"] == job_id
    job = api.wait_job(job_id, timeout_s=10)
    assert job["status"] == "cancelled" and job["error"] == "path learning was cancelled"
    assert api.ok("GET", f"{PL}/recording")["source"] == "none"
    after = api.ok("GET", "/api/state")
    assert after["busy"] is False and after["time_s"] >= state["time_s"]
    r = api.post("/api/postprocess", json={})
    assert r.status_code == 409


def test_the_wall_side_is_set_or_told_never_guessed(api: Api) -> None:
    """Two points recorded free in the pump's groove, one nearer its outer wall and one nearer
    the island's: neither a push nor the nearer wall tells the side, so "auto" is refused
    (422) with what to do, before any job, and the check says so first; with the side set
    the run learns."""
    api.compliance(["x", "y", "z"])
    for x, y in ((720.0, 96.3), (760.0, 98.7)):  # outer wall at y = 95, island at 100 mm
        api.push_to([x, y, 30.0])
        api.push_to([x, y, 17.0])
        api.ok("POST", "/api/guide-points", 201)
    api.push_to([760.0, 97.5, 30.0])
    body = {"force_N": 10, "speed_mm_s": 20, "closed": False}
    for bad, field in (({"wall_side": "up"}, "wall_side"), ({"floor_clearance_mm": 9}, "floor")):
        r = api.post(PL, json=body | bad)
        assert r.status_code == 422 and field in r.json()["detail"], r.text
    r = api.post(PL, json=body | {"wall_side": "auto"})
    assert r.status_code == 422 and "both sides" in r.json()["detail"], r.text
    assert api.ok("GET", "/api/state")["busy"] is False  # refused before any job
    warnings = api.ok("GET", f"{PL}/warnings", params={"wall_side": "auto", "closed": False})
    assert "both sides" in warnings[0]
    # The check every page shows: the refusal first, marked as one, and why the side is unknown.
    check = api.ok("GET", f"{PL}/check", params={"wall_side": "auto", "closed": False})
    assert check["findings"][0]["severity"] == "refusal"
    assert check["findings"][0]["rule"] == "wall_side"
    assert check["findings"][0]["message"] == warnings[0]
    assert "both sides" in check["wall_side"]
    check = api.ok("GET", f"{PL}/check", params={"wall_side": "right", "closed": False})
    assert all(f["severity"] != "refusal" for f in check["findings"])
    assert check["wall_side"].startswith("follows the wall on the right")
    started = api.ok("POST", PL, 202, json=body | {"wall_side": "right"})
    assert {f["message"] for f in started["findings"]} <= set(started["warnings"])
    job = api.wait_job(started["job_id"])
    assert job["status"] == "done", job
    post = api.ok("POST", "/api/postprocess", json={})
    assert post["follows_taught_wall"] is True and post["problems"] == []
    assert post["mesh_overcut_mm"] <= 0.25
