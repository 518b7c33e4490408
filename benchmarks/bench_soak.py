"""A server that lives for weeks: its memory over 10 minutes of comparisons, mesh uploads and
cell changes with event readers attached (issue 32: 544 MB to 6.1 GB in 8.5 minutes and 68
comparisons with 200 readers; 60 cell changes kept 61 supervisors and meshes).

Run: ``python benchmarks/bench_soak.py [--minutes 10] [--readers 50]`` (starts ``robomach
serve`` on free ports with a throwaway data folder, viser workbench included). Two projects:
"machining" holds a learned, post-processed block program; "uploads" takes the meshes. Each
round opens "machining" and runs the machining comparison (18 runs), then opens "uploads",
uploads a new 80k-triangle part (a 4 MB STL) and sets the cell back to a built-in part: three
cell changes and an upload per round. ``--readers`` streams of ``GET /api/events`` are read
meanwhile by a second process. The server's resident memory (and that of every process under
it: the isolation helper, the pool's forkserver and workers) is sampled every ``--every``
seconds and printed as a curve; the summary fits a line to the samples after the warm-up
(the first fifth of the run) and prints its slope. ``--quick``: one round, 5 readers, a
sample every 0.5 s (a smoke test, not a measurement).
"""

from __future__ import annotations

import argparse
import io
import multiprocessing
import sys
import tempfile
import threading
import time
from pathlib import Path

import httpx
import numpy as np
import trimesh

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

from benchmarks.bench_events import listeners_process  # noqa: E402
from tests.api.server_process import Api, descendants, rss_bytes, start_server  # noqa: E402

MIB = 2**20


def part_stl(i: int) -> bytes:
    """A different 80k-triangle part each round (a 4 MB STL)."""
    mesh = trimesh.creation.icosphere(subdivisions=6, radius=40.0)
    mesh.apply_translation([0.0, 0.0, 40.0 + 0.01 * i])
    buf = io.BytesIO()
    mesh.export(buf, file_type="stl")
    return buf.getvalue()


def _rss_all(pid: int) -> int:
    total = 0
    for p in (pid, *descendants(pid)):
        try:
            total += rss_bytes(p)
        except OSError:
            pass
    return total


class Sampler(threading.Thread):
    """The server's memory every ``every_s`` seconds, with the work done so far."""

    def __init__(self, pid: int, every_s: float, counts: dict[str, int]) -> None:
        super().__init__(daemon=True)
        self.pid, self.every_s, self.counts = pid, every_s, counts
        self.rows: list[tuple[float, float, float, int, int, int]] = []
        self.stop = threading.Event()
        self.t0 = time.monotonic()

    def sample(self) -> None:
        c = self.counts
        self.rows.append(
            (time.monotonic() - self.t0, rss_bytes(self.pid) / MIB, _rss_all(self.pid) / MIB,
             c["comparisons"], c["uploads"], c["cell changes"])
        )  # fmt: skip

    def run(self) -> None:
        while not self.stop.wait(self.every_s):
            self.sample()


def setup_projects(api: Api) -> tuple[int, int]:
    """(machining, uploads) project ids; "machining" holds a post-processed block program."""
    machining = api.ok("POST", "/api/projects", 201, json={"name": "machining"})["id"]
    api.learn()
    api.ok("POST", "/api/postprocess", json={"tolerance_mm": 0.05})
    uploads = api.ok("POST", "/api/projects", 201, json={"name": "uploads"})["id"]
    return machining, uploads


