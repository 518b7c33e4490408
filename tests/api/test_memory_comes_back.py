"""A server's memory comes back (issue 32, points 2 and 3), measured on a real ``robomach
serve`` over HTTP: 20 machining comparisons grow its resident memory by less than 100 MB, and
so do 20 cell changes with mesh uploads, measured after the last one.

Before: each comparison kept its result in the job history (about 9 MB on this short block
program, 86 MB on a longer one) and every cell change kept its supervisor and workpiece for
the life of the process (60-470 MB per 500k-triangle upload). One round first warms up
(compiled kernels, the pool's forkserver, the isolation helper); the bound is on the 20 after.
``benchmarks/bench_soak.py`` runs the same for 10 minutes with event readers and prints the
curve.
"""

from __future__ import annotations

import functools
import io
from collections.abc import Iterator
from pathlib import Path

import pytest
import trimesh

from tests.api.server_process import Api, ServerProcess, rss_bytes, start_server

GROWTH_BOUND_BYTES = 100 * 2**20
ROUNDS = 20


@pytest.fixture(scope="module")
def fresh_server(tmp_path_factory: pytest.TempPathFactory) -> Iterator[ServerProcess]:
    """A real server with the default limits (80k-triangle uploads pass)."""
    server = start_server(
        tmp_path_factory.mktemp("memory") / "data", env={"ROBOMACH_REAL_TIME": "0"}
    )
    yield server
    assert server.stop() in (0, 130), server.log()
    assert "Traceback" not in server.log(), server.log()


@functools.cache
def _sphere() -> trimesh.Trimesh:
    return trimesh.creation.icosphere(subdivisions=6, radius=40.0)


def part_stl(i: int) -> bytes:
    """A different 80k-triangle part each time (a 4 MB STL)."""
    mesh = _sphere().copy()
    mesh.apply_translation([0.0, 0.0, 40.0 + 0.01 * i])
    buf = io.BytesIO()
    mesh.export(buf, file_type="stl")
    return buf.getvalue()


def _growth(server: ServerProcess, rounds: int, step) -> tuple[float, list[float]]:
    """RSS growth over ``rounds`` calls of ``step(i)`` after one warm-up call, and the curve."""
    step(-1)
    before = rss_bytes(server.proc.pid)
    curve = []
    for i in range(rounds):
        step(i)
        curve.append(rss_bytes(server.proc.pid) / 2**20)
    return rss_bytes(server.proc.pid) - before, curve


@pytest.mark.slow  # a real server, 21 comparisons
def test_20_comparisons_grow_memory_by_less_than_100_mb(fresh_server: ServerProcess) -> None:
    api = Api(fresh_server.base_url)
    try:
        api.new_project()
        api.learn()
        api.ok("POST", "/api/postprocess", json={"tolerance_mm": 0.05})

        def compare(i: int) -> None:
            job = api.ok("POST", "/api/machining/compare", 202)["job_id"]
            assert api.wait_job(job, 600)["status"] == "done"
            api.ok("GET", "/api/machining/result")  # what a client reads of it

        growth, curve = _growth(fresh_server, ROUNDS, compare)
        print(f"comparisons: grew {growth / 2**20:.0f} MiB; RSS MiB {[round(c) for c in curve]}")
        assert growth < GROWTH_BOUND_BYTES, f"grew {growth / 2**20:.0f} MiB: {curve}"
    finally:
        api.close()


@pytest.mark.slow  # a real server, 21 uploads of an 80k-triangle part
def test_20_cell_changes_with_uploads_grow_memory_by_less_than_100_mb(
    fresh_server: ServerProcess, tmp_path: Path
) -> None:
    api = Api(fresh_server.base_url)
    try:
        api.new_project()

        def change(i: int) -> None:
            upload = {"file": (f"part{i + 1}.stl", part_stl(i + 1), "application/octet-stream")}
            api.ok("POST", "/api/cell/workpiece", files=upload)
            api.ok("PUT", "/api/cell", json={"workpiece": ("block", "water_pump")[i % 2]})

        growth, curve = _growth(fresh_server, ROUNDS, change)
        print(f"cell changes: grew {growth / 2**20:.0f} MiB; RSS MiB {[round(c) for c in curve]}")
        assert growth < GROWTH_BOUND_BYTES, f"grew {growth / 2**20:.0f} MiB: {curve}"
    finally:
        api.close()
