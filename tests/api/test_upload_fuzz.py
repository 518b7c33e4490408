"""Property-based upload fuzzing against a running ``robomach serve`` (issue 19, "What to build"
6): meshes (flat, degenerate, huge, far away, corrupt), URDFs (deep, wide, huge, mutated) and
archives (robot zips and project files: bombs, lying headers, too many entries, bad arrays).

Every answer must be below 500 and the process must live; at the end the peak resident memory
of the server and of its isolation helper (``VmHWM`` of each, reset when the fuzz starts,
summed) must be under ``PEAK_MEMORY_BYTES``. The isolation helper's forked children are not in
that sum: each runs under ``RLIMIT_AS`` = the helper's address space + 1 GiB
(``isolation.DEFAULT_MEMORY_BYTES``).

Counts: ``test_upload_fuzz`` sends ``QUICK`` examples of each family (a minute or two),
``test_upload_fuzz_full`` sends ``FULL`` (>= 500 meshes, >= 200 URDFs and archives); both are
slow (a server of their own), the quick one alone: ``-k "upload_fuzz and not full"``.
The inputs are drawn from a fresh seed each run, printed (``ROBOMACH_SEED`` replays it).
"""

from __future__ import annotations

import io
import json
import struct
import zipfile
from collections import Counter
from collections.abc import Iterator
from pathlib import Path

import numpy as np
import pytest
import trimesh
from hypothesis import HealthCheck, given, seed, settings
from hypothesis import strategies as st

from robomach_core.robots import abb
from tests.api.server_process import (
    Api,
    ServerProcess,
    descendants,
    peak_rss_bytes,
    reset_peak_rss,
    start_server,
)
from tests.api.zip_bombs import renamed, zeros_member, zip_with
from tests.envelope import replay, run_seed

PEAK_MEMORY_BYTES = 2 << 30
QUICK = {"mesh": 60, "urdf": 25, "archive": 25}
FULL = {"mesh": 520, "urdf": 110, "archive": 110}
BOMB_BYTES = 1 << 30
COUNTS: Counter = Counter()
STATUSES: Counter = Counter()  # (family, status): what the server answered


@pytest.fixture(scope="module")
def fuzzed(tmp_path_factory: pytest.TempPathFactory) -> Iterator[tuple[ServerProcess, Api]]:
    data: Path = tmp_path_factory.mktemp("upload-fuzz") / "data"
    proc = start_server(data, env={"ROBOMACH_REAL_TIME": "0"})
    api = Api(proc.base_url)
    api.new_project()
    api.ok("GET", "/api/state")
    reset_peak_rss(proc.proc.pid)
    yield proc, api
    api.http.close()
    code = proc.stop(kill_on_timeout=True)
    assert code in (0, 130), proc.log()[-5000:]


@pytest.fixture(scope="module")
def bombs() -> dict[str, bytes]:
    """Deflate bombs made once: 1 GiB of zeros as a referenced robot mesh, a project array."""
    return {"mesh": zeros_member(BOMB_BYTES), "npy": zeros_member(BOMB_BYTES, npy=True)}


def _answer_ok(server: ServerProcess, r, family: str) -> None:
    STATUSES[family, r.status_code] += 1
    assert r.status_code < 500, f"{r.status_code}: {r.text[:500]}"
    assert server.proc.poll() is None, server.log()[-5000:]


# --- meshes ---------------------------------------------------------------------------------

FLOATS = st.one_of(
    st.floats(-1e4, 1e4),
    st.sampled_from([0.0, 1e-9, 1e9, 1e30, -1e30, 3.4e38, float("nan"), float("inf")]),
)


def _export(mesh: trimesh.Trimesh, kind: str) -> bytes:
    out = mesh.export(file_type=kind)
    return out.encode() if isinstance(out, str) else out


