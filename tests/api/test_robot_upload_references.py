"""Over real HTTP (issue 32, point 1): a robot upload whose URDF names a mesh 120 times, outside
the upload or inside it, is refused with 422 naming the reference, and the server's memory
stays within 100 MB of where it was; a saved project whose arm this server refuses opens on
the default arm with a message, and the server starts on it (it reopened the last project
at every start and ran out of memory again before answering).
"""

from __future__ import annotations

import base64
import io
import json
import sqlite3
import zipfile
from dataclasses import asdict
from pathlib import Path

import numpy as np
import pytest
import trimesh

from app.store import DB_FILENAME, GuidePointRow, Store
from robomach_core.project import CellSettings
from robomach_core.robots import abb
from robomach_core.robots.custom import robot_name_for
from tests.api.server_process import (
    Api,
    ServerProcess,
    peak_rss_bytes,
    reset_peak_rss,
    rss_bytes,
    start_server,
)

UPLOAD = "/api/cell/robot"
MEMORY_BOUND_BYTES = 100 * 2**20
REFERENCES = 120


def arm_naming(ref: str, times: int = REFERENCES) -> str:
    """The IRB 4400 whose links carry ``times`` visuals, each the mesh ``ref``."""
    text = abb.urdf_text(abb.ABB_ARMS["irb4400"])
    visual = f'<visual><geometry><mesh filename="{ref}"/></geometry></visual>'
    per_link = -(-times // 6)
    for i in range(1, 7):
        n = min(per_link, times - (i - 1) * per_link)
        text = text.replace(f'<link name="link_{i}">', f'<link name="link_{i}">' + visual * n, 1)
    assert text.count("<mesh ") == times
    return text


def mesh_stl(triangles_subdivisions: int = 5) -> bytes:
    """A sphere of 20,480 triangles: 1 MB of binary STL."""
    mesh = trimesh.creation.icosphere(subdivisions=triangles_subdivisions, radius=0.05)
    return mesh.export(file_type="stl")


def _refused_in_bounded_memory(server: ServerProcess, api: Api, name: str, data: bytes) -> str:
    pid = server.proc.pid
    reset_peak_rss(pid)
    before = rss_bytes(pid)
    r = api.post(UPLOAD, files={"file": (name, data)})
    assert r.status_code == 422, r.text
    api.ok("GET", "/api/state")  # alive, and the scene has drawn whatever it was going to
    growth = peak_rss_bytes(pid) - before
    assert growth < MEMORY_BOUND_BYTES, f"the server's peak grew {growth / 2**20:.0f} MiB"
    return r.json()["detail"]


@pytest.mark.slow  # a real server process, memory measured
def test_a_urdf_naming_a_file_of_the_server_s_disk_120_times_is_refused(
    server: ServerProcess, http_api: Api, tmp_path: Path
) -> None:
    on_disk = tmp_path / "server-side.stl"
    on_disk.write_bytes(mesh_stl())
    for ref in (str(on_disk), f"file://{on_disk}"):
        text = arm_naming(ref)
        assert len(text) < 40_000
        detail = _refused_in_bounded_memory(server, http_api, "arm.urdf", text.encode())
        assert ref in detail and "server's disk" in detail, detail
    assert not http_api.ok("GET", "/api/cell")["robot"].startswith("urdf_")


@pytest.mark.slow  # a real server process, memory measured
def test_a_zip_naming_its_mesh_120_times_counts_it_120_times(
    server: ServerProcess, http_api: Api
) -> None:
    stl = mesh_stl()
    buf = io.BytesIO()
    with zipfile.ZipFile(buf, "w", zipfile.ZIP_DEFLATED) as z:
        z.writestr("arm/robot.urdf", arm_naming("package://arm/meshes/link.stl"))
        z.writestr("arm/meshes/link.stl", stl)
    detail = _refused_in_bounded_memory(server, http_api, "arm.zip", buf.getvalue())
    assert f"{REFERENCES} mesh references load" in detail, detail


def _store_project_on_a_refused_arm(data_dir: Path, mesh_on_disk: Path) -> int:
    """A database as an earlier version left it: the last project on an uploaded arm whose
    URDF names a mesh of the server's disk, with two guide points."""
    text = arm_naming(str(mesh_on_disk), times=6).encode()
    cell = asdict(CellSettings(robot=robot_name_for("old_arm.urdf", text)))
    cell["robot_urdf"] = ["old_arm.urdf", base64.b64encode(text).decode("ascii")]
    store = Store(data_dir / DB_FILENAME)
    try:
        row = store.create_project("on its own arm", cell)
        guides = [GuidePointRow(np.eye(4), np.zeros(6), float(i), np.zeros(6)) for i in range(2)]
        store.save(row.id, guide_points=guides)
        return row.id
    finally:
        store.close()


@pytest.mark.slow  # two real server starts
def test_a_saved_project_whose_arm_is_refused_opens_on_the_default_arm(tmp_path: Path) -> None:
    on_disk = tmp_path / "server-side.stl"
    on_disk.write_bytes(mesh_stl(3))
    data = tmp_path / "data"
    project_id = _store_project_on_a_refused_arm(data, on_disk)
    for start in range(2):  # and again: no crash loop, whatever the last start did
        server = start_server(data, env={"ROBOMACH_REAL_TIME": "0"}, log_name=f"s{start}.log")
        api = Api(server.base_url)
        try:
            current = api.ok("GET", "/api/projects/current")
            assert current["id"] == project_id
            assert "old_arm.urdf" in current["notice"] and "is refused" in current["notice"]
            assert "is an absolute path" in current["notice"], current["notice"]
            assert api.ok("GET", "/api/cell")["robot"] == "ur10"
            assert api.ok("GET", "/api/guide-points") == []
        finally:
            api.close()
            assert server.stop() in (0, 130), server.log()
        assert "Traceback" not in server.log(), server.log()
    with sqlite3.connect(data / DB_FILENAME) as db:  # kept as it was: nobody changed it
        (cell_json,) = db.execute("SELECT cell_json FROM projects WHERE id = ?", (project_id,))
        assert json.loads(cell_json[0])["robot_urdf"][0] == "old_arm.urdf"
        assert db.execute("SELECT COUNT(*) FROM guide_points").fetchone()[0] == 2
    # The first change saves the project as it now is; the notice has served.
    server = start_server(data, env={"ROBOMACH_REAL_TIME": "0"}, log_name="s2.log")
    api = Api(server.base_url)
    try:
        api.ok("POST", "/api/guide-points", 201)
        assert api.ok("GET", "/api/projects/current")["notice"] == ""
    finally:
        api.close()
        server.stop()
    with sqlite3.connect(data / DB_FILENAME) as db:
        (cell_json,) = db.execute("SELECT cell_json FROM projects WHERE id = ?", (project_id,))
        cell = json.loads(cell_json[0])
        assert cell["robot"] == "ur10" and "robot_urdf" not in cell
        assert db.execute("SELECT COUNT(*) FROM guide_points").fetchone()[0] == 1
