"""Quick teaching on the pendant page (issue 9): keys, touch-off, server push, in a real browser.

Eight guide points around the water-pump groove, each with at most five user actions (key
presses, clicks, one typed number), then path learning on the wall the operator names,
post-processing (within 0.3 mm of the true wall) and the RAPID download, all through the page.
The actions and seconds per point are printed (``-s``); the browser tests' server is unpaced, so
the seconds are the page's and the server's, without the robot's motion at a person's pace.
"""

from __future__ import annotations

import re
import time

import httpx
import numpy as np
import pytest
from playwright.sync_api import Page, expect

from tests.browser.conftest import Served
from tests.browser.test_pendant import open_pendant, pose_mm

pytestmark = pytest.mark.slow

WOBJ_MM = np.array([800.0, 160.0, 0.0])  # the water pump's work-object origin (base frame)
# Over the groove's centreline (work-object frame, mm): a point in each straight run between
# the bolt bosses, and the corners. The first is reached in the setup.
GUIDE_XY_MM = [(-80, -62.5), (0, -62.5), (97, -62.5), (97, 16.25), (97, 62.5), (0, 62.5),
               (-97, 62.5), (-97, -16.25)]  # fmt: skip
TRAVEL_Z_MM = 30.0  # above the plate (its top at z = 20 mm) for the setup
LIFT_MM = 8.0  # the Z step: out of the 6 mm deep groove
MAX_ACTIONS_PER_POINT = 5


class Actions:
    """The user's actions, counted: each waits for the request it makes to answer.

    A motion key or button is ignored while the page's previous motion is still running (one
    motion request at a time), as a person's would be; the answer can reach the browser before
    the page has shown it, so each action first waits for the page to be idle.
    """

    def __init__(self, page: Page) -> None:
        self.page = page
        self.count = 0

    def idle(self) -> None:
        expect(self.page.locator("body")).not_to_have_attribute("data-moving", re.compile(".*"))

    def key(self, key: str, url_part: str) -> None:
        self.count += 1
        self.idle()
        with self.page.expect_response(lambda r: url_part in r.url and r.request.method == "POST"):
            self.page.keyboard.press(key)

    def click(self, selector: str, url_part: str) -> None:
        self.count += 1
        self.idle()
        with self.page.expect_response(lambda r: url_part in r.url and r.request.method == "POST"):
            self.page.click(selector)

    def fill(self, selector: str, value: float) -> None:
        self.count += 1
        self.page.fill(selector, f"{value:g}")


def wobj_mm(page: Page) -> np.ndarray:
    return pose_mm(page) - WOBJ_MM


def test_eight_guide_points_by_touch_off_then_learn_and_download(
    served: Served, api: httpx.Client, page: Page
) -> None:
    open_pendant(page, served)
    expect(page.locator("[data-frame-label]").first).to_have_text("work object")
    act = Actions(page)

    # Setup: fast jogs, a gentle touch-off force, then over the first point and down.
    act.fill("#jog-speed", 50)
    act.fill("#touch-force", 5)
    start = wobj_mm(page)
    for axis, goal, key in (("x", GUIDE_XY_MM[0][0], "Arrow"), ("y", GUIDE_XY_MM[0][1], "Arrow"),
                            ("z", TRAVEL_Z_MM, "Page")):  # fmt: skip
        delta = goal - start["xyz".index(axis)]
        field = "#jog-step-z" if axis == "z" else "#jog-step-mm"
        names = {"x": ("Left", "Right"), "y": ("Down", "Up"), "z": ("Down", "Up")}[axis]
        while abs(delta) > 0.01:
            step = min(abs(delta), 200.0)
            act.fill(field, round(step, 3))
            act.key(key + names[int(delta > 0)], "/api/leadthrough/jog")
            delta -= np.copysign(step, delta)
    act.fill("#jog-step-z", LIFT_MM)
    setup_actions = act.count
    assert np.allclose(wobj_mm(page)[:2], GUIDE_XY_MM[0], atol=0.5), wobj_mm(page)

    per_point: list[tuple[int, float]] = []
    step_mm = None
    for k, (x, y) in enumerate(GUIDE_XY_MM):
        t0, before = time.monotonic(), act.count
        if k:
            act.key("PageUp", "/api/leadthrough/jog")  # out of the groove
            here = wobj_mm(page)
            dx, dy = x - here[0], y - here[1]
            axis, delta = ("x", dx) if abs(dx) > abs(dy) else ("y", dy)
            if step_mm is None or abs(abs(delta) - step_mm) > 0.05:
                step_mm = round(abs(delta), 2)
                act.fill("#jog-step-mm", step_mm)
            key = {"x": ("ArrowLeft", "ArrowRight"), "y": ("ArrowDown", "ArrowUp")}[axis]
            act.key(key[int(delta > 0)], "/api/leadthrough/jog")
        act.click("#touch-z-minus", "/api/leadthrough/touch-off")  # down to the groove floor
        expect(page.locator("#contact")).to_have_text("contact")
        act.key("g", "/api/guide-points")
        expect(page.locator("#guide-count")).to_have_text(str(k + 1))
        per_point.append((act.count - before, time.monotonic() - t0))
        here = wobj_mm(page)
        assert np.allclose(here[:2], (x, y), atol=1.5) and 14.0 < here[2] < 16.0, here

    actions = [n for n, _ in per_point]
    seconds = [s for _, s in per_point]
    print(f"\nsetup: {setup_actions} actions; per guide point: actions {actions}, seconds "
          f"{[round(s, 1) for s in seconds]} (mean {np.mean(seconds):.1f} s)")  # fmt: skip
    assert max(actions) <= MAX_ACTIONS_PER_POINT, actions
    rows = page.locator("#guide-list tr")
    expect(rows).to_have_count(8)

    # Out of the groove, then learn the closed path at 10 N, post-process and download.
    act.key("PageUp", "/api/leadthrough/jog")
    page.fill("#learn-force", "10")
    page.fill("#learn-speed", "10")
    page.check("#learn-closed")
    # Over the centreline neither a push nor the nearer wall tells the side: the operator
    # says it (the outer wall, on the right of the anticlockwise route).
    page.select_option("#learn-wall-side", "auto")
    page.click("#learn-check")
    expect(page.locator("#learn-warnings")).to_contain_text("set the wall side")
    page.select_option("#learn-wall-side", "right")
    page.click("#learn-start")
    status = page.locator("#learn-status")
    expect(status).to_have_text(re.compile(r"^(done|failed|cancelled|recorded)"), timeout=300_000)
    # "done", or the recording's line that an event redraws over it right after.
    assert status.inner_text().startswith(("done", "recorded")), status.inner_text()
    page.click("#post-run")
    expect(page.locator("#post-targets")).not_to_have_text("-")
    assert int(page.locator("#post-targets").inner_text()) >= 8
    print(f"learned: {page.locator('#post-samples').inner_text()} samples, "
          f"{page.locator('#post-targets').inner_text()} targets, max deviation "
          f"{page.locator('#post-max').inner_text()}")  # fmt: skip
    # Touch-off left the points on the groove's floor: learned at the machining height, the
    # outer wall within 0.3 mm (1.27 mm before the wall was followed by force).
    assert float(page.locator("#post-max").inner_text().split()[0]) <= 0.3
    expect(page.locator("#post-taught")).to_contain_text("follows the taught wall")
    expect(page.locator("#post-problems")).to_be_hidden()
    with page.expect_download() as download:
        page.click("#export-download")
    text = open(download.value.path(), encoding="utf-8").read()
    assert "MODULE" in text and "MoveL" in text and "ENDMODULE" in text


