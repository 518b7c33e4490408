"""The machining routes over real HTTP: settings, run and compare jobs, result, choice, stock,
staleness, and the same program bytes as ``robomach machine`` for the same project."""

from __future__ import annotations

import json
import time

import pytest

from tests.api.server_process import Api
from tests.cli import robomach_here
from tests.demo_project import block_demo_dir

STATUS = "/api/projects/current/status"


def _processed(api: Api) -> None:
    api.learn()
    api.ok("POST", "/api/postprocess", json={"tolerance_mm": 0.05})


def _run(api: Api, kind: str = "run", timeout_s: float = 300.0) -> dict:
    job_id = api.ok("POST", f"/api/machining/{kind}", 202)["job_id"]
    job = api.wait_job(job_id, timeout_s=timeout_s)
    assert job["status"] == "done", job
    return job


def test_settings_have_ranges_in_the_schema_and_refuse_bad_values(api: Api) -> None:
    settings = api.ok("GET", "/api/machining/settings")
    assert settings["process_gain_N"] == 23.0 and settings["force_limit_N"] == 150.0
    assert (settings["controller"], settings["compensation"]) == ("adaptive-pi", "off")
    assert settings["status"] == "none"
    schema = api.ok("GET", "/openapi.json")
    update = schema["components"]["schemas"]["MachiningSettingsUpdate"]["properties"]
    gain = update["process_gain_N"]["anyOf"][0]
    assert gain["minimum"] == 0.1 and gain["maximum"] == 1.0e4
    for path in ("/settings", "/run", "/compare", "/result", "/comparison", "/choice"):
        assert f"/api/machining{path}" in schema["paths"], path
    assert settings["stages"] == "online"
    bad = ({"force_limit_N": 0}, {"depth_exponent": 4}, {"controller": "magic"}, {"x": 1})
    for body in (*bad, {"stages": "sometimes"}):
        r = api.put("/api/machining/settings", json=body)
        assert r.status_code == 422, (body, r.text)
    new = api.ok(
        "PUT", "/api/machining/settings", json={"process_gain_N": 30, "force_limit_N": 200}
    )
    assert new["process_gain_N"] == 30 and new["reference_force_N"] == pytest.approx(140.0)
    assert api.ok("GET", "/api/machining/settings")["force_limit_N"] == 200
    assert api.ok("PUT", "/api/machining/settings", json={"stages": "planned"})["stages"] == (
        "planned"
    )


def test_no_program_no_run(api: Api) -> None:
    r = api.post("/api/machining/run")
    assert r.status_code == 409 and "path learning" in r.json()["detail"]
    assert api.get("/api/machining/result").status_code == 409


