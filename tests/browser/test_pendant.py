"""The teach pendant page (/pendant/) in a real browser over a real server.

A short programming-by-demonstration session on the aluminium block, all through the page:
jog, lead the tool by push buttons to two points pressed against the block's front wall
(y = 135 mm), record them, learn the path between them, post-process, download program.mod.
"""

from __future__ import annotations

import re
import time

import httpx
import numpy as np
import pytest
from playwright.sync_api import Page, expect

from tests.browser.conftest import Served

pytestmark = pytest.mark.slow

PUSH_DURATION_S = 2.0
DAMPING_N_S_M = 500.0  # the admittance's damping: a push F for T seconds moves F T / D
PUSH_MAX_N = 25.0  # 25 N / 500 N*s/m = the 50 mm/s speed limit
DEADBAND_N = 1.0  # the admittance ignores this much of any force (sensor noise)
WALL_Y_MM = 135.0  # the block's front wall (block centred at y = 160 mm, 50 mm deep)


def pose_mm(page: Page) -> np.ndarray:
    return np.array([float(page.locator(f"#pose-{a}").inner_text()) for a in "xyz"])


def click_and_wait(page: Page, selector: str, url_part: str) -> None:
    """Click and wait until the request it makes has answered."""
    with page.expect_response(lambda r: url_part in r.url and r.request.method != "GET"):
        page.click(selector)


def set_compliance(page: Page, axes: str) -> None:
    """Tick exactly the given translational axes ("xyz", "xy") on the page."""
    for a in "xyz":
        box = page.locator(f"#comp-{a}")
        if box.is_checked() != (a in axes):
            with page.expect_response("**/api/leadthrough/compliance"):
                box.click()


def push(page: Page, axis: str, force_N: float, duration_s: float = PUSH_DURATION_S) -> None:
    """One push along a base axis with the page's push buttons."""
    page.fill("#push-force", f"{abs(force_N):.3f}")
    page.fill("#push-duration", f"{duration_s:.3f}")
    sign = "plus" if force_N > 0 else "minus"
    click_and_wait(page, f"#push-{axis}-{sign}", "/api/leadthrough/push")


def push_to(page: Page, goal_mm: tuple[float, float, float], tolerance_mm: float = 1.0) -> None:
    """Lead the tool to ``goal_mm`` by pushes along x and y, then z (the admittance stops at
    once when the push ends)."""
    for axes in ("xy", "z"):
        for _ in range(20):
            err = np.asarray(goal_mm) - pose_mm(page)
            todo = [i for i in ("xyz".index(a) for a in axes) if abs(err[i]) > tolerance_mm]
            if not todo:
                break
            for i in todo:
                # Moves (|F| - deadband) T / D: a firm push for long moves, a short one near.
                e = abs(err[i]) * 1e-3
                f = float(
                    np.clip(DAMPING_N_S_M * e / PUSH_DURATION_S + DEADBAND_N, 3.0, PUSH_MAX_N)
                )
                t = min(PUSH_DURATION_S, DAMPING_N_S_M * e / (f - DEADBAND_N))
                push(page, "xyz"[i], float(np.copysign(f, err[i])), t)
        else:
            raise AssertionError(f"the tool did not reach {goal_mm}: it is at {pose_mm(page)}")


def open_pendant(page: Page, served: Served) -> None:
    page.goto(f"{served.base_url}/pendant/?viser=about:blank")
    expect(page.locator("#connection")).to_have_text("online")
    expect(page.locator("#pose-x")).not_to_have_text("-")


