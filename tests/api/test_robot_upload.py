"""Uploading a user's 6-axis URDF over HTTP (good and bad files), and the URScript export."""

from __future__ import annotations

import io
import re
import zipfile

import pytest

from robomach_core.robots import abb
from tests.api.server_process import Api

UPLOAD = "/api/cell/robot"


def arm_text() -> str:
    """A good serial arm: the IRB 4400's URDF without its tool0 flange (the upload adds one)."""
    text = abb.urdf_text(abb.ABB_ARMS["irb4400"]).replace(
        '<robot name="irb4400">', '<robot name="my_arm">'
    )
    text = text.replace('<link name="tool0"/>', "")
    return re.sub(
        r'<joint name="[^"]*" type="fixed"><parent link="link_6"/><child link="tool0"/>.*?</joint>',
        "",
        text,
        flags=re.S,
    )


def test_a_good_urdf_becomes_the_cell_robot(api: Api) -> None:
    api.new_project()
    cell = api.ok("POST", UPLOAD, files={"file": ("my arm.urdf", arm_text().encode())})
    assert cell["robot"].startswith("urdf_my_arm_")
    assert cell["robot"] in cell["robots"] and "irb4400" in cell["robots"]
    state = api.ok("GET", "/api/state")
    assert len(state["joints_deg"]) == 6
    assert api.ok("GET", "/api/path-learning/warnings") == []


def test_a_zip_with_the_urdf_and_its_meshes(api: Api) -> None:
    api.new_project()
    buf = io.BytesIO()
    with zipfile.ZipFile(buf, "w") as z:
        z.writestr("arm/robot.urdf", arm_text())
        z.writestr("arm/meshes/base.stl", b"solid x\nendsolid x\n")
    cell = api.ok("POST", UPLOAD, files={"file": ("arm.zip", buf.getvalue())})
    assert cell["robot"].startswith("urdf_arm_")


def _bad(text: str) -> str:
    return text


@pytest.mark.parametrize(
    ("filename", "mutate", "needle"),
    [
        ("arm.urdf", lambda t: t[:200], "not valid XML"),
        ("arm.urdf", lambda t: t.replace('type="revolute"', 'type="prismatic"', 1), "prismatic"),
        ("arm.urdf", lambda t: re.sub(r"<limit [^>]*/>", "", t, count=1), "no <limit"),
        (
            "arm.urdf",
            lambda t: re.sub(r'<joint name="joint_6".*?</joint>', "", t, flags=re.S),
            "root links",
        ),
        ("arm.step", lambda t: t, ".urdf file or a .zip"),
        ("arm.zip", lambda t: t, "not a readable zip"),
    ],
)
def test_a_bad_robot_file_is_refused_with_the_reason(api: Api, filename, mutate, needle) -> None:
    before = api.ok("GET", "/api/cell")["robot"]
    r = api.post(UPLOAD, files={"file": (filename, mutate(arm_text()).encode())})
    assert r.status_code == 422, r.text
    assert needle in r.json()["detail"], r.json()
    assert api.ok("GET", "/api/cell")["robot"] == before


def test_five_revolute_joints_are_named_as_the_fault(api: Api) -> None:
    text = arm_text().replace(
        '<joint name="joint_6" type="revolute">', '<joint name="joint_6" type="fixed">'
    )
    r = api.post(UPLOAD, files={"file": ("arm.urdf", text.encode())})
    assert r.status_code == 422
    assert "has 5 revolute joints" in r.json()["detail"]


def test_urscript_export_needs_a_processed_path(api: Api) -> None:
    api.new_project()
    r = api.get("/api/export/urscript")
    assert r.status_code == 409, r.text


def test_learning_start_returns_warnings_and_the_program_exports_as_urscript(api: Api) -> None:
    api.new_project()
    api.block_guide_points()
    assert isinstance(api.ok("GET", "/api/path-learning/warnings"), list)
    body = {"force_N": 10, "speed_mm_s": 20, "closed": False}
    started = api.ok("POST", "/api/path-learning", 202, json=body)
    assert isinstance(started["warnings"], list)
    assert api.wait_job(started["job_id"])["status"] == "done"
    straight = api.ok("POST", "/api/postprocess", json={"tolerance_mm": 0.2, "arcs": False})
    assert 0.0 <= straight["mesh_rms_deviation_mm"] <= straight["mesh_max_deviation_mm"] < 0.5
    assert straight["moves"] == straight["targets"] and straight["circular_moves"] == 0
    arcs = api.ok("POST", "/api/postprocess", json={"arcs": True})
    assert arcs["settings"]["arcs"] is True
    assert arcs["moves"] <= arcs["straight_moves"] == straight["targets"]
    script = api.get("/api/export/urscript")
    assert script.status_code == 200 and script.text.startswith("def learned_path():")
    assert "program.script" in script.headers["content-disposition"]
    fc = api.get("/api/export/urscript", params={"force_control": True})
    assert "force_mode(" in fc.text
    saved = api.ok("POST", "/api/exports", 201, json={"name": "wiring"})
    assert "program.script" in saved["files"]  # the UR10's language
