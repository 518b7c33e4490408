"""Compensation studies over HTTP: identification and gravity as jobs, summary, plots, settings,
cancel, errors, saved to the project and loaded back after a restart. Quick studies only."""

from __future__ import annotations

import json
import time

import pytest

from app.session import Session
from app.store import Store
from app.studies import COMPENSATION_EXPORT, StudyService
from tests.api.in_process import InProcessServer
from tests.api.server_process import Api
from tests.api.test_cmrr_routes import PNG_SIGNATURE


@pytest.fixture(scope="module")
def identified(app_server: InProcessServer) -> int:
    """A project whose last study is a quick identification; returns its id."""
    api = app_server.api()
    project = api.new_project()
    run_study(api, {"study": "identify", "quick": True})
    api.close()
    return project["id"]


def run_study(api: Api, body: dict) -> dict:
    job_id = api.ok("POST", "/api/compensation/studies", 202, json=body)["job_id"]
    job = api.wait_job(job_id)
    assert job["status"] == "done", job
    assert job["kind"] == "compensation_study"
    return api.ok("GET", "/api/compensation/studies/last")


def test_no_study_yet(api: Api) -> None:
    for path in (
        "/api/compensation/studies/last",
        "/api/compensation/studies/last/plots",
        "/api/compensation/studies/last/plots/identification.png",
        "/api/compensation/settings",
    ):
        r = api.get(path)
        assert r.status_code == 409 and "no compensation study" in r.json()["detail"], path


def test_identification(api: Api, identified: int) -> None:
    api.ok("POST", f"/api/projects/{identified}/open")
    study = api.ok("GET", "/api/compensation/studies/last")
    assert study["study"] == "identify" and study["quick"] is True
    assert study["folder"] == f"studies/{identified}/compensation"
    summary = study["summary"]
    assert 0.0 <= summary["stiffness_rel_error_max"] < 0.5  # a relative error, not a percentage
    assert 0.0 < summary["prediction_error_max_mm"] < 0.04  # the chapter: < 0.04 mm
    assert summary["paper_references"]["chapter_prediction_error_max_mm"] == 0.04
    assert study["settings_available"] is True
    plots = api.ok("GET", "/api/compensation/studies/last/plots")
    assert "identification" in plots and plots == study["plots"]
    r = api.get("/api/compensation/studies/last/plots/identification.png")
    assert r.status_code == 200 and r.headers["content-type"] == "image/png"
    assert r.content.startswith(PNG_SIGNATURE)
    r = api.get("/api/compensation/studies/last/plots/gravity.png")
    assert r.status_code == 404 and "identification" in r.json()["detail"]
    r = api.get("/api/compensation/settings")
    assert r.status_code == 200 and r.headers["content-type"] == "application/json"
    assert 'filename="compensation_settings.json"' in r.headers["content-disposition"]
    settings = json.loads(r.text)
    assert len(settings["joint_stiffness_Nm_rad"]) == 6
    # online needs the gravity study's tool model
    assert (settings["mode"], settings["offline_model"]) == ("offline", "linear")


def test_gravity_keeps_the_identified_settings(api: Api) -> None:
    assert api.get("/api/compensation/settings").status_code == 409
    study = run_study(api, {"study": "gravity", "quick": True, "seed": 2})
    assert study["summary"]["gravity_residual_max_N"] < 5.0 and study["seed"] == 2
    assert study["plots"] == ["gravity"] and study["settings_available"] is False
    r = api.get("/api/compensation/settings")
    assert r.status_code == 409 and "identify" in r.json()["detail"]
    run_study(api, {"study": "identify", "quick": True, "mode": "off"})
    run_study(api, {"study": "gravity", "quick": True})
    assert api.ok("GET", "/api/compensation/settings")["mode"] == "off"  # kept


@pytest.mark.parametrize(
    ("body", "field"),
    [
        ({"study": "calibrate"}, "study"),
        ({"study": "identify", "quick": "maybe"}, "quick"),
        ({"study": "identify", "mode": "sometimes"}, "mode"),
        ({"study": "identify", "seed": 2**40}, "seed"),
        ({"study": "identify", "poses": 3}, "poses"),
    ],
)
def test_bad_input(api: Api, body: dict, field: str) -> None:
    r = api.post("/api/compensation/studies", json=body)
    assert r.status_code == 422 and field in r.json()["detail"], r.text


def test_cancel(api: Api, app_server: InProcessServer) -> None:
    job_id = api.ok("POST", "/api/compensation/studies", 202, json={"quick": True})["job_id"]
    deadline = time.monotonic() + 30.0
    while (job := api.ok("GET", f"/api/jobs/{job_id}"))["progress"] == 0.0:
        assert job["status"] in ("queued", "running") and time.monotonic() < deadline, job
        time.sleep(0.02)
    api.ok("POST", f"/api/jobs/{job_id}/cancel")
    job = api.wait_job(job_id, timeout_s=20.0)
    assert job["status"] == "cancelled" and "cancelled" in job["error"]
    assert api.get("/api/compensation/studies/last").status_code == 409
    r = api.post(f"/api/jobs/{job_id}/cancel")
    assert r.status_code == 409 and "already ended" in r.json()["detail"]
    tmp = app_server.data_dir / "studies" / ".tmp"
    assert not any(tmp.iterdir()), list(tmp.iterdir())


def test_saved_and_loaded_after_restart(
    api: Api, app_server: InProcessServer, identified: int
) -> None:
    store = Store.in_data_dir(app_server.data_dir)
    try:
        files = store.get_export(identified, COMPENSATION_EXPORT)
    finally:
        store.close()
    assert files is not None
    assert "stiffness_rel_error_max" in json.loads(files["compensation_summary.json"])
    assert len(json.loads(files["compensation_settings.json"])["joint_stiffness_Nm_rad"]) == 6

    # A second session on the same data folder, as after a restart, opened on that project.
    api.ok("POST", f"/api/projects/{identified}/open")
    session = Session(Store.in_data_dir(app_server.data_dir), data_dir=app_server.data_dir)
    try:
        assert session.current_project().id == identified
        outcome = StudyService(session).compensation_result()
        assert outcome is not None and outcome.study == "identify"
        assert outcome.plots["identification"].startswith(PNG_SIGNATURE)
        assert outcome.settings is not None
    finally:
        session.close()