def test_run_result_choice_and_staleness_from_the_guide_points(api: Api) -> None:
    _processed(api)
    api.ok("PUT", "/api/machining/choice", json={"controller": "fuzzy", "compensation": "online"})
    _run(api)
    result = api.ok("GET", "/api/machining/result", params={"points": 200})
    assert result["status"] == "current" and result["stale_reason"] is None
    (run,) = result["runs"]
    assert (run["controller"], run["compensation"]) == ("fuzzy", "online")
    trace = result["trace"]
    assert len(trace["force_N"]) == 200 and trace["limit_N"] == 150.0
    assert all(
        lo <= m <= hi
        for lo, m, hi in zip(
            trace["force_min_N"], trace["force_N"], trace["force_max_N"], strict=True
        )
    )
    assert len(trace["wall_error_mm"]) == len(trace["wall_s_mm"]) > 10
    table = api.ok("GET", "/api/machining/comparison")
    assert table["table_markdown"].startswith("| cell | controller |")
    assert "fuzzy" in table["table_text"]
    # The choice reaches the export: the FC SpeedChange block of the chosen controller.
    rapid = api.get("/api/export/rapid").text
    assert "FCSpdChgAct" in rapid and "CMRR: fuzzy" in rapid
    settings = api.get("/api/export/settings.json").json()
    assert settings["machining"]["chosen"] == {"controller": "fuzzy", "compensation": "online"}
    assert settings["compensation"]["mode"] == "online"
    # Choosing does not date a result; constant feed drops the SpeedChange block.
    api.ok("PUT", "/api/machining/choice", json={"controller": "constant", "compensation": "off"})
    assert api.ok("GET", STATUS)["machining"] == "current"
    assert "FCSpdChgAct" not in api.get("/api/export/rapid").text
    # A process change does.
    api.ok("PUT", "/api/machining/settings", json={"process_gain_N": 25})
    assert api.ok("GET", STATUS)["machining"] == "stale"
    _run(api)
    assert api.ok("GET", STATUS)["machining"] == "current"

    api.ok("DELETE", "/api/guide-points/1", 204)
    status = api.ok("GET", STATUS)
    assert status["postprocess"] == "stale" and status["machining"] == "stale"
    assert "machining" in status["reasons"]
    assert api.ok("GET", "/api/state")["project_status"]["machining"] == "stale"
    result = api.ok("GET", "/api/machining/result")
    assert result["status"] == "stale" and "run the machining again" in result["stale_reason"]
    assert api.ok("GET", "/api/machining/settings")["status"] == "stale"
    assert api.post("/api/machining/run").status_code == 409


@pytest.mark.slow  # a process pool's start and a comparison
def test_a_comparison_can_be_cancelled(api: Api) -> None:
    _processed(api)
    job_id = api.ok("POST", "/api/machining/compare", 202)["job_id"]
    deadline = time.monotonic() + 60
    while api.ok("GET", f"/api/jobs/{job_id}")["status"] == "queued":
        assert time.monotonic() < deadline
        time.sleep(0.02)
    api.ok("POST", f"/api/jobs/{job_id}/cancel")
    job = api.wait_job(job_id)
    assert job["status"] == "cancelled", job
    assert api.ok("GET", STATUS)["machining"] == "none"


def test_stock_profile_and_a_bad_stock_mesh(api: Api) -> None:
    body = {"profile_mm": [[0, 0.5], [40, 2.0]]}
    assert api.ok("PUT", "/api/machining/stock/profile", json=body)["stock_source"] == "profile"
    r = api.put("/api/machining/stock/profile", json={"profile_mm": []})
    assert r.status_code == 422
    r = api.post("/api/machining/stock", files={"file": ("stock.stl", b"\x00 not a mesh")})
    assert r.status_code == 422, r.text
    assert api.ok("GET", "/api/machining/settings")["stock_source"] == "profile"


@pytest.mark.slow  # the shared block demo run and a `robomach machine`
def test_cli_and_rest_write_the_same_program_for_the_same_project(api: Api, tmp_path) -> None:
    demo = block_demo_dir()
    out = tmp_path / "cli"
    # ``robomach machine``'s main in this process (tests/cli.py): the files it writes are
    # what is compared; a process of its own would add only its imports.
    proc = robomach_here(
        "machine", "--out", str(out), "--from", str(demo),
        "--controller", "adaptive-pi", "--compensation", "offline", "--no-plot",
    )  # fmt: skip
    assert proc.returncode == 0, proc.stderr

    files = {"file": ("project.npz", (demo / "project.npz").read_bytes())}
    name = f"demo-{time.monotonic_ns()}"
    api.ok("POST", "/api/projects/import", 201, files=files, params={"name": name})
    assert api.ok("GET", STATUS)["postprocess"] == "current"
    choice = {"controller": "adaptive-pi", "compensation": "offline"}
    api.ok("PUT", "/api/machining/choice", json=choice)
    _run(api)
    rest = api.get("/api/export/rapid").text
    cli = (out / "program.mod").read_text()
    assert "planned from rehearsals of the adaptive-pi cut" in cli and "FCSpdChgAct" in cli
    assert rest == cli
    fc = api.get(
        "/api/export/rapid", params={"force_control": True, "module_name": "LearnedPathFC"}
    )
    assert fc.text == (out / "program_fc.mod").read_text()
    assert api.get("/api/export/targets.csv").text == (out / "targets.csv").read_text()
    cli_settings = (out / "settings.json").read_text()
    rest_settings = api.get("/api/export/settings.json").json()
    cli_doc = json.loads(cli_settings)
    for key in ("project", "compliance"):  # the workbench's own: project name, compliance
        cli_doc.pop(key), rest_settings.pop(key)
    assert rest_settings == cli_doc


