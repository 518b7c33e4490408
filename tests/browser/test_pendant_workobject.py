"""The pendant's Work object card on a real ``robomach serve`` (issue 31, points 1 and 2): the
numbers typed are tried (the scene's preview, nothing applied) and placed, as ``PUT /api/cell``
would; on the realistic part, *Touch faces* then *Touch the planned features* touches the
part, the touches are listed with their residuals, and *Accept* calibrates the work object
(the mark shows) and puts the click back to proposing; then a wall proposed, learned and
post-processed from the page: the comparison has the CAD-only program as placed beside the
calibrated one, off by about the fixture error (a few mm), the learned within 0.3 mm plus the
casting's burrs."""

from __future__ import annotations

import random

import httpx
import pytest
from playwright.sync_api import Page, expect

from tests.browser.conftest import Served, wait_for

pytestmark = pytest.mark.slow


def test_the_pendant_places_the_part_and_calibrates_it_by_touch(
    served: Served, api: httpx.Client, page: Page
) -> None:
    rng = random.Random()
    seed = rng.randrange(2**32)
    rng.seed(seed)
    x, y, rz = 800.0 + rng.uniform(-30, 30), 160.0 + rng.uniform(-30, 30), rng.uniform(-30, 30)
    context = f"seed {seed}: the pump placed at ({x:.1f}, {y:.1f}) mm turned {rz:.1f} deg"
    assert api.put("/api/cell", json={"realistic": True}).status_code == 200
    page.goto(f"{served.base_url}/pendant/?viser=about:blank")
    expect(page.locator("#wobj-x")).to_have_value("800")
    for field, value in (("x", x), ("y", y), ("rz", rz)):
        page.locator(f"#wobj-{field}").fill(f"{value:.1f}")
    expect(page.locator("#wobj-note")).to_contain_text("Trying the numbers above")
    tried = [round(x, 1), round(y, 1), 0.0, 0.0, 0.0, round(rz, 1)]
    wait_for(  # the scene follows once the keys pause
        lambda: (
            api.get("/api/cell/placement-preview").json()["wobj_mm_deg"] == pytest.approx(tried)
        ),
        describe=lambda: f"{context}: {api.get('/api/cell/placement-preview').json()}",
    )
    assert api.get("/api/cell").json()["wobj_mm_deg"] is None  # tried, not applied
    page.locator("#wobj-place").click()
    wait_for(
        lambda: api.get("/api/cell").json()["wobj_mm_deg"] == pytest.approx(tried),
        describe=lambda: f"{context}: {api.get('/api/cell').json()['wobj_mm_deg']}",
    )
    expect(page.locator("#wobj-place")).to_be_disabled()

    page.locator("#calib-mode").click()
    wait_for(lambda: api.get("/api/guide-points/pointing").json()["click_mode"] == "touch")
    page.locator("#calib-auto").click()
    expect(page.locator("#calib-list tr")).to_have_count(9, timeout=300_000)
    expect(page.locator("#calib-fit")).to_contain_text("Fit:")
    expect(page.locator("#calib-accept")).to_be_enabled()
    page.locator("#calib-accept").click()
    expect(page.locator("#wobj-calibrated")).to_be_visible()
    registration = api.get("/api/cell").json()["registration"]
    assert registration is not None, context
    wait_for(lambda: api.get("/api/guide-points/pointing").json()["click_mode"] == "propose")
    expect(page.locator("#calib-remove")).to_be_enabled()

    # Propose the groove's outer wall on the calibrated CAD, learn, post-process.
    for field, value in (("x", 0), ("y", -65), ("z", 17)):
        page.locator(f"#point-{field}").fill(str(value))
    page.click("#point-propose")
    expect(page.locator("#proposal-list tr").first).to_be_visible(timeout=120_000)
    page.click("#proposal-accept")
    expect(page.locator("#proposal-list tr")).to_have_count(0, timeout=300_000)
    expect(page.locator("#learn-start")).to_be_enabled(timeout=300_000)
    page.click("#learn-start")
    wait_for(lambda: api.get("/api/path-learning/recording?max_points=2").json()["source"]
             == "recording", timeout_s=600)  # fmt: skip
    expect(page.locator("#learn-start")).to_be_enabled(timeout=120_000)
    page.click("#post-run")
    rows = page.locator("#compare-list tr")
    expect(rows).to_have_count(3, timeout=120_000)
    expect(rows.nth(2)).to_contain_text("as placed (not calibrated)")
    figure = [float(rows.nth(k).locator("td").nth(1).inner_text()) for k in range(3)]
    print(f"{context}: learned {figure[0]} mm, CAD-only {figure[1]}, as placed {figure[2]}")
    assert figure[0] <= 0.4, context  # 0.3 mm and the 0.1 mm burrs
    assert figure[2] > 1.0, context  # the fixture's 2-4 mm move of the wall, not calibrated
