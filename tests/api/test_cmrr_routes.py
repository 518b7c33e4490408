"""CMRR studies over HTTP: run as jobs, summary, plot, settings, cancel, errors, saved to the
project. The app is the shared in-process one of tests/api/conftest.py."""

from __future__ import annotations

import json
import time
from typing import get_args

import pytest

from app.api.routes import cmrr
from app.session import Session
from app.store import Store
from app.studies import CMRR_EXPORT, MAX_ACTIVE_STUDIES, StudyService, _clean_failures
from robomach_core.cmrr import CONTROLLER_NAMES, SCENARIO_NAMES
from tests.api.in_process import InProcessServer
from tests.api.server_process import Api
from tests.jobs import finished

PNG_SIGNATURE = b"\x89PNG\r\n\x1a\n"


def run_study(api: Api, body: dict) -> dict:
    job_id = api.ok("POST", "/api/cmrr/studies", 202, json=body)["job_id"]
    job = api.wait_job(job_id)
    assert job["status"] == "done", job
    assert job["kind"] == "cmrr_study"
    return api.ok("GET", "/api/cmrr/studies/last")


def test_options(api: Api) -> None:
    options = api.ok("GET", "/api/cmrr/options")
    assert options["scenarios"] == list(SCENARIO_NAMES)
    assert options["controllers"] == [*CONTROLLER_NAMES, "all"]
    assert options["default_controllers"]["milling-steps"] == "adaptive-pi"
    assert get_args(cmrr.ControllerChoice) == (*CONTROLLER_NAMES, "all", "default")


def test_no_study_yet(api: Api) -> None:
    for path in ("/api/cmrr/studies/last", "/api/cmrr/studies/last/plot.png", "/api/cmrr/settings"):
        r = api.get(path)
        assert r.status_code == 409 and "no CMRR study" in r.json()["detail"], (path, r.text)


def test_fixed_pi_unstable_self_tuning_stable(api: Api) -> None:
    """Chapter figs. 11-12: the PI tuned for 1 mm limit-cycles at 3 mm; the self-tuning holds."""
    fixed = run_study(api, {"scenario": "milling-steps", "controller": "fixed-pi"})
    assert fixed["controller"] == "fixed-pi" and fixed["controllers"] == ["fixed-pi"]
    assert fixed["summary"]["stable"] is False
    assert fixed["summary"]["peak_force_N"] > 300.0
    r = api.get(fixed["plot_url"])
    assert r.status_code == 200 and r.headers["content-type"] == "image/png"
    assert r.content.startswith(PNG_SIGNATURE) and len(r.content) > 10_000

    tuned = run_study(api, {"scenario": "milling-steps", "controller": "adaptive-pi", "seed": 3})
    summary = tuned["summary"]
    assert summary["stable"] is True and tuned["seed"] == 3
    assert summary["peak_force_N"] < 300.0 and summary["cycle_time_s"] > 0
    assert {"force_rms_error_N", "cycle_time_gain", "reference_force_N"} <= set(summary)
    r = api.get(tuned["settings_url"])
    assert r.status_code == 200 and r.headers["content-type"] == "application/json"
    assert 'filename="cmrr_settings.json"' in r.headers["content-disposition"]
    settings = json.loads(r.text)
    assert settings["controller"] == "adaptive-pi"
    assert settings["reference_force_N"] == 250.0 and settings["command_speed_mm_s"] == 30.0


def test_default_controller_and_overrides(api: Api) -> None:
    body = {"scenario": "milling-steps", "reference_force_N": 200, "command_speed_mm_s": 25}
    study = run_study(api, body)
    assert study["controller"] == "adaptive-pi"  # the scenario's own
    settings = api.ok("GET", "/api/cmrr/settings")
    assert settings["reference_force_N"] == 200.0 and settings["command_speed_mm_s"] == 25.0


