"""Recording, listing and deleting guide points; the example lead-through job and its cancel."""

from __future__ import annotations

import time

import numpy as np
import pytest

from tests.api.server_process import Api

GP = "/api/guide-points"


def test_record_list_delete(api: Api) -> None:
    assert api.ok("GET", GP) == []
    first = api.ok("POST", GP, 201)
    assert first["index"] == 0
    state = api.ok("GET", "/api/state")
    assert np.allclose(first["position_mm"], state["tcp"]["position_mm"], atol=1e-3)
    assert len(first["quaternion_wxyz"]) == 4 and len(first["joints_deg"]) == 6
    api.ok("POST", "/api/leadthrough/push", json={"force_N": [0, 10, 0], "duration_s": 0.5})
    second = api.ok("POST", GP, 201)
    third = api.ok("POST", GP, 201)
    assert (second["index"], third["index"]) == (1, 2)
    assert second["position_mm"][1] > first["position_mm"][1] + 5
    listed = api.ok("GET", GP)
    assert [p["index"] for p in listed] == [0, 1, 2]
    api.ok("DELETE", f"{GP}/0", 204)
    listed = api.ok("GET", GP)
    assert [p["index"] for p in listed] == [0, 1]
    assert listed[0]["position_mm"] == second["position_mm"]
    api.ok("DELETE", GP, 204)
    assert api.ok("GET", GP) == []


@pytest.mark.parametrize(
    ("index", "status"), [("5", 404), ("-1", 404), (str(10**30), 404), ("abc", 422), ("1.5", 422)]
)
def test_delete_missing_guide_point(api: Api, index: str, status: int) -> None:
    api.ok("POST", GP, 201)
    r = api.delete(f"{GP}/{index}")
    assert r.status_code == status and r.json()["detail"], r.text


def test_example_job_runs_and_cancels(api: Api) -> None:
    before = api.position_mm()
    job_id = api.ok("POST", f"{GP}/example", 202)["job_id"]
    job = api.ok("GET", f"/api/jobs/{job_id}")
    assert job["kind"] == "example" and job["status"] in ("queued", "running")
    # While it runs the robot belongs to the job: pushes, records and cell changes are refused.
    deadline = time.monotonic() + 10
    while api.ok("GET", "/api/state")["time_s"] < 1.0 and time.monotonic() < deadline:
        time.sleep(0.05)
    state = api.ok("GET", "/api/state")
    assert state["busy"] is True
    r = api.post("/api/leadthrough/push", json={"force_N": [1, 0, 0], "duration_s": 0.1})
    assert r.status_code == 409 and "busy" in r.json()["detail"]
    assert api.post(GP).status_code == 409
    assert api.put("/api/cell", json={"robot": "ur5"}).status_code == 409
    assert api.post("/api/projects", json={"name": "while-busy"}).status_code == 409
    live = api.ok("GET", "/api/path-learning/recording")
    assert live["source"] == "live" and len(live["time_s"]) == len(live["force_N"]) > 0

    cancelled = api.ok("POST", f"/api/jobs/{job_id}/cancel")
    assert cancelled["status"] in ("running", "cancelled")
    job = api.wait_job(job_id, timeout_s=10)
    assert job["status"] == "cancelled" and "cancelled" in job["error"]
    # The robot stays where the operator had led it; the guide points are unchanged.
    assert np.linalg.norm(api.position_mm() - before) > 1.0
    assert api.ok("GET", GP) == []
    assert api.ok("GET", "/api/state")["busy"] is False
    r = api.post(f"/api/jobs/{job_id}/cancel")
    assert r.status_code == 409 and "already ended" in r.json()["detail"]


def test_example_needs_a_builtin_workpiece(api: Api) -> None:
    import trimesh

    data = trimesh.creation.box(extents=(100, 60, 30)).export(file_type="stl")
    api.ok("POST", "/api/cell/workpiece", files={"file": ("part.stl", data)})
    r = api.post(f"{GP}/example")
    assert r.status_code == 422 and "built-in workpiece" in r.json()["detail"]
