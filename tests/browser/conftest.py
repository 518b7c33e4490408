"""Browser tests: a real ``robomach serve`` process and Debian's chromium driven by Playwright.

Playwright's own browser download cannot work here, so the tests launch ``/usr/bin/chromium``
(apt: ``chromium``); without it they skip locally and fail under CI. viser's WebGL scene
renders headless through SwiftShader.
"""

from __future__ import annotations

import os
import shutil
import time
import uuid
from collections.abc import Callable, Iterator
from contextlib import contextmanager
from pathlib import Path

import httpx
import pytest

from tests.api.server_process import ServerProcess, free_port, start_server

Served = ServerProcess  # the browser tests' name for a running ``robomach serve``

# Playwright's expect() waits 5 s by default (the context timeout does not apply to it); on the
# loaded 2-core machine viser's page takes longer than that to connect.
EXPECT_TIMEOUT_MS = 60_000

CHROMIUM = Path("/usr/bin/chromium")
CHROMIUM_ARGS = [
    "--headless=new",
    "--no-sandbox",
    "--disable-gpu",
    "--use-angle=swiftshader",
    "--disable-background-networking",
    "--disable-component-update",
    "--disable-sync",
    "--no-first-run",
]
# The tests' chromium draws WebGL without multisampling: SwiftShader's 4x MSAA cost a third of
# chromium's CPU in the pointing tests (27 -> 18 s in the click-to-teach test), for edges a
# pixel smoother in the screenshots. Clicks pick through the scene graph, not the pixels, and
# the pixel checks (test_viser_scene) compare far above an edge's share. The docs' screenshots
# (docs_screenshots.py) and the benchmarks keep CHROMIUM_ARGS as a person's browser draws.
TEST_CHROMIUM_ARGS = [*CHROMIUM_ARGS, "--webgl-antialiasing-mode=none"]
# A 3D page redraws its scene in software (SwiftShader) as fast as the machine allows: about
# six frames a second here, 0.25 s of CPU each, so an open viser page took over a core while
# the robot moved and chromium was a fifth of the suite's CPU. The tests need each change drawn,
# not six frames a second: every context they open (``new_context``) lets each animation-frame
# request wait ``FRAME_INTERVAL_MS`` first, so its pages draw about two frames a second. It is
# the same page drawn less often, as on a slower machine; what it draws and what a click picks
# do not change. (benchmarks/bench_browser_pose_rate.py measures the pages unthrottled.)
FRAME_INTERVAL_MS = 500
_THROTTLED_FRAMES_JS = f"""
(() => {{
  const raf = window.requestAnimationFrame.bind(window);
  const caf = window.cancelAnimationFrame.bind(window);
  const pending = new Map();
  let next = 1;
  window.requestAnimationFrame = (callback) => {{
    const id = next++;
    const entry = {{frame: undefined}};
    entry.timer = setTimeout(() => {{
      entry.frame = raf((t) => {{ pending.delete(id); callback(t); }});
    }}, {FRAME_INTERVAL_MS});
    pending.set(id, entry);
    return id;
  }};
  window.cancelAnimationFrame = (id) => {{
    const entry = pending.get(id);
    if (entry === undefined) return;
    clearTimeout(entry.timer);
    if (entry.frame !== undefined) caf(entry.frame);
    pending.delete(id);
  }};
}})();
"""


def new_context(browser, **options):
    """``browser.new_context(**options)`` whose pages draw about two frames a second (above)."""
    context = browser.new_context(**options)
    context.add_init_script(_THROTTLED_FRAMES_JS)
    return context


def frames_drawn(page, frames: int = 3) -> None:
    """Wait until ``page`` has drawn ``frames`` more animation frames. viser draws the scene
    messages it has received in its next frame, and the workbench sends a panel's scene before
    its text: once the text shows, this waits for its scene to be drawn (for a screenshot),
    instead of a fixed time. Its labels (the points' names) take three frames: after a guide
    point recorded, screenshots after one, two and three frames differed from the settled
    page in 928, 105 and 0 pixels."""
    page.evaluate(
        """(n) => new Promise((done) => {
             const next = (k) => (k > 0 ? requestAnimationFrame(() => next(k - 1)) : done());
             next(n);
           })""",
        frames,
    )


def drawn_whole(page, timeout_s: float = 30.0) -> None:
    """Wait until ``page`` draws no change from one frame to the next (for a screenshot).
    viser rasterises its labels' new glyphs 5 ms a frame: a label with new letters (the first
    "P1", "P2", ...) streams in over frames, as many as the machine's load makes it take."""
    deadline = time.monotonic() + timeout_s
    last = page.screenshot()
    while time.monotonic() < deadline:
        frames_drawn(page, 1)
        now = page.screenshot()
        if now == last:
            return
        last = now


