"""A real browser opens the workbench under a name that resolves to 127.0.0.1 (DNS rebinding)
and gets no workbench (issue 19, R8: such a page recorded guide points through viser with no
token). Chromium's ``--host-resolver-rules`` maps the name to 127.0.0.1, as a rebinding DNS
server would; the pages are the server's own (viser's page, the pendant)."""

from __future__ import annotations

from collections.abc import Iterator
from urllib.parse import urlsplit

import httpx
import pytest
from playwright.sync_api import expect

from tests.browser.conftest import CHROMIUM, TEST_CHROMIUM_ARGS, Served, new_context, wait_for

pytestmark = pytest.mark.slow

REBOUND = "rebound.test"


@pytest.fixture(scope="module")
def rebinding_browser(browser) -> Iterator:
    """A second chromium, from the shared one's Playwright, resolving ``rebound.test`` to
    127.0.0.1."""
    b = browser.browser_type.launch(
        executable_path=str(CHROMIUM),
        args=[*TEST_CHROMIUM_ARGS, f"--host-resolver-rules=MAP {REBOUND} 127.0.0.1"],
    )
    yield b
    b.close()


def test_the_viser_scene_under_a_rebound_name_never_connects(
    served: Served, api: httpx.Client, rebinding_browser
) -> None:
    before = api.get("/api/guide-points").json()
    port = urlsplit(served.viser_url).port
    context = new_context(rebinding_browser)
    page = context.new_page()
    refusal = f"refused a websocket from host '{REBOUND}:{port}'"
    refused_before = served.log().count(refusal)
    page.goto(f"http://{REBOUND}:{port}/")
    # viser's page retries its websocket: a retry refused too shows the refusal is not a fluke.
    wait_for(
        lambda: served.log().count(refusal) >= refused_before + 2,
        timeout_s=30,
        describe=lambda: f"{served.log().count(refusal) - refused_before} refusals",
    )
    assert page.get_by_text("Lead-through").count() == 0  # the workbench's panels never came
    assert page.get_by_role("button", name="Record guide point").count() == 0
    context.close()
    assert api.get("/api/guide-points").json() == before
    # The same browser under a loopback name gets the workbench: the refusal is the name's.
    context = new_context(rebinding_browser)
    page = context.new_page()
    page.goto(f"http://127.0.0.1:{port}/")
    expect(page.get_by_text("Lead-through")).to_be_visible()
    context.close()


def test_the_pendant_under_a_rebound_name_is_refused(served: Served, rebinding_browser) -> None:
    port = urlsplit(served.base_url).port
    context = new_context(rebinding_browser)
    page = context.new_page()
    response = page.goto(f"http://{REBOUND}:{port}/pendant/")
    assert response is not None and response.status == 403
    assert "loopback only" in page.content()
    # the page's own script, same origin with its name, reads the customer's project file
    status = page.evaluate("fetch('/api/projects/current/project.npz').then((r) => r.status)")
    assert status == 403
    context.close()