def test_pendant_teaches_a_short_path(served: Served, api: httpx.Client, page: Page) -> None:
    # Choosing the workpiece is not a pendant function: the cell is set up through the API.
    assert api.put("/api/cell", json={"workpiece": "block"}).status_code == 200
    open_pendant(page, served)
    expect(page.locator("#viser-frame")).to_have_attribute("src", "about:blank")

    # A refused call shows the server's message.
    page.click("#learn-start")
    expect(page.locator("#message-text")).to_contain_text("at least 2 guide points")
    page.click("#message-close")
    expect(page.locator("#message")).to_be_hidden()

    # Jog: a 5 mm step along a tool axis moves the TCP by 5 mm.
    before = pose_mm(page)
    click_and_wait(page, "#jog-x-plus", "/api/leadthrough/jog")
    # The page draws the pose once it has read the answer's body: wait for the move to show.
    deadline = time.monotonic() + 10.0
    while np.linalg.norm(pose_mm(page) - before) < 4.0 and time.monotonic() < deadline:
        time.sleep(0.05)
    assert abs(np.linalg.norm(pose_mm(page) - before) - 5.0) < 0.5
    rx_before = page.locator("#pose-rz").inner_text()
    click_and_wait(page, "#jog-rz-plus", "/api/leadthrough/jog")
    expect(page.locator("#pose-rz")).not_to_have_text(rx_before)

    # Lead-through: two guide points pressed gently against the front wall.
    for x in (760.0, 840.0):
        set_compliance(page, "xyz")
        push_to(page, (x, WALL_Y_MM - 4.0, 30.0))
        set_compliance(page, "xy")
        push(page, "y", 6.0, 1.5)
        expect(page.locator("#contact")).to_have_text("contact")
        click_and_wait(page, "#guide-record", "/api/guide-points")
    set_compliance(page, "xyz")
    rows = page.locator("#guide-list tr")
    expect(rows).to_have_count(2)
    y_mm = [float(rows.nth(k).locator("td").nth(2).inner_text()) for k in range(2)]
    assert all(WALL_Y_MM - 2.0 < y < WALL_Y_MM for y in y_mm), y_mm

    # Record a third and delete it again from the list.
    click_and_wait(page, "#guide-record", "/api/guide-points")
    expect(rows).to_have_count(3)
    rows.nth(2).click()
    expect(rows.nth(2)).to_have_class(re.compile("selected"))
    click_and_wait(page, "#guide-delete", "/api/guide-points/2")
    expect(rows).to_have_count(2)
    expect(page.locator("#guide-count")).to_have_text("2")

    # Path learning along the wall between them (open path, fast: ~1 s of compute).
    page.fill("#learn-force", "10")
    page.fill("#learn-speed", "20")
    page.uncheck("#learn-closed")
    page.click("#learn-start")
    status = page.locator("#learn-status")
    expect(status).to_have_text(re.compile(r"^(done|failed|cancelled|recorded)"), timeout=90_000)
    # "done", or the recording's line that an event redraws over it right after: both say the
    # run ended and what it recorded; a failure or a cancel would say so.
    text = status.inner_text()
    assert text == "done" or text.endswith("reached the last guide point"), text
    assert page.locator("#learn-progress").evaluate("el => el.value") == 1
    expect(page.locator("#learn-start")).to_be_enabled()

    # Post-processing.
    page.fill("#post-fmin", "5")
    page.fill("#post-fmax", "15")
    page.fill("#post-tol", "0.05")
    click_and_wait(page, "#post-run", "/api/postprocess")
    # The result is drawn from the answer or from the event that follows it: wait for it.
    expect(page.locator("#post-targets")).not_to_have_text("-")
    expect(page.locator("#post-samples")).not_to_have_text("-")
    assert int(page.locator("#post-samples").inner_text()) > 500
    assert (
        0
        < int(page.locator("#post-filtered").inner_text())
        <= int(page.locator("#post-samples").inner_text())
    )
    assert int(page.locator("#post-targets").inner_text()) >= 2
    max_dev = float(page.locator("#post-max").inner_text().split()[0])
    assert 0.0 <= max_dev < 1.0  # a flat wall learned to within a millimetre

    # Export: the preview and the downloaded program.
    page.click("#export-preview")
    expect(page.locator("#rapid-preview")).to_contain_text("MODULE")
    with page.expect_download() as download:
        page.click("#export-download")
    assert download.value.suggested_filename == "program.mod"
    text = open(download.value.path(), encoding="utf-8").read()
    assert text.lstrip().startswith(("MODULE", "%%%")) or "MODULE" in text
    assert "MoveL" in text and "ENDMODULE" in text

    # Changing the guide points leaves the path and its targets marked out of date.
    expect(page.locator("#post-stale")).to_be_hidden()
    assert api.delete("/api/guide-points/1").status_code == 204
    expect(page.locator("#post-stale")).to_be_visible()
    expect(page.locator("#learn-stale")).to_be_visible()


def test_pendant_keeps_the_token_and_finds_the_scene(served: Served, page: Page) -> None:
    open_pendant(page, served)
    page.fill("#token", "not-needed-here-0123456789")
    page.locator("#token").dispatch_event("change")
    # The scene URL comes from ?viser=...; the token survives a reload (localStorage).
    page.goto(f"{served.base_url}/pendant/?viser={served.viser_url}")
    expect(page.locator("#token")).to_have_value("not-needed-here-0123456789")
    expect(page.locator("#viser-frame")).to_have_attribute("src", served.viser_url)
    expect(page.locator("#viser-link")).to_have_text(served.viser_url)


def test_pendant_numbers_start_at_the_cores_defaults(
    served: Served, api: httpx.Client, page: Page
) -> None:
    # The force, speed, floor clearance and tolerance are not typed in the page: it reads
    # them from GET /api/choices (limits.py's defaults, the one place they are written).
    ranges = api.get("/api/choices").json()["ranges"]
    open_pendant(page, served)
    for input_id, name in (
        ("learn-force", "LEARNING_FORCE_N"),
        ("learn-speed", "LEARNING_SPEED_MM_S"),
        ("learn-floor", "FLOOR_CLEARANCE_MM"),
        ("post-tol", "TOLERANCE_MM"),
        ("touch-force", "TOUCH_OFF_FORCE_N"),
        ("touch-travel", "TOUCH_OFF_TRAVEL_MM"),
        ("push-force", "PUSH_FORCE_N"),
        ("point-gap", "WALL_GAP_MM"),
        ("point-height", "MACHINING_HEIGHT_MM"),
        ("jog-step-mm", "JOG_STEP_MM"),
        ("jog-step-deg", "JOG_TURN_DEG"),
        ("jog-rate", "JOG_RATE_DEG_S"),
    ):
        default = ranges[name]["default"]
        assert default is not None, name
        expect(page.locator(f"#{input_id}")).to_have_value(re.compile(rf"^{default:g}(\.0)?$"))
    # One compensation vocabulary: the machining menu offers the core's, nothing else.
    compensation = api.get("/api/choices").json()["enums"]["compensation"]["values"]
    options = page.locator("#mach-compensation option")
    expect(options).to_have_count(len(compensation))
    assert options.evaluate_all("os => os.map((o) => o.value)") == compensation


def test_pendant_loads_the_example(served: Served, api: httpx.Client, page: Page) -> None:
    # The default cell: the water pump, whose scripted operator pushes the robot to a guide
    # point in each straight run of the groove's wall (a job of a few seconds).
    open_pendant(page, served)
    page.click("#guide-example")
    expect(page.locator("#example-progress-row")).to_be_visible()
    expect(page.locator("#example-status")).to_have_text(
        re.compile(r"^(done|failed|cancelled)"), timeout=120_000
    )
    assert page.locator("#example-status").inner_text().startswith("done")
    expect(page.locator("#guide-example")).to_be_enabled()
    assert int(page.locator("#guide-count").inner_text()) >= 8