@st.composite
def meshes(draw) -> tuple[str, bytes]:
    kind = draw(st.sampled_from(["stl", "stl_ascii", "obj", "ply"]))
    suffix = "." + kind.split("_")[0]
    family = draw(st.sampled_from(["box", "flat", "soup", "sphere", "bytes", "header", "text"]))
    if family == "box":
        extents = draw(st.tuples(*[st.floats(1e-3, 3e3)] * 3))
        mesh = trimesh.creation.box(extents=extents)
        mesh.apply_translation(draw(st.tuples(*[st.sampled_from([0.0, 1e3, 1e6, 1e9])] * 3)))
        return suffix, _export(mesh, kind)
    if family == "flat":
        n = draw(st.integers(1, 40))
        rng = np.random.default_rng(draw(st.integers(0, 2**32 - 1)))
        points = rng.uniform(-50, 50, (n * 3, 3))
        normal = rng.normal(size=3)
        points -= np.outer(points @ normal / (normal @ normal), normal)  # into one plane
        mesh = trimesh.Trimesh(points, np.arange(n * 3).reshape(n, 3), process=False)
        return suffix, _export(mesh, kind)
    if family == "soup":
        n = draw(st.integers(1, 60))
        rng = np.random.default_rng(draw(st.integers(0, 2**32 - 1)))
        scale = draw(st.sampled_from([1e-3, 1.0, 100.0, 1e5]))
        vertices = rng.uniform(-1, 1, (n + 3, 3)) * scale
        faces = rng.integers(0, n + 3, (n, 3))
        mesh = trimesh.Trimesh(vertices, faces, process=False)
        return suffix, _export(mesh, kind)
    if family == "sphere":
        mesh = trimesh.creation.icosphere(subdivisions=draw(st.integers(0, 4)), radius=30.0)
        return suffix, _export(mesh, kind)
    if family == "bytes":
        return suffix, draw(st.binary(max_size=2000))
    if family == "header":  # a binary STL that lies about its triangles, or a PLY header
        n = draw(st.sampled_from([0, 1, 2, 499_999, 500_001, 2**31, 2**32 - 1]))
        body = draw(st.integers(0, 50)) * 50
        if suffix == ".ply":
            return suffix, (
                f"ply\nformat binary_little_endian 1.0\nelement vertex {n}\n"
                f"property float x\nproperty float y\nproperty float z\nelement face {n}\n"
                "property list uchar int vertex_indices\nend_header\n"
            ).encode() + bytes(body)
        return ".stl", bytes(80) + struct.pack("<I", n) + bytes(body)
    # text: OBJ/ASCII lines with extreme numbers and out-of-range indices
    lines = []
    for _ in range(draw(st.integers(1, 30))):
        if draw(st.booleans()):
            x, y, z = (draw(FLOATS) for _ in range(3))
            lines.append(f"v {x!r} {y!r} {z!r}")
        else:
            a, b, c = (draw(st.integers(-5, 40)) for _ in range(3))
            lines.append(f"f {a} {b} {c}")
    return ".obj", "\n".join(lines).encode()


SEED = run_seed()


def fuzz_settings(examples: int):
    """Every upload fuzzer's settings: ``examples`` inputs drawn from the run's ``SEED`` (no
    example database), no deadline or health check (each input is an HTTP upload)."""
    chosen = settings(
        max_examples=examples,
        deadline=None,
        database=None,
        suppress_health_check=list(HealthCheck),
    )
    return lambda test: seed(SEED)(chosen(test))


def _fuzz_meshes(fuzzed, examples: int) -> None:
    server, api = fuzzed

    @fuzz_settings(examples)
    @given(mesh=meshes())
    def upload(mesh: tuple[str, bytes]) -> None:
        suffix, data = mesh
        COUNTS["mesh"] += 1
        r = api.post("/api/cell/workpiece", files={"file": (f"fuzz{suffix}", data)})
        _answer_ok(server, r, "mesh")

    upload()


# --- URDFs ----------------------------------------------------------------------------------

IRB = abb.urdf_text(abb.ABB_ARMS["irb4400"])
NUMBERS = st.sampled_from(["nan", "inf", "-inf", "1e308", "-1e308", "1e-308", "0", "x", ""])


