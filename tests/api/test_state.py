"""GET /api/health, GET /api/state, the docs, unknown routes."""

from __future__ import annotations

import numpy as np

from tests.api.server_process import Api


def test_health(api: Api) -> None:
    assert api.ok("GET", "/api/health") == {"status": "ok"}


def test_state_has_units_and_shapes(api: Api) -> None:
    state = api.ok("GET", "/api/state")
    assert set(state) >= {"joints_deg", "tcp", "wrench", "in_contact"}
    assert len(state["joints_deg"]) == 6
    assert len(state["tcp"]["position_mm"]) == 3
    q = np.array(state["tcp"]["quaternion_wxyz"])
    assert q.shape == (4,) and abs(np.linalg.norm(q) - 1) < 1e-5
    assert len(state["wrench"]["force_N"]) == 3 and len(state["wrench"]["torque_Nm"]) == 3
    assert state["in_contact"] is False and state["busy"] is False
    # Home pose of the UR10 with the spindle: ~0.6 m in front of the base, tool down (mm).
    assert 400 < state["tcp"]["position_mm"][0] < 800
    assert abs(state["joints_deg"][1] - np.degrees(-1.7)) < 2.0
    # Free tool, tared sensor: only noise is measured.
    assert np.linalg.norm(state["wrench"]["force_N"]) < 2.0


def test_openapi_and_docs(api: Api) -> None:
    schema = api.ok("GET", "/openapi.json")
    for path in (
        "/api/health", "/api/state", "/api/leadthrough/compliance", "/api/leadthrough/push",
        "/api/leadthrough/jog", "/api/guide-points", "/api/guide-points/{index}",
        "/api/guide-points/example", "/api/path-learning", "/api/path-learning/recording",
        "/api/jobs/{job_id}", "/api/jobs/{job_id}/cancel", "/api/postprocess",
        "/api/export/rapid", "/api/export/samples.csv", "/api/export/targets.csv",
        "/api/export/settings.json", "/api/projects", "/api/cell", "/api/cell/workpiece",
    ):  # fmt: skip
        assert path in schema["paths"], path
    assert api.get("/docs").status_code == 200


def test_unknown_route_and_method_are_4xx_with_a_message(api: Api) -> None:
    r = api.get("/api/nothing-here")
    assert r.status_code == 404 and "no route" in r.json()["detail"]
    r = api.delete("/api/state")
    assert r.status_code == 405 and r.json()["detail"]


def test_root_redirects(api: Api) -> None:
    r = api.get("/", follow_redirects=False)
    assert r.status_code in (302, 307) and r.headers["location"] in ("/docs", "/pendant/")


def test_workbench_tells_the_pendant_where_viser_listens(api: Api) -> None:
    import httpx

    port = api.ok("GET", "/api/workbench")["viser_port"]
    assert isinstance(port, int)
    # The viser server of the same process serves its page there.
    page = httpx.get(f"http://127.0.0.1:{port}/", timeout=10.0)
    assert page.status_code == 200 and "<html" in page.text.lower()
