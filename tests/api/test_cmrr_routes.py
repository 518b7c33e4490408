"""CMRR studies over HTTP: run as jobs, summary, plot, settings, cancel, errors, saved to the
project. The server is the shared real ``robomach serve`` of tests/api/conftest.py."""

from __future__ import annotations

import json
import time
from typing import get_args

import pytest

from app.api.routes import cmrr
from app.store import Store
from robomach_core.cmrr import CONTROLLER_NAMES, SCENARIO_NAMES
from tests.api.server_process import Api, ServerProcess

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


def test_cancel(api: Api, server: ServerProcess) -> None:
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
    tmp = server.data_dir / "studies" / ".tmp"
    assert not any(tmp.iterdir()), list(tmp.iterdir())  # the run's folder is gone


def test_saved_to_project(api: Api, server: ServerProcess) -> None:
    project = api.ok("GET", "/api/projects/current")
    run_study(api, {"scenario": "deburr-burrs", "controller": "two-stage", "seed": 7})
    store = Store.in_data_dir(server.data_dir)  # a second connection, as after a restart
    try:
        files = store.get_export(project["id"], "cmrr-study")
    finally:
        store.close()
    assert files is not None
    assert json.loads(files["cmrr_settings.json"])["controller"] == "two-stage"
    assert json.loads(files["cmrr_summary.json"])["scenario"] == "deburr-burrs"
    assert json.loads(files["study.json"])["seed"] == 7
    names = [e["name"] for e in api.ok("GET", "/api/exports")]
    assert "cmrr-study" in names

    api.new_project()  # another project: its own (no) study
    assert api.get("/api/cmrr/studies/last").status_code == 409
    api.ok("POST", f"/api/projects/{project['id']}/open")  # loaded back on open
    study = api.ok("GET", "/api/cmrr/studies/last")
    assert study["controller"] == "two-stage" and study["seed"] == 7
    assert study["folder"] == f"studies/{project['id']}/cmrr"
    assert (server.data_dir / study["folder"] / "cmrr.csv").is_file()
    assert api.get(study["plot_url"]).content.startswith(PNG_SIGNATURE)
