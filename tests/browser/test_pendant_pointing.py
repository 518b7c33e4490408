"""Teaching by pointing on the pendant page: the click mode, a typed point taught and a whole
wall proposed through REST, the proposal edited and accepted, the CAD-only program beside the
learned one; and the page's rough edges: Home, Clear all, labelled steps, the touch banner."""

from __future__ import annotations

import httpx
import numpy as np
import pytest
from playwright.sync_api import Page, expect

from tests.browser.conftest import Served, wait_for
from tests.browser.test_pendant import pose_mm

pytestmark = pytest.mark.slow

WOBJ_MM = np.array([800.0, 160.0, 0.0])


def _fill_point(page: Page, x: float, y: float, z: float) -> None:
    for axis, v in zip("xyz", (x, y, z), strict=True):
        page.fill(f"#point-{axis}", f"{v:g}")


def test_opening_the_pendant_leaves_the_sessions_pointing_settings(
    served: Served, api: httpx.Client, page: Page
) -> None:
    """The page filled its click-mode menu and announced it as the user's change: every load
    sent the menu's first option and the page's gap and height over the session's settings
    (another user's, in viser)."""
    chosen = {"click_mode": "teach", "gap_mm": 2.5, "height_above_floor_mm": 4.0}
    before = api.get("/api/guide-points/pointing").json()
    assert api.put("/api/guide-points/pointing", json=chosen).status_code == 200
    try:
        _open_and_check(served, api, page, chosen)
    finally:  # the settings are the server's, not the project's: the next test gets its own
        restored = {k: before[k] for k in chosen}
        assert api.put("/api/guide-points/pointing", json=restored).status_code == 200


def _open_and_check(served: Served, api: httpx.Client, page: Page, chosen: dict) -> None:
    sent = []
    page.on("request", lambda r: r.method != "GET" and sent.append(f"{r.method} {r.url}"))
    page.goto(f"{served.base_url}/pendant/?viser=about:blank")
    expect(page.locator("#connection")).to_have_text("online")
    expect(page.locator("#point-mode option")).not_to_have_count(0)  # the choices arrived
    # Shown from the session after the menu was filled (a GET after the filling's events).
    expect(page.locator("#point-mode")).to_have_value("teach")
    expect(page.locator("#point-gap")).to_have_value("2.5")
    assert sent == [], sent  # loading the page changes nothing
    now = api.get("/api/guide-points/pointing").json()
    assert {k: now[k] for k in chosen} == chosen


def test_pointing_from_the_pendant(served: Served, api: httpx.Client, page: Page) -> None:
    page.goto(f"{served.base_url}/pendant/?viser=about:blank")
    expect(page.locator("#connection")).to_have_text("online")
    for label in ("X/Y step", "Z step", "Turn step"):
        expect(page.get_by_label(label)).to_be_visible()

    # The click mode is the session's: viser's dropdown follows it.
    # The page also GETs this path when it refreshes: wait for the PUT's answer.
    with page.expect_response(
        lambda r: r.url.endswith("/api/guide-points/pointing") and r.request.method == "PUT"
    ):
        page.select_option("#point-mode", "teach")
    assert api.get("/api/guide-points/pointing").json()["click_mode"] == "teach"

    # A typed point on the wall: the robot goes beside it and the point is recorded.
    _fill_point(page, 40, -65, 18.5)
    with page.expect_response("**/api/guide-points/from-surface"):
        page.click("#point-teach")
    expect(page.locator("#guide-count")).to_have_text("1")
    # The pose shown comes from the page's state poll (every 200 ms): under load the count's
    # event can arrive before the poll that reads the arrived pose (it read z 17.66 once).
    beside = np.array([40.0, -63.0, 18.5])  # the typed point's height, kept
    wait_for(
        lambda: np.allclose(pose_mm(page) - WOBJ_MM, beside, atol=0.6),
        timeout_s=10,
        describe=lambda: f"the page shows {pose_mm(page) - WOBJ_MM}, not {beside}",
    )

    # A whole wall proposed: 14 points, all reachable; one deleted; accepted.
    _fill_point(page, 0, -65, 17)
    page.click("#point-propose")
    expect(page.locator("#proposal-list tr")).to_have_count(14)
    expect(page.locator("#proposal-list tr.reach-ok")).to_have_count(14)
    expect(page.locator("#point-summary")).to_contain_text("closed wall")
    page.locator("#proposal-list tr").nth(3).click()
    page.click("#proposal-delete")
    expect(page.locator("#proposal-list tr")).to_have_count(13)
    page.click("#proposal-accept")
    expect(page.locator("#guide-count")).to_have_text("13", timeout=300_000)
    expect(page.locator("#proposal-list tr")).to_have_count(0)

    # Learn and post-process from the page: both programs against the wall, in a table.
    page.click("#learn-start")
    wait_for(lambda: api.get("/api/path-learning/recording?max_points=2").json()["source"]
             == "recording", timeout_s=300)  # fmt: skip
    expect(page.locator("#learn-start")).to_be_enabled(timeout=60_000)
    page.click("#post-run")
    expect(page.locator("#compare-list tr")).to_have_count(2)
    learned = float(page.locator("#compare-list tr").nth(0).locator("td").nth(1).inner_text())
    assert learned <= 0.3
    expect(page.locator("#compare-note")).to_contain_text("the part is its mesh")

    # The touch banner goes once the point is recorded; Clear all; Home.
    page.select_option("#jog-frame", "wobj")
    with page.expect_response("**/api/leadthrough/touch-off"):
        page.click("#touch-z-minus")
    expect(page.locator("#message")).to_be_visible()
    expect(page.locator("#message-text")).to_contain_text("record the guide point")
    page.keyboard.press("g")
    expect(page.locator("#guide-count")).to_have_text("14")
    expect(page.locator("#message")).to_be_hidden()
    page.click("#guide-clear")
    expect(page.locator("#guide-count")).to_have_text("0")
    home_z = api.post("/api/leadthrough/home").json()["tcp"]["position_mm"][2]
    api.post("/api/leadthrough/jog", json={"axis": "z", "step": -20, "frame": "base"})
    with page.expect_response("**/api/leadthrough/home"):
        page.click("#jog-home")
    # The answer has arrived; the page shows it once its handler has run.
    wait_for(lambda: abs(pose_mm(page)[2] - home_z) <= 0.01, timeout_s=10)


def test_an_error_says_what_is_wrong_without_the_route(
    served: Served, api: httpx.Client, page: Page
) -> None:
    page.goto(f"{served.base_url}/pendant/?viser=about:blank")
    expect(page.locator("#connection")).to_have_text("online")
    _fill_point(page, 0, -62.5, 14)  # the groove's floor, not a wall
    page.click("#point-propose")
    expect(page.locator("#message-text")).to_contain_text("pick a point on a wall")
    text = page.locator("#message-text").inner_text()
    assert "POST" not in text and "/guide-points" not in text
