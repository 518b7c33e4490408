"""Latency of GET /api/state over HTTP on a real ``robomach serve`` (p50, p99).

Run: ``python benchmarks/bench_api.py`` (starts a server on free ports with a throwaway data
folder, viser workbench included) or ``python benchmarks/bench_api.py --url
http://127.0.0.1:8000`` for a running one. One keep-alive client, sequential requests, three
conditions: idle; while the example lead-through job computes in the background (the job
thread competes for the interpreter); and with 4 clients reading at once. ``--quick`` sends 40
requests per condition (a smoke test, not a measurement).
"""

from __future__ import annotations

import argparse
import concurrent.futures
import sys
import tempfile
import time
from pathlib import Path

import httpx
import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

from tests.api.server_process import start_server  # noqa: E402


def latencies_ms(client: httpx.Client, n: int) -> np.ndarray:
    out = np.empty(n)
    for i in range(n):
        t = time.perf_counter()
        r = client.get("/api/state")
        out[i] = (time.perf_counter() - t) * 1e3
        r.raise_for_status()
    return out


def report(label: str, ms: np.ndarray) -> None:
    p50, p99 = np.percentile(ms, [50, 99])
    print(f"{label:<34} {len(ms):>6} {p50:>8.2f} {p99:>8.2f} {ms.max():>8.2f}")


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--url", help="a running server (default: start one)")
    parser.add_argument("-n", type=int, default=2000, help="requests per condition")
    parser.add_argument("--quick", action="store_true", help="40 requests per condition")
    args = parser.parse_args()
    if args.quick:
        args.n = 40
    server = None
    if args.url:
        url = args.url
    else:
        started = time.perf_counter()
        server = start_server(Path(tempfile.mkdtemp(prefix="robomach-bench-")) / "data")
        url = server.base_url
        print(f"server ready in {time.perf_counter() - started:.1f} s")
    try:
        with httpx.Client(base_url=url, timeout=30) as client:
            latencies_ms(client, min(200, args.n))  # warm up
            print(f"{'GET /api/state':<34} {'n':>6} {'p50 ms':>8} {'p99 ms':>8} {'max ms':>8}")
            report("idle", latencies_ms(client, args.n))

            job_id = None
            if not args.url:
                client.post("/api/projects", json={"name": f"bench-{time.time():.0f}"})
                client.put("/api/cell", json={"workpiece": "block"})
                job_id = client.post("/api/guide-points/example").json()["job_id"]
                time.sleep(0.5)
                report("during the example job", latencies_ms(client, args.n))
                client.post(f"/api/jobs/{job_id}/cancel")

            def reader(_: int) -> np.ndarray:
                with httpx.Client(base_url=url, timeout=30) as c:
                    return latencies_ms(c, args.n // 4)

            with concurrent.futures.ThreadPoolExecutor(4) as pool:
                ms = np.concatenate(list(pool.map(reader, range(4))))
            report("4 clients at once (per request)", ms)
    finally:
        if server is not None:
            server.stop(30.0)


if __name__ == "__main__":
    main()
