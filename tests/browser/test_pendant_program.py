"""The pendant's issue-11 parts: the guide-point hint, the arcs option, the program download in
the arm's languages (from the server's language registry) and the mesh score, on the real
page."""

from __future__ import annotations

import httpx
import pytest
from playwright.sync_api import Page, expect

from robomach_core.choices import TEXTS
from tests.browser.conftest import Served

pytestmark = pytest.mark.slow


def test_pendant_hint_arcs_and_urscript(served: Served, api: httpx.Client, page: Page) -> None:
    assert api.post("/api/projects", json={"name": "pendant-program"}).status_code == 201
    page.goto(f"{served.base_url}/pendant/?viser=about:blank")
    expect(page.locator("#connection")).to_have_text("online")
    # The one advice every page gives (choices.TEXTS; it said "bracket each corner" here).
    expect(page.locator("#guide-hint")).to_have_text(TEXTS["guide_point_advice"])
    expect(page.locator("#post-arcs")).not_to_be_checked()
    # The UR10 is offered its languages only, URScript among them (GET /api/export/languages).
    expect(page.locator("#export-language option")).to_have_count(2)
    page.select_option("#export-language", "urscript")
    expect(page.locator("#export-download")).to_have_text("Download program.script")
    # Nothing learned yet: the download says why instead of saving an empty file.
    page.click("#export-download")
    expect(page.locator("#message-text")).to_contain_text("path learning")
    page.click("#message-close")
    # Arcs ride in the post-processing request; the server refuses it for the same reason.
    page.check("#post-arcs")
    with page.expect_request(lambda r: r.url.endswith("/api/postprocess")) as request:
        page.click("#post-run")
    assert request.value.post_data_json["arcs"] is True
