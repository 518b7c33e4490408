"""Pose updates per second that a browser showing the viser workbench receives while the robot
is pushed.

Run: ``python benchmarks/bench_browser_pose_rate.py`` (needs Debian's chromium). Two ways of
pushing, each measured for ``--seconds``:

- ``handle``: the workbench's spring handle, in-process (Session + Workbench on a free port):
  the handle circles around the tool and the spring pushes the robot after it, in real time.
- ``rest``: a real ``robomach serve``; a client holds a push as the pendant's push button does,
  as back-to-back ``POST /api/leadthrough/push`` of 20 ms each, paced to real time.

The browser's websocket frames are decoded (viser's wire format: zstd-compressed msgpack) and a
frame that moves ``/robot/tcp`` counts as one pose update seen. The page's own draw rate
(requestAnimationFrame, software WebGL here) is printed for information. ``--quick`` measures
each mode for 1 s after a short settling, on a page drawing two frames a second as the browser
tests' pages do, the rest mode's server started while the handle mode runs (a smoke test, not a
measurement).
"""

from __future__ import annotations

import argparse
import functools
import math
import sys
import tempfile
import threading
import time
from concurrent.futures import ThreadPoolExecutor
from pathlib import Path

import msgspec
import numpy as np
import zstandard

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

from tests.api.server_process import ServerProcess, free_port, start_server  # noqa: E402
from tests.browser.conftest import CHROMIUM_ARGS, START_TIMEOUT_S, new_context  # noqa: E402

TCP_NODE = "/robot/tcp"
LOAD_TIMEOUT_S = 90.0
REST_PUSH_S = 0.02
HANDLE_RADIUS_M = 0.04
HANDLE_PERIOD_S = 4.0


class PoseCounter:
    """Counts websocket frames that move the TCP node, with their arrival times."""

    def __init__(self) -> None:
        self.times: list[float] = []
        self._zstd = zstandard.ZstdDecompressor()

    def on_websocket(self, ws) -> None:
        ws.on("framereceived", self.on_frame)

    def on_frame(self, payload: bytes | str) -> None:
        if isinstance(payload, str) or len(payload) < 16:
            return
        size = int.from_bytes(payload[0:8], "little")
        compressed = int.from_bytes(payload[8:16], "little")
        try:
            inner = self._zstd.decompress(payload[16 : 16 + compressed], max_output_size=size)
            messages = msgspec.msgpack.decode(inner)["messages"]
        except Exception:
            return
        if any(
            m.get("type") == "SetPositionMessage" and m.get("name") == TCP_NODE for m in messages
        ):
            self.times.append(time.monotonic())

    def rate(self, start: float, end: float) -> tuple[int, float, float, float]:
        """Updates, rate [Hz], median and 95th-percentile interval [ms] within [start, end]."""
        t = np.array([x for x in self.times if start <= x <= end])
        if len(t) < 2:
            return len(t), 0.0, math.nan, math.nan
        gaps = np.diff(t) * 1e3
        return (
            len(t),
            len(t) / (end - start),
            float(np.median(gaps)),
            float(np.percentile(gaps, 95)),
        )


# Seconds the page is left to settle before measuring: the initial scene (meshes) arriving and
# parsed, then the pushes getting under way. ``--quick`` shortens both (a smoke test).
SETTLE_S = {"scene": 3.0, "pushing": 1.0}
THROTTLED = {"frames": False}  # --quick: the pages draw two frames a second (the tests' pace)


def open_viewer(browser, url: str):
    """A page of the headless ``browser`` on the viser URL; returns (page, counter)."""
    viewport = {"width": 960, "height": 640}
    if THROTTLED["frames"]:
        page = new_context(browser, viewport=viewport).new_page()
    else:
        page = browser.new_page(viewport=viewport)
    counter = PoseCounter()
    page.on("websocket", counter.on_websocket)
    page.add_init_script(
        "window.__frames = 0;"
        "(function tick() { window.__frames++; requestAnimationFrame(tick); })();"
    )
    page.goto(url)
    page.get_by_text("Connected").wait_for(timeout=LOAD_TIMEOUT_S * 1e3)
    page.get_by_text("Lead-through").first.wait_for(timeout=LOAD_TIMEOUT_S * 1e3)
    page.wait_for_timeout(SETTLE_S["scene"] * 1e3)  # the initial scene arrives and is parsed
    return page, counter