def test_a_rest_change_reaches_the_pendant_within_a_second(
    served: Served, api: httpx.Client, page: Page
) -> None:
    open_pendant(page, served)
    expect(page.locator("#guide-count")).to_have_text("0")
    page.wait_for_function("() => window.robomachEvents && window.robomachEvents.readyState === 1")
    for n in (1, 2):
        t = time.monotonic()
        assert api.post("/api/guide-points", json={}).status_code == 201
        expect(page.locator("#guide-count")).to_have_text(str(n), timeout=1000)
        print(f"guide point {n} shown {1e3 * (time.monotonic() - t):.0f} ms after the REST call")
    assert api.put("/api/cell", json={"workpiece": "block"}).status_code == 200
    expect(page.locator("#guide-count")).to_have_text("0", timeout=1000)


def test_preview_keeps_the_pendant_column_width(served: Served, page: Page) -> None:
    open_pendant(page, served)
    width = page.locator(".pendant").evaluate("el => el.getBoundingClientRect().width")
    page.evaluate(
        "() => { const pre = document.getElementById('rapid-preview');"
        " pre.textContent = 'x'.repeat(2000); pre.classList.remove('hidden'); }"
    )
    card = page.locator("#export-card").evaluate("el => el.getBoundingClientRect().left")
    assert page.locator(".pendant").evaluate("el => el.getBoundingClientRect().width") == width
    assert card >= 0


FAKE_GAMEPAD = """
(() => {
  const pad = { id: "test stick", connected: true, index: 0, axes: [0, 0, 0, 0],
                buttons: [{ pressed: false, value: 0 }] };
  window.testPad = pad;
  navigator.getGamepads = () => [pad];
})();
"""


def test_gamepad_stick_jogs_and_button_records(
    served: Served, api: httpx.Client, page: Page
) -> None:
    page.add_init_script(FAKE_GAMEPAD)
    open_pendant(page, served)
    expect(page.locator("#gamepad-status")).to_have_text("test stick")
    expect(page.locator("#keymap")).to_be_visible()
    x0 = pose_mm(page)[0]
    page.evaluate("() => { window.testPad.axes[0] = 0.8; }")  # stick right: +X of the frame
    page.wait_for_timeout(1500)
    page.evaluate("() => { window.testPad.axes[0] = 0; }")
    page.wait_for_timeout(500)
    moved = pose_mm(page)[0] - x0
    assert 5.0 < moved < 1.5 * 25.0 * 0.8 * 1.6, moved  # up to 0.8 x 25 mm/s for ~1.5 s
    page.evaluate("() => { window.testPad.buttons[0].pressed = true; }")
    expect(page.locator("#guide-count")).to_have_text("1")
