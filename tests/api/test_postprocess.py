"""Post-processing: before any recording, settings validation, results and their score."""

from __future__ import annotations

import pytest

from tests.api.in_process import InProcessServer
from tests.api.server_process import Api

PP = "/api/postprocess"


def test_before_any_recording(api: Api) -> None:
    r = api.post(PP, json={"force_min_N": 5, "force_max_N": 15, "tolerance_mm": 0.2})
    assert r.status_code == 409 and "path learning" in r.json()["detail"]
    state = api.ok("GET", PP)
    assert state["result"] is None
    assert state["settings"]["tolerance_mm"] == pytest.approx(0.2)


@pytest.mark.parametrize(
    ("body", "needle"),
    [
        ({"force_min_N": 15, "force_max_N": 5}, "Fmin < Fmax"),
        ({"tolerance_mm": 0}, "tolerance_mm"),
        ({"tolerance_mm": -1}, "tolerance_mm"),
        ({"force_min_N": -1}, "force_min_N"),
        ({"force_min_N": 30, "force_max_N": 40}, "widen the thresholds"),
        ({"tolerance": 0.2}, "tolerance"),
    ],
)
def test_bad_settings(learned: Api, body: dict, needle: str) -> None:
    r = learned.post(PP, json=body)
    assert r.status_code == 422 and needle in r.json()["detail"], r.text


def test_filters_reduces_and_scores(learned: Api) -> None:
    result = learned.ok("POST", PP, json={"force_min_N": 5, "force_max_N": 15, "tolerance_mm": 0.2})
    assert result["samples_raw"] > 500
    assert 0 < result["samples_filtered"] <= result["samples_raw"]
    assert 2 <= result["targets"] < result["samples_filtered"]
    # A straight wall learned at 10 N: the targets lie within a fraction of a mm of the truth.
    assert 0 <= result["rms_deviation_mm"] <= result["max_deviation_mm"] < 0.5
    state = learned.ok("GET", PP)
    assert state["result"] == result
    # Omitted settings keep their value; a finer tolerance never gives fewer targets.
    finer = learned.ok("POST", PP, json={"tolerance_mm": 0.01})
    assert finer["settings"]["force_max_N"] == 15
    assert finer["targets"] >= result["targets"]


@pytest.fixture(scope="module")
def learned_project(app_server: InProcessServer) -> int:
    """A project with a short recording on the block, made once for this module."""
    client = app_server.api()
    project = client.new_project()
    client.learn()
    return project["id"]


@pytest.fixture
def learned(api: Api, learned_project: int) -> Api:
    """The client with the learned project (re)opened."""
    api.ok("POST", f"/api/projects/{learned_project}/open")
    return api