def box_of(locator) -> dict[str, float]:
    """``locator``'s box on the page (x, y, width, height in CSS pixels), as ``bounding_box()``
    gives it, read by the page itself: ``bounding_box()`` took 0.3-1 s on a 3D page (a click on
    the part spent most of its time there), ``getBoundingClientRect`` 0.03 s."""
    return locator.evaluate(
        "(e) => { const r = e.getBoundingClientRect();"
        " return {x: r.x, y: r.y, width: r.width, height: r.height}; }"
    )


START_TIMEOUT_S = 90.0
VIEWPORT = {"width": 1400, "height": 900}


@pytest.fixture(scope="session")
def served(tmp_path_factory: pytest.TempPathFactory) -> Iterator[Served]:
    """One server for the browser tests (each test opens its own project), unpaced: a page's
    jogs, pushes and touch-offs answer as soon as they are computed. What the pages show does
    not depend on the pace; pacing itself is tested through the API (tests/api/test_teach.py)
    and a person's wait is measured in benchmarks/ (bench_pointing.py and
    bench_browser_pose_rate.py)."""
    server = start_server(
        tmp_path_factory.mktemp("browser") / "data",
        env={"ROBOMACH_REAL_TIME": "0"},
        log_name="serve.log",
        start_timeout_s=START_TIMEOUT_S,
    )
    yield server
    code = server.stop(kill_on_timeout=True)
    assert code in (0, 130), server.log()
    assert "Traceback" not in server.log(), server.log()


@pytest.fixture
def api(served: Served) -> Iterator[httpx.Client]:
    """A REST client on a new, open project: each test starts from the default cell."""
    client = httpx.Client(base_url=served.base_url, timeout=60.0)
    r = client.post("/api/projects", json={"name": f"browser-{uuid.uuid4().hex[:8]}"})
    assert r.status_code == 201, r.text
    yield client
    for job in client.get("/api/jobs").json():
        if job["status"] in ("queued", "running"):
            client.post(f"/api/jobs/{job['job_id']}/cancel")
    client.close()


@pytest.fixture(scope="session")
def browser():
    """Headless chromium (Debian's), shared by the tests."""
    if not CHROMIUM.exists() and shutil.which("chromium") is None:
        message = "chromium is not installed (apt-get install chromium chromium-driver)"
        if os.environ.get("CI"):
            pytest.fail(message)
        pytest.skip(message)
    from playwright.sync_api import expect, sync_playwright

    expect.set_options(timeout=EXPECT_TIMEOUT_MS)

    with sync_playwright() as p:
        executable = str(CHROMIUM) if CHROMIUM.exists() else shutil.which("chromium")
        b = p.chromium.launch(executable_path=executable, args=TEST_CHROMIUM_ARGS)
        yield b
        b.close()


@pytest.fixture(autouse=True)
def _close_left_contexts(request: pytest.FixtureRequest) -> Iterator[None]:
    """After a test that used the shared browser, close any context it left open: a viser page
    left open keeps drawing its scene in software (a quarter of a core each) and slowed the
    later browser tests up to tenfold."""
    yield
    if "browser" in request.fixturenames:
        for context in list(request.getfixturevalue("browser").contexts):
            context.close()


@pytest.fixture
def page(browser):
    """A fresh browser context (own localStorage, downloads accepted) and page."""
    context = new_context(browser, viewport=VIEWPORT, accept_downloads=True)
    context.set_default_timeout(30_000)
    pg = context.new_page()
    yield pg
    context.close()


def wait_for(
    condition: Callable[[], bool],
    timeout_s: float = 60.0,
    poll_s: float = 0.02,
    *,
    describe: Callable[[], str] | None = None,
) -> None:
    """Poll ``condition`` until it holds; fail after ``timeout_s``, saying ``describe()`` (what
    was seen instead) when given."""
    deadline = time.monotonic() + timeout_s
    while not condition():
        if time.monotonic() > deadline:
            seen = f": {describe()}" if describe is not None else ""
            raise AssertionError(f"condition not met in {timeout_s:g} s{seen}")
        time.sleep(poll_s)


@contextmanager
def workbench_on(session) -> Iterator:
    """The viser workbench in-process over ``session`` (no browser needed); closes both."""
    import viser

    from app.gui import Workbench

    server = viser.ViserServer(host="127.0.0.1", port=free_port(), verbose=False)
    wb = Workbench(server, session)
    try:
        yield wb
    finally:
        wb.close()
        server.stop()
        session.close()
