"""Exports: RAPID, CSV and settings downloads, and named exports saved in the data folder."""

from __future__ import annotations

import csv
import io
import json

import pytest

from robomach_core.export.rapid_check import check_rapid_module
from tests.api.in_process import InProcessServer
from tests.api.server_process import Api

EXPORTS = ("/api/export/rapid", "/api/export/samples.csv", "/api/export/targets.csv")


@pytest.fixture(scope="module")
def processed_project(app_server: InProcessServer) -> int:
    client = app_server.api()
    project = client.new_project()
    client.learn()
    client.ok("POST", "/api/postprocess", json={"tolerance_mm": 0.05})
    return project["id"]


@pytest.fixture
def processed(api: Api, processed_project: int) -> Api:
    api.ok("POST", f"/api/projects/{processed_project}/open")
    return api


def test_exports_need_their_stage(api: Api) -> None:
    for path in EXPORTS:
        r = api.get(path)
        assert r.status_code == 409 and "run path learning" in r.json()["detail"], path
    settings = json.loads(api.get("/api/export/settings.json").text)
    assert settings["postprocess"]["tolerance_mm"] == pytest.approx(0.2)
    assert settings["path_learning"] is None


def test_rapid_module(processed: Api) -> None:
    r = processed.get("/api/export/rapid")
    assert r.status_code == 200 and r.headers["content-type"].startswith("text/plain")
    assert 'filename="LearnedPath.mod"' in r.headers["content-disposition"]
    text = r.text
    assert text.startswith("MODULE LearnedPath") and "ENDMODULE" in text
    info = check_rapid_module(text)
    targets = processed.ok("GET", "/api/postprocess")["result"]["targets"]
    assert len([n for n in info.robtargets if n.startswith("p")]) >= targets
    assert "MoveL" in text and "wobj_block" in text


def test_rapid_options(processed: Api) -> None:
    r = processed.get("/api/export/rapid", params={"module_name": "Pump_1", "force_control": True})
    assert r.status_code == 200 and r.text.startswith("MODULE Pump_1")
    assert "FCPress" in r.text
    check_rapid_module(r.text)
    for name in ("!!!", ""):
        r = processed.get("/api/export/rapid", params={"module_name": name})
        assert r.status_code == 422 and r.json()["detail"], name
    r = processed.get("/api/export/rapid", params={"force_control": "sometimes"})
    assert r.status_code == 422 and "force_control" in r.json()["detail"]


def test_csv_and_settings(processed: Api) -> None:
    post = processed.ok("GET", "/api/postprocess")["result"]
    samples = list(csv.DictReader(io.StringIO(processed.get("/api/export/samples.csv").text)))
    assert len(samples) == post["samples_raw"]
    assert sum(int(row["kept_by_filter"]) for row in samples) == post["samples_filtered"]
    assert "x_mm" in samples[0] and "force_normal_N" in samples[0]
    r = processed.get("/api/export/targets.csv")
    assert r.headers["content-type"].startswith("text/csv")
    targets = list(csv.DictReader(io.StringIO(r.text)))
    assert len(targets) == post["targets"]
    assert 720 < float(targets[0]["x_mm"]) < 880  # on the block's front wall, in mm
    settings = json.loads(processed.get("/api/export/settings.json").text)
    assert settings["cell"]["workpiece"] == "block"
    assert settings["path_learning"]["speed_mm_s"] == pytest.approx(20.0)
    assert settings["postprocess"]["tolerance_mm"] == pytest.approx(0.05)
    assert settings["result"]["targets"] == post["targets"]


def test_saved_exports_stay_in_the_data_folder(processed: Api, app_server: InProcessServer) -> None:
    saved = processed.ok("POST", "/api/exports", 201, json={"name": "block_v1"})
    assert set(saved["files"]) >= {"program.mod", "samples.csv", "targets.csv", "settings.json"}
    folder = app_server.data_dir / saved["folder"]
    assert folder.resolve().is_relative_to(app_server.data_dir.resolve())
    assert (folder / "program.mod").read_text().startswith("MODULE block_v1")
    listed = processed.ok("GET", "/api/exports")
    assert [e["name"] for e in listed] == ["block_v1"]
    r = processed.get("/api/exports/block_v1/targets.csv")
    assert r.status_code == 200 and r.text == (folder / "targets.csv").read_text()
    for bad in ("../evil", "..", "a/b", "/abs", ".hidden", "x" * 65, "", "a\\b", "a..b"):
        r = processed.post("/api/exports", json={"name": bad})
        assert r.status_code == 422 and "export name" in r.json()["detail"], bad
    assert not (app_server.data_dir.parent / "evil").exists()
    assert processed.get("/api/exports/nope/program.mod").status_code == 404
    assert processed.get("/api/exports/block_v1/passwd").status_code == 404
    assert processed.get("/api/exports/..%2F..%2Fetc/passwd").status_code == 404