def test_compare_all(api: Api) -> None:
    study = run_study(api, {"scenario": "milling-steps", "controller": "all"})
    assert study["controller"] == "all" and study["controllers"] == list(CONTROLLER_NAMES)
    by_name = {s["controller"]: s for s in study["summary"]["results"]}
    assert by_name["fixed-pi"]["stable"] is False and by_name["adaptive-pi"]["stable"] is True
    assert len(api.ok("GET", "/api/cmrr/settings")) == len(CONTROLLER_NAMES)
    r = api.get("/api/cmrr/settings", params={"controller": "two-stage"})
    assert r.status_code == 200 and json.loads(r.text)["controller"] == "two-stage"
    assert 'filename="cmrr_settings_two-stage.json"' in r.headers["content-disposition"]
    r = api.get("/api/cmrr/settings", params={"controller": "../etc"})
    assert r.status_code == 404 and "did not run" in r.json()["detail"]


@pytest.mark.parametrize(
    ("body", "field"),
    [
        ({"scenario": "turning"}, "scenario"),
        ({"scenario": "milling-steps", "controller": "pid"}, "controller"),
        ({"scenario": "milling-steps", "seed": -1}, "seed"),
        ({"scenario": "milling-steps", "seed": "one"}, "seed"),
        ({"scenario": "milling-steps", "reference_force_N": 0}, "reference_force_N"),
        ({"scenario": "milling-steps", "feed": 3}, "feed"),
        ({}, "scenario"),
    ],
)
def test_bad_input(api: Api, body: dict, field: str) -> None:
    r = api.post("/api/cmrr/studies", json=body)
    assert r.status_code == 422, r.text
    assert field in r.json()["detail"], r.text


def test_unknown_scenario_message(api: Api) -> None:
    r = api.post("/api/cmrr/studies", json={"scenario": "turning"})
    assert r.status_code == 422 and "milling-steps" in r.json()["detail"]


def test_cancel(api: Api, app_server: InProcessServer) -> None:
    body = {"scenario": "lund-df", "controller": "all"}
    job_id = api.ok("POST", "/api/cmrr/studies", 202, json=body)["job_id"]
    deadline = time.monotonic() + 30.0
    while (job := api.ok("GET", f"/api/jobs/{job_id}"))["status"] == "queued":
        assert time.monotonic() < deadline
        time.sleep(0.02)
    assert job["status"] == "running", job
    api.ok("POST", f"/api/jobs/{job_id}/cancel")
    job = api.wait_job(job_id)
    assert job["status"] == "cancelled" and "cancelled" in job["error"]
    assert api.get("/api/cmrr/studies/last").status_code == 409  # nothing kept
    tmp = app_server.data_dir / "studies" / ".tmp"
    assert not any(tmp.iterdir()), list(tmp.iterdir())  # the run's folder is gone


def test_saved_to_project(api: Api, app_server: InProcessServer) -> None:
    project = api.ok("GET", "/api/projects/current")
    run_study(api, {"scenario": "deburr-burrs", "controller": "two-stage", "seed": 7})
    store = Store.in_data_dir(app_server.data_dir)  # a second connection, as after a restart
    try:
        files = store.get_export(project["id"], CMRR_EXPORT)
    finally:
        store.close()
    assert files is not None
    assert json.loads(files["cmrr_settings.json"])["controller"] == "two-stage"
    assert json.loads(files["cmrr_summary.json"])["scenario"] == "deburr-burrs"
    assert json.loads(files["study.json"])["seed"] == 7
    names = [e["name"] for e in api.ok("GET", "/api/exports")]
    assert CMRR_EXPORT in names

    api.new_project()  # another project: its own (no) study
    assert api.get("/api/cmrr/studies/last").status_code == 409
    api.ok("POST", f"/api/projects/{project['id']}/open")  # loaded back on open
    study = api.ok("GET", "/api/cmrr/studies/last")
    assert study["controller"] == "two-stage" and study["seed"] == 7
    assert study["folder"] == f"studies/{project['id']}/cmrr"
    assert (app_server.data_dir / study["folder"] / "cmrr.csv").is_file()
    assert api.get(study["plot_url"]).content.startswith(PNG_SIGNATURE)


# --- issue 10: extreme numbers, memory, queue, export names ----------------------------------


@pytest.mark.parametrize("value", [1e308, 1e-300, 1e-6, 1.4e-45, 0.5, 5000.0])
@pytest.mark.parametrize(
    ("field", "range_text"),
    [("reference_force_N", "1-1000 N"), ("command_speed_mm_s", "1-500 mm/s")],
)
def test_extreme_numbers_refused_with_their_range(
    api: Api, field: str, range_text: str, value: float
) -> None:
    r = api.post("/api/cmrr/studies", json={"scenario": "lund-df", field: value})
    assert r.status_code == 422, r.text
    assert field in r.json()["detail"] and range_text in r.json()["detail"], r.text


