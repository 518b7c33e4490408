"""The issue's reproducers against a real ``robomach serve`` (issue 19, R1, R2, R4): the process
survives each, answers 4xx with a message, and its memory stays bounded.

Old code: the flat STL (upload or inside a 3.3 KB project) and the 5,000-link URDF killed the
process (SIGSEGV); the 1 MB robot zip holding a 1 GiB mesh and the project file holding a
1 GiB array each added about a GiB. The bound chosen here: the server's peak resident memory
(``VmHWM``, reset before each request) grows by less than ``MEMORY_GROWTH_BOUND_BYTES``.
"""

from __future__ import annotations

import io
import re
import struct
import zipfile

import pytest
import trimesh

from robomach_core.project import CellSettings, Project, project_file_bytes
from robomach_core.robots import abb
from tests.api.server_process import Api, ServerProcess, peak_rss_bytes, reset_peak_rss, rss_bytes
from tests.api.zip_bombs import renamed, zeros_member, zip_with

MEMORY_GROWTH_BOUND_BYTES = 200 << 20
# The issue's 184-byte STL: two coplanar triangles, a 100 mm square at z = 0.
FLAT_STL = (
    bytes(80)
    + struct.pack("<I", 2)
    + b"".join(
        struct.pack("<12f", 0, 0, 0, *t) + b"\0\0"
        for t in [(0, 0, 0, 100, 0, 0, 100, 100, 0), (0, 0, 0, 100, 100, 0, 0, 100, 0)]
    )
)
BOMB_BYTES = 1 << 30


@pytest.fixture
def api(http_api: Api) -> Api:
    """Over real HTTP to ``robomach serve``: the process must survive what killed it, and
    its memory is measured."""
    return http_api


def alive(server: ServerProcess, api: Api) -> None:
    assert server.proc.poll() is None, server.log()[-3000:]
    assert api.get("/api/health").status_code == 200


def refused(r, needle: str, status: int = 422) -> None:
    assert r.status_code == status, r.text
    assert re.search(needle, r.json()["detail"]), r.json()["detail"]


@pytest.mark.slow  # a real server process (it must survive the input)
def test_r1_the_flat_stl_is_refused_and_the_server_lives(server: ServerProcess, api: Api):
    r = api.post("/api/cell/workpiece", files={"file": ("flat.stl", FLAT_STL)})
    refused(r, r"flat.stl|flat: the part is 0 mm thick")
    alive(server, api)
    far = trimesh.creation.box(extents=(100.0, 100.0, 100.0))
    far.apply_translation([1e9, 0, 0])
    r = api.post("/api/cell/workpiece", files={"file": ("far.stl", far.export(file_type="stl"))})
    refused(r, "from its origin")
    alive(server, api)
    assert api.ok("GET", "/api/cell")["workpiece"] == "water_pump"  # nothing lost


@pytest.mark.slow  # a real server process (it must survive the input)
def test_r1_a_project_file_holding_the_flat_stl_is_refused(server: ServerProcess, api: Api):
    project = Project(
        cell=CellSettings(workpiece="flat", workpiece_builtin=False), mesh=("flat.stl", FLAT_STL)
    )
    data = project_file_bytes(project)
    assert len(data) < 4000
    r = api.post("/api/projects/import", params={"name": "flat"}, files={"file": ("p.npz", data)})
    refused(r, "0 mm thick")
    alive(server, api)


def _deep_urdf(n: int) -> bytes:
    text = abb.urdf_text(abb.ABB_ARMS["irb4400"])
    extra, parent = [], "tool0"
    for i in range(n):
        extra.append(
            f'<link name="x{i}"/><joint name="jx{i}" type="fixed"><parent link="{parent}"/>'
            f'<child link="x{i}"/><origin xyz="0 0 0.001" rpy="0 0 0"/></joint>'
        )
        parent = f"x{i}"
    return text.replace("</robot>", "".join(extra) + "</robot>").encode()


@pytest.mark.slow  # a real server process (it must survive the input)
def test_r2_the_5000_link_urdf_is_refused_and_the_server_lives(server: ServerProcess, api: Api):
    r = api.post("/api/cell/robot", files={"file": ("deep.urdf", _deep_urdf(5000))})
    refused(r, "5008 links, more than 500")
    alive(server, api)


@pytest.fixture(scope="module")
def robot_bomb() -> bytes:
    text = (
        _deep_urdf(0)
        .decode()
        .replace(
            '<link name="tool0"/>',
            '<link name="tool0"><visual><geometry><mesh filename="package://arm/meshes/tool.stl"/>'
            "</geometry></visual></link>",
        )
    )
    mesh = renamed(zeros_member(BOMB_BYTES), "arm/meshes/tool.stl")
    return zip_with({"arm/robot.urdf": text.encode()}, {"mesh": mesh})


@pytest.fixture(scope="module")
def project_bomb() -> bytes:
    good = project_file_bytes(Project())
    with zipfile.ZipFile(io.BytesIO(good)) as z:
        document = z.read("document.npy")
    array = renamed(zeros_member(BOMB_BYTES, npy=True), "rec_time_s.npy")
    return zip_with({"document.npy": document}, {"array": array})


def _memory_bounded(server: ServerProcess, request) -> None:
    pid = server.proc.pid
    reset_peak_rss(pid)
    before = rss_bytes(pid)
    request()
    growth = peak_rss_bytes(pid) - before
    assert growth < MEMORY_GROWTH_BOUND_BYTES, f"peak grew {growth / 2**20:.0f} MiB"


@pytest.mark.slow  # a real server process, memory measured
def test_r4_a_robot_zip_bomb_is_refused_in_bounded_memory(
    server: ServerProcess, api: Api, robot_bomb: bytes
):
    assert len(robot_bomb) < 2_000_000

    def upload() -> None:
        r = api.post("/api/cell/robot", files={"file": ("arm.zip", robot_bomb)})
        refused(r, r"tool.stl declares 1073.7 MB, more than 50 MB")

    _memory_bounded(server, upload)
    alive(server, api)
    cache = server.data_dir.parent
    assert not any(p.stat().st_size > 50e6 for p in cache.rglob("*.stl"))


@pytest.mark.slow  # a real server process, memory measured
def test_r4_a_project_file_bomb_is_refused_in_bounded_memory(
    server: ServerProcess, api: Api, project_bomb: bytes
):
    assert len(project_bomb) < 8_000_000

    def upload() -> None:
        r = api.post(
            "/api/projects/import", params={"name": "bomb"}, files={"file": ("p.npz", project_bomb)}
        )
        refused(r, r"'rec_time_s' has 134217728 rows, more than 1000000")

    _memory_bounded(server, upload)
    alive(server, api)