@st.composite
def urdfs(draw) -> tuple[str, bytes]:
    family = draw(st.sampled_from(["chain", "wide", "nested", "mutated", "bytes", "huge"]))
    if family in ("chain", "wide"):
        n = draw(st.sampled_from([0, 10, 99, 101, 499, 501, 3500, 6000]))
        extra, parent = [], "tool0"
        for i in range(n):
            extra.append(
                f'<link name="x{i}"/><joint name="jx{i}" type="fixed"><parent link="{parent}"/>'
                f'<child link="x{i}"/><origin xyz="0 0 0.001" rpy="0 0 0"/></joint>'
            )
            parent = f"x{i}" if family == "chain" else parent
        return "arm.urdf", IRB.replace("</robot>", "".join(extra) + "</robot>").encode()
    if family == "nested":
        depth = draw(st.integers(1, 200))
        inner = "<a>" * depth + "</a>" * depth
        return "arm.urdf", IRB.replace(
            "</robot>", f"<link name='n'>{inner}</link></robot>"
        ).encode()
    if family == "mutated":
        text = IRB
        for _ in range(draw(st.integers(1, 6))):
            kind = draw(st.sampled_from(["number", "type", "drop", "dup", "cycle"]))
            if kind == "number":
                attr = draw(st.sampled_from(['lower="', 'upper="', 'xyz="', 'value="', 'mass="']))
                at = text.find(attr, draw(st.integers(0, len(text) - 1)))
                if at >= 0:
                    end = text.index('"', at + len(attr))
                    text = text[: at + len(attr)] + draw(NUMBERS) + text[end:]
            elif kind == "type":
                new = draw(st.sampled_from(["prismatic", "floating", "planar", "x", "fixed"]))
                text = text.replace('type="revolute"', f'type="{new}"', 1)
            elif kind == "drop":
                tag = draw(st.sampled_from(["<limit", "<parent", "<child", "<origin", "<link"]))
                at = text.find(tag)
                if at >= 0:
                    end = text.find(">", at)
                    text = text[:at] + text[end + 1 :]
            elif kind == "dup":
                text = text.replace("</robot>", '<link name="link_1"/></robot>')
            else:
                text = text.replace(
                    "</robot>",
                    '<joint name="back" type="fixed"><parent link="link_6"/>'
                    '<child link="base_link"/></joint></robot>',
                )
        return "arm.urdf", text.encode()
    if family == "huge":
        return "arm.urdf", IRB.replace(
            "</robot>", " " * draw(st.sampled_from([10**5, 3 * 10**6])) + "</robot>"
        ).encode()
    return draw(st.sampled_from(["arm.urdf", "arm.zip"])), draw(st.binary(max_size=3000))


def _fuzz_urdfs(fuzzed, examples: int) -> None:
    server, api = fuzzed

    @fuzz_settings(examples)
    @given(robot=urdfs())
    def upload(robot: tuple[str, bytes]) -> None:
        filename, data = robot
        COUNTS["urdf"] += 1
        r = api.post("/api/cell/robot", files={"file": (filename, data)})
        _answer_ok(server, r, "urdf")

    upload()


# --- archives -------------------------------------------------------------------------------

MESH_REF = "package://arm/meshes/tool.stl"
IRB_WITH_MESH = IRB.replace(
    '<link name="tool0"/>',
    f'<link name="tool0"><visual><geometry><mesh filename="{MESH_REF}"/></geometry></visual>'
    "</link>",
)


