"""One project, one pipeline: staleness in the API, no-op cell updates, and the REST export
giving the same bytes as the core writer on the same stored project."""

from __future__ import annotations

import json

import pytest

from app.session.persistence import cell_from_doc, project_from_data
from app.store import Store
from robomach_core import project as core
from robomach_core.cell import Cell, CellConfig
from robomach_core.export.rapid_check import check_rapid_module
from tests.api.in_process import InProcessServer
from tests.api.server_process import Api

STATUS = "/api/projects/current/status"


def _processed(api: Api) -> None:
    api.learn()
    api.ok("POST", "/api/postprocess", json={"tolerance_mm": 0.05})


def test_changing_guide_points_marks_results_out_of_date(api: Api) -> None:
    assert api.ok("GET", STATUS)["postprocess"] == "none"
    _processed(api)
    status = api.ok("GET", STATUS)
    assert (status["recording"], status["postprocess"], status["machining"]) == (
        "current",
        "current",
        "none",
    )
    assert api.ok("GET", "/api/state")["project_status"]["postprocess"] == "current"
    targets_before = api.ok("GET", "/api/postprocess")["result"]["targets"]

    api.ok("DELETE", "/api/guide-points/1", 204)
    status = api.ok("GET", STATUS)
    assert status["recording"] == "stale" and status["postprocess"] == "stale"
    assert "guide points" in status["reasons"]["recording"]
    assert api.ok("GET", "/api/state")["project_status"]["postprocess"] == "stale"
    # Kept, but never exported as if current.
    post = api.ok("GET", "/api/postprocess")
    assert post["result"]["targets"] == targets_before and post["status"] == "stale"
    for path in ("/api/export/rapid", "/api/export/targets.csv"):
        r = api.get(path)
        assert r.status_code == 409 and "out of date" in r.json()["detail"], path
    r = api.post("/api/exports", json={"name": "stale_one"})
    assert r.status_code == 409 and "out of date" in r.json()["detail"]
    settings = json.loads(api.get("/api/export/settings.json").text)
    assert settings["status"]["postprocess"] == "stale"


def test_a_cell_update_that_changes_nothing_keeps_all_work(api: Api) -> None:
    _processed(api)
    guides = api.ok("GET", "/api/guide-points")
    state = api.ok("GET", "/api/state")
    for body in ({}, {"robot": "ur10"}, {"robot": "UR10", "workpiece": "block"}):
        api.ok("PUT", "/api/cell", json=body)
        assert api.ok("GET", "/api/guide-points") == guides, body
        assert api.ok("GET", STATUS)["postprocess"] == "current", body
    assert api.ok("GET", "/api/state")["joints_deg"] == state["joints_deg"]  # not sent home
    # A real change clears the guide points and leaves the results stale, not current.
    api.ok("PUT", "/api/cell", json={"tool_radius_mm": 2.0})
    assert api.ok("GET", "/api/guide-points") == []
    status = api.ok("GET", STATUS)
    assert status["recording"] == "stale" and status["postprocess"] == "stale"


def _cmrr_and_compensation() -> dict:
    from robomach_core.cell.joint_compliance import TRUE_JOINT_STIFFNESS_NM_RAD
    from robomach_core.cmrr import build_scenario, cmrr_settings_for, settings_for
    from robomach_core.cmrr import settings_to_dict as cmrr_to_dict
    from robomach_core.stiffness import CompensationSettings
    from robomach_core.stiffness.settings import settings_to_dict as compensation_to_dict

    cmrr = cmrr_settings_for(build_scenario("deburr-burrs"), settings_for("two-stage"))
    comp = CompensationSettings("ur10", TRUE_JOINT_STIFFNESS_NM_RAD["ur10"], mode="offline")
    old = compensation_to_dict(comp) | {"version": 1, "mode": "offline_linear"}
    del old["offline_model"]  # an older client's document: read by the old-spelling rule
    return {"cmrr": cmrr_to_dict(cmrr), "compensation": old}


def test_rest_export_and_core_writer_give_the_same_bytes(
    api: Api, app_server: InProcessServer
) -> None:
    _processed(api)
    chosen = api.ok("PUT", "/api/projects/current/process-settings", json=_cmrr_and_compensation())
    assert chosen["cmrr"]["controller"] == "two-stage"
    rest = {
        "program.mod": api.get("/api/export/rapid").text,
        "program_fc.mod": api.get(
            "/api/export/rapid", params={"module_name": "LearnedPathFC", "force_control": True}
        ).text,
        "targets.csv": api.get("/api/export/targets.csv").text,
        "samples.csv": api.get("/api/export/samples.csv").text,
    }
    text = rest["program.mod"]
    check_rapid_module(text)
    assert "FCSpdChgAct" in text and "largest target correction" in text
    settings = json.loads(api.get("/api/export/settings.json").text)
    assert settings["cmrr"]["controller"] == "two-stage"
    assert settings["compensation"]["mode"] == "offline"
    assert settings["compensation"]["offline_model"] == "linear"

    # The same project, read back from the server's store file, through the core writer.
    pid = api.ok("GET", "/api/projects/current")["id"]
    store = Store.in_data_dir(app_server.data_dir)
    try:
        data = store.load_project(pid)
    finally:
        store.close()
    cell_settings = cell_from_doc(data.cell)
    workpiece = core.build_workpiece(cell_settings, data.mesh)
    project = project_from_data(data, workpiece)
    assert project.status()["postprocess"] == "current"
    cell = Cell(
        CellConfig(
            robot=cell_settings.robot,
            tool=project.tool(),
            workpiece=workpiece,
            seed=cell_settings.seed,
        )
    )
    files = core.program_files(project, workpiece, cell.robot)
    for name, text in rest.items():
        assert files[name] == text, name


@pytest.mark.parametrize("body", [{"cmrr": [1, 2]}, {"compensation": {"mode": "sideways"}}])
def test_bad_process_settings_are_422(api: Api, body: dict) -> None:
    r = api.put("/api/projects/current/process-settings", json=body)
    assert r.status_code == 422 and r.json()["detail"], r.text


def test_process_settings_from_the_last_studies(api: Api) -> None:
    path = "/api/projects/current/process-settings/from-studies"
    r = api.post(path, json={"compensation": False})
    assert r.status_code == 409 and "no CMRR study" in r.json()["detail"]
    body = {"scenario": "deburr-burrs", "controller": "two-stage"}
    job = api.wait_job(api.ok("POST", "/api/cmrr/studies", 202, json=body)["job_id"], 300)
    assert job["status"] == "done", job
    r = api.post(path, json={"compensation": False, "controller": "fuzzy"})
    assert r.status_code == 404 and "two-stage" in r.json()["detail"]
    chosen = api.ok("POST", path, json={"compensation": False})
    assert chosen["cmrr"]["controller"] == "two-stage" and chosen["compensation"] is None
    _processed(api)
    text = api.get("/api/export/rapid").text
    assert "FCSpdChgAct" in text and "CMRR: two-stage" in text
    api.ok("PUT", "/api/projects/current/process-settings", json={})
    assert "FCSpdChgAct" not in api.get("/api/export/rapid").text