def measure(page, counter: PoseCounter, seconds: float, mode: str) -> dict:
    raf0 = page.evaluate("window.__frames")
    start = time.monotonic()
    page.wait_for_timeout(seconds * 1e3)  # Playwright delivers the frame events meanwhile
    end = time.monotonic()
    raf = (page.evaluate("window.__frames") - raf0) / (end - start)
    n, hz, median_ms, p95_ms = counter.rate(start, end)
    print(
        f"{mode:7s} {n:5d} pose updates in {end - start:.1f} s: {hz:5.1f} Hz "
        f"(interval median {median_ms:.1f} ms, p95 {p95_ms:.1f} ms); page draws {raf:.1f} fps"
    )
    return {"mode": mode, "updates": n, "rate_hz": hz, "median_ms": median_ms, "p95_ms": p95_ms}


def measure_while(browser, url: str, drive, seconds: float, mode: str) -> dict:
    """``measure`` the viewer at ``url`` while ``drive(stop)`` moves the robot in a thread
    (after the pushing settles); the thread is told to stop at the end."""
    stop = threading.Event()
    try:
        page, counter = open_viewer(browser, url)
        threading.Thread(target=drive, args=(stop,), daemon=True).start()
        page.wait_for_timeout(SETTLE_S["pushing"] * 1e3)
        result = measure(page, counter, seconds, mode)
        page.context.close()
    finally:
        stop.set()
    return result


def bench_handle(browser, seconds: float) -> dict:
    import viser

    from app.gui import Workbench
    from app.session import Session

    session = Session()
    server = viser.ViserServer(host="127.0.0.1", port=free_port(), verbose=False)
    wb = Workbench(server, session)

    def circle(stop: threading.Event) -> None:
        centre = session.robot.snapshot().position_m.copy()
        wb.leadthrough.spring.value = 1.0
        t0 = time.monotonic()
        while not stop.is_set():
            a = 2 * math.pi * (time.monotonic() - t0) / HANDLE_PERIOD_S
            offset = HANDLE_RADIUS_M * np.array([math.cos(a) - 1.0, math.sin(a), 0.0])
            wb.scene.handle.position = centre + offset
            wb.leadthrough.arm()
            stop.wait(0.02)

    try:
        url = f"http://127.0.0.1:{server.get_port()}/"
        return measure_while(browser, url, circle, seconds, "handle")
    finally:
        wb.close()
        server.stop()
        session.close()


def bench_rest(browser, seconds: float, served: ServerProcess) -> dict:
    """The ``rest`` mode on ``served`` (a real ``robomach serve``); stops it at the end."""
    import httpx

    def hold_push(stop: threading.Event) -> None:
        with httpx.Client(base_url=served.base_url, timeout=30.0) as client:
            t_next, direction, flipped = time.monotonic(), 1.0, time.monotonic()
            while not stop.is_set():
                if time.monotonic() - flipped > 2.0:  # back and forth, 2 s each way
                    direction, flipped = -direction, time.monotonic()
                body = {"force_N": [10.0 * direction, 0, 0], "duration_s": REST_PUSH_S}
                client.post("/api/leadthrough/push", json=body)
                t_next += REST_PUSH_S
                stop.wait(max(0.0, t_next - time.monotonic()))

    try:
        return measure_while(browser, served.viser_url, hold_push, seconds, "rest")
    finally:
        served.stop()


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--seconds", type=float, default=10.0, help="measuring window per mode")
    parser.add_argument("--mode", choices=("handle", "rest", "both"), default="both")
    parser.add_argument("--quick", action="store_true", help="1 s per mode, short settling")
    args = parser.parse_args()
    if args.quick:
        args.seconds = 1.0
        SETTLE_S.update(scene=0.5, pushing=0.3)
        THROTTLED["frames"] = True
    from playwright.sync_api import sync_playwright

    with tempfile.TemporaryDirectory() as tmp, ThreadPoolExecutor(max_workers=1) as starter:
        start = functools.partial(start_server, Path(tmp) / "data", start_timeout_s=START_TIMEOUT_S)
        # --quick (a smoke test): the rest mode's server starts while the handle mode runs; a
        # measurement keeps them apart
        early = starter.submit(start) if args.quick and args.mode == "both" else None
        try:
            with sync_playwright() as p:  # one chromium; each mode a page of its own
                browser = p.chromium.launch(executable_path="/usr/bin/chromium", args=CHROMIUM_ARGS)
                if args.mode in ("handle", "both"):
                    bench_handle(browser, args.seconds)
                if args.mode in ("rest", "both"):
                    served, early = (start() if early is None else early.result()), None
                    bench_rest(browser, args.seconds, served)
                browser.close()
        finally:
            if early is not None:  # the handle mode failed: stop the server started for rest
                early.result().stop(kill_on_timeout=True)
    return 0


if __name__ == "__main__":
    sys.exit(main())