@st.composite
def archives(draw, bombs: dict[str, bytes]) -> tuple[str, str, bytes]:
    """(route, filename, bytes): robot zips to /api/cell/robot, project files to import."""
    family = draw(st.sampled_from(["robot-bomb", "robot-many", "robot-lying", "robot-odd", "npz"]))
    if family == "robot-bomb":
        name = draw(st.sampled_from(["arm/meshes/tool.stl", "arm/junk.bin", "../../x.stl"]))
        data = zip_with(
            {"arm/robot.urdf": IRB_WITH_MESH.encode()}, {"b": renamed(bombs["mesh"], name)}
        )
        return "/api/cell/robot", "arm.zip", data
    if family == "robot-many":
        n = draw(st.sampled_from([2, 100, 9_999, 10_001, 30_000]))
        buf = io.BytesIO()
        with zipfile.ZipFile(buf, "w", zipfile.ZIP_STORED) as z:
            z.writestr("arm/robot.urdf", IRB_WITH_MESH)
            for i in range(n):
                z.writestr(f"m/{i}", b"")
        return "/api/cell/robot", "arm.zip", buf.getvalue()
    if family == "robot-lying":  # a member that declares 10 bytes and holds more, or less
        stl = trimesh.creation.box(extents=(0.1, 0.1, 0.1)).export(file_type="stl")
        data = bytearray(zip_with({"arm/robot.urdf": IRB_WITH_MESH.encode(),
                                    "arm/meshes/tool.stl": stl}, {}))  # fmt: skip
        at = data.rfind(b"PK\x01\x02")  # the last central entry: the mesh
        declared = draw(st.sampled_from([0, 10, 2**31, 2**32 - 1]))
        data[at + 24 : at + 28] = struct.pack("<I", declared)
        return "/api/cell/robot", "arm.zip", bytes(data)
    if family == "robot-odd":
        members = draw(
            st.dictionaries(
                st.sampled_from(["a.urdf", "b.urdf", "arm/robot.urdf", "x/../../y", "m.stl"]),
                st.one_of(st.just(IRB_WITH_MESH.encode()), st.binary(max_size=500)),
                max_size=4,
            )
        )
        return "/api/cell/robot", "arm.zip", zip_with(members, {})
    # project files: bombs, wrong dtypes and shapes, documents of any JSON
    arrays: dict[str, np.ndarray] = {}
    doc = {"format": "robomach-project", "version": 1, "cell": {}, "guide_times_s": [],
           "post_settings": {}}  # fmt: skip
    if draw(st.booleans()):
        doc = draw(
            st.recursive(
                st.none() | st.booleans() | st.floats() | st.text(max_size=5),
                lambda kids: (
                    st.lists(kids, max_size=3)
                    | st.dictionaries(st.text(max_size=5), kids, max_size=3)
                ),
                max_leaves=10,
            )
        )
    arrays["document"] = np.frombuffer(json.dumps(doc).encode(), np.uint8)
    for key in draw(st.lists(st.sampled_from(["rec_time_s", "guide_T_base_tcp", "mesh_bytes",
                                              "rec_in_contact"]), max_size=3)):  # fmt: skip
        shape = draw(st.sampled_from([(0,), (3,), (2, 4, 4), (5, 6), (1_000_001,)]))
        dtype = draw(st.sampled_from(["<f8", "<f4", "|b1", "<i8", "<c16", "|u1"]))
        arrays[key] = np.zeros(shape, dtype=dtype)
    buf = io.BytesIO()
    np.savez_compressed(buf, **arrays)
    data = buf.getvalue()
    if draw(st.booleans()):  # and a 1 GiB array bomb beside them
        with zipfile.ZipFile(io.BytesIO(data)) as z:
            members = {n: z.read(n) for n in z.namelist()}
        name = draw(st.sampled_from(["rec_time_s.npy", "guide_force_N.npy", "other.npy"]))
        data = zip_with(members, {"b": renamed(bombs["npy"], name)})
    return "/api/projects/import", "project.npz", data


def _fuzz_archives(fuzzed, bombs, examples: int) -> None:
    server, api = fuzzed

    @fuzz_settings(examples)
    @given(archive=archives(bombs))
    def upload(archive: tuple[str, str, bytes]) -> None:
        route, filename, data = archive
        COUNTS["archive"] += 1
        params = {"name": "fuzz"} if route.endswith("import") else None
        r = api.post(route, params=params, files={"file": (filename, data)})
        _answer_ok(server, r, "archive")
        if route.endswith("import") and r.status_code == 201:
            api.new_project()

    upload()


def _memory_ok(server: ServerProcess) -> int:
    pids = [server.proc.pid, *descendants(server.proc.pid)]
    peak = sum(peak_rss_bytes(pid) for pid in pids)
    assert peak < PEAK_MEMORY_BYTES, f"peak {peak / 2**20:.0f} MiB over pids {pids}"
    return peak


def _run(fuzzed, bombs, counts: dict[str, int]) -> None:
    print(f"upload fuzz inputs: {replay(SEED)}")  # shown with a failure
    COUNTS.clear()
    STATUSES.clear()
    _fuzz_meshes(fuzzed, counts["mesh"])
    _fuzz_urdfs(fuzzed, counts["urdf"])
    _fuzz_archives(fuzzed, bombs, counts["archive"])
    server, _ = fuzzed
    peak = _memory_ok(server)
    print(f"upload fuzz: {dict(COUNTS)}; peak resident {peak / 2**20:.0f} MiB")
    print("answers:", dict(sorted(STATUSES.items())))
    for family, n in counts.items():
        assert COUNTS[family] >= n, COUNTS


@pytest.mark.slow  # a server of its own and 110 uploads
def test_upload_fuzz(fuzzed, bombs) -> None:
    _run(fuzzed, bombs, QUICK)


@pytest.mark.slow
def test_upload_fuzz_full(fuzzed, bombs) -> None:
    _run(fuzzed, bombs, FULL)