@pytest.mark.parametrize(
    ("content", "words"),
    [
        ('{"profile_mm": [[0, -1]]}', "greater than or equal to 0"),
        ('{"profile_mm": [[0, NaN]]}', "finite number"),
        ('{"profile_mm": [[0, 1], [5, 25]]}', "less than or equal to 20"),
        ('{"profile_mm": [[5, 1], [5, 2]]}', "increase strictly"),
        ('{"profile_mm": [[-3, 1]]}', "greater than or equal to 0"),
    ],
)
def test_bad_stock_profiles_are_refused_before_they_are_stored(api: Api, content, words) -> None:
    """Issue 19 R12: profiles with NaN, negative or out-of-range values were stored (200) and
    failed only when the machining ran."""
    r = api.put(
        "/api/machining/stock/profile",
        content=content,
        headers={"content-type": "application/json"},
    )
    assert r.status_code == 422, r.text
    assert words in r.text
    assert api.ok("GET", "/api/machining/settings")["stock_source"] == "builtin"


def test_every_advertised_force_limit_is_accepted_under_its_own_name(api: Api) -> None:
    """Issue 19 R12: a limit inside the advertised range was refused as "reference_force_N ...
    got 0.7". The schema's range is the one limits.py states, and both ends go through."""
    from robomach_core.limits import MACHINING_FORCE_LIMIT_N

    schema = api.ok("GET", "/openapi.json")["components"]["schemas"]["MachiningSettingsUpdate"]
    limit = schema["properties"]["force_limit_N"]["anyOf"][0]
    assert (limit["minimum"], limit["maximum"]) == (
        MACHINING_FORCE_LIMIT_N.min,
        MACHINING_FORCE_LIMIT_N.max,
    )
    for value in (MACHINING_FORCE_LIMIT_N.min, MACHINING_FORCE_LIMIT_N.max):
        s = api.ok("PUT", "/api/machining/settings", json={"force_limit_N": value})
        assert s["reference_force_N"] == pytest.approx(0.7 * value)
        for controller in ("fixed-pi", "two-stage"):
            chosen = api.ok(
                "PUT",
                "/api/machining/choice",
                json={"controller": controller, "compensation": "off"},
            )
            assert chosen["controller"] == controller
    r = api.put("/api/machining/settings", json={"force_limit_N": 1.0})
    assert r.status_code == 422 and "force_limit_N" in r.text


def test_the_cell_options_follow_the_arm_until_set(api: Api) -> None:
    s = api.ok("GET", "/api/machining/settings")
    assert s["cell_options"] == ["force_mode"] and s["cell_options_default"]  # UR10: URScript
    s = api.ok("PUT", "/api/machining/settings", json={"cell_options": ["path_correction"]})
    assert s["cell_options"] == ["path_correction"] and not s["cell_options_default"]
    assert "MISSING" in s["program_needs"]  # the chosen adaptive-pi needs a feed override
    s = api.ok("PUT", "/api/machining/settings", json={"cell_options_default": True})
    assert s["cell_options"] == ["force_mode"] and s["cell_options_default"]
    r = api.put("/api/machining/settings", json={"cell_options": ["laser"]})
    assert r.status_code == 422
    r = api.put("/api/machining/settings", json={"variations": 5000})
    assert r.status_code == 422 and "1000" in r.text
    assert api.ok("PUT", "/api/machining/settings", json={"variations": 3})["variations"] == 3