def one_round(api: Api, machining: int, uploads: int, i: int, counts: dict[str, int]) -> None:
    api.ok("POST", f"/api/projects/{machining}/open")
    counts["cell changes"] += 1
    job = api.ok("POST", "/api/machining/compare", 202)["job_id"]
    status = api.wait_job(job, 900)["status"]
    if status != "done":
        raise SystemExit(f"comparison {i} ended {status}")
    api.ok("GET", "/api/machining/result")
    counts["comparisons"] += 1
    api.ok("POST", f"/api/projects/{uploads}/open")
    counts["cell changes"] += 1
    upload = {"file": (f"part{i}.stl", part_stl(i), "application/octet-stream")}
    api.ok("POST", "/api/cell/workpiece", files=upload)
    counts["uploads"] += 1
    counts["cell changes"] += 1
    api.ok("PUT", "/api/cell", json={"workpiece": ("block", "water_pump")[i % 2]})
    counts["cell changes"] += 1


def summary(rows: list[tuple], warm_up_s: float) -> str:
    t = np.array([r[0] for r in rows])
    server = np.array([r[1] for r in rows])
    after = t >= warm_up_s
    if after.sum() < 3:
        return "too few samples after the warm-up for a slope"
    slope, _ = np.polyfit(t[after] / 60.0, server[after], 1)
    return (
        f"after the warm-up ({warm_up_s:.0f} s): server RSS {server[after].min():.0f}-"
        f"{server[after].max():.0f} MiB, slope {slope:+.1f} MiB/min, last minus first "
        f"{server[after][-1] - server[after][0]:+.0f} MiB"
    )


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--minutes", type=float, default=10.0)
    parser.add_argument("--readers", type=int, default=50)
    parser.add_argument("--every", type=float, default=15.0, help="seconds between samples")
    parser.add_argument("--quick", action="store_true")
    args = parser.parse_args()
    if args.quick:
        args.minutes, args.readers, args.every = 0.0, 5, 0.5
    data = Path(tempfile.mkdtemp(prefix="robomach-soak-")) / "data"
    server = start_server(data, env={"ROBOMACH_REAL_TIME": "0"})
    ctx = multiprocessing.get_context("spawn")
    counts_shared = ctx.Array("l", max(args.readers, 1), lock=False)
    ready = ctx.Semaphore(0)
    readers = ctx.Process(
        target=listeners_process,
        args=(server.base_url, args.readers, counts_shared, ready),
        daemon=True,
    )
    api = Api(server.base_url)
    counts = {"comparisons": 0, "uploads": 0, "cell changes": 0}
    try:
        machining, uploads = setup_projects(api)
        if args.readers:
            readers.start()
            for _ in range(args.readers):
                if not ready.acquire(timeout=60):
                    raise SystemExit("the event readers did not connect")
        sampler = Sampler(server.proc.pid, args.every, counts)
        sampler.sample()
        sampler.start()
        deadline = time.monotonic() + 60.0 * args.minutes
        i = 0
        while i == 0 or time.monotonic() < deadline:  # one round at least
            one_round(api, machining, uploads, i, counts)
            i += 1
        sampler.stop.set()
        sampler.join()
        sampler.sample()
        events = sum(counts_shared[: args.readers]) if args.readers else 0
    except (httpx.HTTPError, AssertionError) as exc:
        print(server.log()[-4000:])
        raise SystemExit(f"the soak stopped: {exc}") from None
    finally:
        api.close()
        if readers.is_alive():
            readers.terminate()
        server.stop(kill_on_timeout=True)
    print(f"soak: {args.minutes:g} min, {args.readers} event readers, {i} rounds")
    print(f"{'t_s':>6} {'server_MiB':>10} {'all_MiB':>8} {'compare':>8} {'uploads':>8} "
          f"{'cell_changes':>12}")  # fmt: skip
    for t, server_mib, all_mib, comparisons, n_uploads, changes in sampler.rows:
        print(f"{t:6.0f} {server_mib:10.0f} {all_mib:8.0f} {comparisons:8d} {n_uploads:8d} "
              f"{changes:12d}")  # fmt: skip
    print(
        f"done: {counts['comparisons']} comparisons, {counts['uploads']} uploads, "
        f"{counts['cell changes']} cell changes; {events} robot events read"
    )
    print(summary(sampler.rows, warm_up_s=0.2 * 60.0 * args.minutes))


if __name__ == "__main__":
    main()
