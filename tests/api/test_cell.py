"""Cell settings and mesh uploads with their limits."""

from __future__ import annotations

import pytest
import trimesh

from robomach_core.cell import ROBOT_NAMES
from tests.api.conftest import TRIANGLE_LIMIT, UPLOAD_LIMIT_BYTES
from tests.api.server_process import Api

CELL = "/api/cell"
UPLOAD = "/api/cell/workpiece"


def test_default_cell(api: Api) -> None:
    cell = api.ok("GET", CELL)
    assert cell["robot"] == "ur10" and cell["workpiece"] == "water_pump"
    assert cell["tool_radius_mm"] == pytest.approx(1.0)
    # the core's list of built-in arms (an uploaded one joins it only while it is the cell's)
    assert set(cell["robots"]) == set(ROBOT_NAMES)
    assert set(cell["workpieces"]) == {"water_pump", "block", "s_groove"}


def test_change_cell_resets_downstream(api: Api) -> None:
    api.ok("POST", "/api/guide-points", 201)
    cell = api.ok("PUT", CELL, json={"robot": "UR5", "tool_radius_mm": 2.5, "workpiece": "block"})
    assert (cell["robot"], cell["tool_radius_mm"], cell["workpiece"]) == ("ur5", 2.5, "block")
    assert api.ok("GET", "/api/guide-points") == []
    assert api.ok("PUT", CELL, json={})["robot"] == "ur5"  # omitted settings stay


@pytest.mark.parametrize(
    ("body", "needle"),
    [
        ({"robot": "kuka"}, "unknown robot"),
        ({"tool_radius_mm": 9}, "tool radius"),
        ({"tool_radius_mm": 0}, "tool radius"),
        ({"workpiece": "engine"}, "unknown workpiece"),
        ({"robot": 10}, "robot"),
        ({"seed": 3}, "seed"),
    ],
)
def test_bad_cell_settings(api: Api, body: dict, needle: str) -> None:
    before = api.ok("GET", CELL)
    r = api.put(CELL, json=body)
    assert r.status_code == 422 and needle in r.json()["detail"], r.text
    assert api.ok("GET", CELL) == before


def test_upload_mesh(api: Api) -> None:
    data = trimesh.creation.box(extents=(120, 80, 30)).export(file_type="stl")
    cell = api.ok("POST", UPLOAD, files={"file": ("my part.stl", data)})
    assert cell["workpiece"] == "my_part" and cell["workpiece_builtin"] is False
    # Scored only against built-in geometry; the uploaded one stays selected on other changes.
    assert api.ok("PUT", CELL, json={"tool_radius_mm": 2})["workpiece"] == "my_part"
    assert api.ok("PUT", CELL, json={"workpiece": "my_part"})["workpiece"] == "my_part"
    assert api.ok("PUT", CELL, json={"workpiece": "block"})["workpiece_builtin"] is True


@pytest.mark.parametrize(
    ("filename", "data", "status", "needle"),
    [
        ("part.step", b"ISO-10303-21;", 422, "unsupported mesh type"),
        ("part.stl", b"solid nothing\nendsolid\n", 422, "part"),
        ("part.obj", b"this is not a mesh", 422, "part"),
        ("part.stl", b"", 422, "empty"),
        ("huge.stl", b"x" * (UPLOAD_LIMIT_BYTES + 1), 413, "limit"),
    ],
)
def test_upload_errors(api: Api, filename: str, data: bytes, status: int, needle: str) -> None:
    r = api.post(UPLOAD, files={"file": (filename, data)})
    assert r.status_code == status and needle in r.json()["detail"], r.text
    assert api.ok("GET", CELL)["workpiece"] == "water_pump"


def test_upload_triangle_limit(api: Api) -> None:
    sphere = trimesh.creation.icosphere(subdivisions=3, radius=40.0)  # 1280 triangles
    assert len(sphere.faces) > TRIANGLE_LIMIT
    data = sphere.export(file_type="stl")
    assert len(data) < UPLOAD_LIMIT_BYTES
    r = api.post(UPLOAD, files={"file": ("ball.stl", data)})
    assert r.status_code == 422 and f"limit of {TRIANGLE_LIMIT}" in r.json()["detail"]


def test_upload_without_a_file(api: Api) -> None:
    r = api.post(UPLOAD, data={"name": "x"})
    assert r.status_code == 422 and "file" in r.json()["detail"]
    r = api.post(UPLOAD, content=b"not multipart", headers={"content-type": "application/json"})
    assert r.status_code == 422


def test_body_larger_than_the_route_takes(api: Api) -> None:
    big = b'{"name": "' + b"x" * (2 * 1024 * 1024) + b'"}'
    r = api.post("/api/projects", content=big, headers={"content-type": "application/json"})
    assert r.status_code == 413