def test_a_study_too_long_to_simulate_is_refused_up_front(api: Api) -> None:
    # 1 mm/s is a valid feed, but all six controllers at 5 % of it on the 330 mm Lund cut
    # would allocate ~15 M samples (the 0.01 mm/s took 6.9 GB).
    body = {"scenario": "lund-df", "controller": "all", "command_speed_mm_s": 1.0}
    r = api.post("/api/cmrr/studies", json=body)
    assert r.status_code == 422, r.text
    assert "control samples" in r.json()["detail"] and "3,000,000" in r.json()["detail"]
    one = api.ok("POST", "/api/cmrr/studies", 202, json={**body, "controller": "fixed-pi"})
    api.ok("POST", f"/api/jobs/{one['job_id']}/cancel")


def test_the_study_queue_has_a_limit(api: Api) -> None:
    body = {"scenario": "lund-df", "controller": "all"}
    for _ in range(MAX_ACTIVE_STUDIES):
        api.ok("POST", "/api/cmrr/studies", 202, json=body)
    r = api.post("/api/cmrr/studies", json=body)
    assert r.status_code == 429, r.text
    assert "already queued or running" in r.json()["detail"]
    r = api.post("/api/compensation/studies", json={"quick": True})
    assert r.status_code == 429, r.text
    api.cancel_all()
    api.ok("POST", "/api/compensation/studies", 202, json={"quick": True})


def test_an_export_cannot_replace_the_study(api: Api) -> None:
    """Issue 10, 8: an export named cmrr-study overwrote the saved study."""
    project = api.ok("GET", "/api/projects/current")
    api.learn()
    api.ok("POST", "/api/postprocess", json={"tolerance_mm": 0.2})
    run_study(api, {"scenario": "milling-steps", "controller": "constant", "seed": 5})
    for name in ("cmrr-study", "compensation-study"):
        api.ok("POST", "/api/exports", 201, json={"name": name})
    r = api.post("/api/exports", json={"name": CMRR_EXPORT})
    assert r.status_code == 422, r.text
    api.new_project()
    api.ok("POST", f"/api/projects/{project['id']}/open")  # loaded from the store, as on restart
    study = api.ok("GET", "/api/cmrr/studies/last")
    assert study["controller"] == "constant" and study["seed"] == 5


def test_a_study_saved_under_the_old_name_is_read_and_moved(tmp_path) -> None:
    session = Session(Store.in_data_dir(tmp_path), data_dir=tmp_path)
    try:
        pid = session.current_project().id
        meta = {"kind": "cmrr", "scenario": "lund-df", "controller": "adaptive-lq", "seed": 4,
                "finished_s": 1.0}  # fmt: skip
        session.store.save_export(pid, "cmrr-study", {
            "study.json": json.dumps(meta),
            "cmrr_summary.json": json.dumps({"scenario": "lund-df"}),
            "cmrr_settings.json": json.dumps({"controller": "adaptive-lq"}),
        })  # fmt: skip
        outcome = StudyService(session).cmrr_result()
        assert outcome is not None and outcome.seed == 4
        assert session.store.get_export(pid, CMRR_EXPORT)["study.json"] == json.dumps(meta)
        # An export of the program that took the old name is not a study.
        session.store.save_export(pid, "compensation-study", {"program.mod": "MODULE x"})
        assert StudyService(session).compensation_result() is None
    finally:
        session.close()


def test_an_unforeseen_failure_ends_the_job_with_one_line(tmp_path) -> None:
    """Inputs passed validation, yet the simulation raised: a failed job with the cause, not
    an "internal error" with a traceback in the log."""
    session = Session(Store.in_data_dir(tmp_path), data_dir=tmp_path)
    try:
        work = _clean_failures("CMRR", lambda ctx: 1 / 0)
        job_id = session.jobs.submit("cmrr_study", work)
        job = finished(session, job_id, timeout_s=10.0)
        assert job.status == "failed"
        assert job.error == "the CMRR study failed: ZeroDivisionError: division by zero"
    finally:
        session.close()
