"""The Machining section of the pendant page in a real browser, and the viser Machining panel
in-process: a comparison shows its table, a run its plots and scene, and a change of the guide
points marks the result out of date in the panel."""

from __future__ import annotations

from collections.abc import Iterator

import pytest
from playwright.sync_api import expect

from tests.api.server_process import Api
from tests.browser.conftest import Served, wait_for, workbench_on
from tests.demo_project import block_demo_dir

pytestmark = pytest.mark.slow

COMPARE_TIMEOUT_MS = 600_000
RUN_TIMEOUT_S = 300.0  # an in-process machining run on the block


def test_the_pendant_compares_and_chooses(served: Served, browser) -> None:
    api = Api(served.base_url)
    api.new_project()
    api.learn()
    api.ok("POST", "/api/postprocess", json={"tolerance_mm": 0.05})
    context = browser.new_context(viewport={"width": 1400, "height": 1400})
    page = context.new_page()
    try:
        page.goto(f"{served.base_url}/pendant/")
        expect(page.locator("#machining-card")).to_be_visible()
        expect(page.locator("#mach-controller")).to_have_value("adaptive-pi")
        page.click("#mach-compare")
        rows = page.locator("#mach-comparison tbody tr")
        expect(rows).to_have_count(18, timeout=COMPARE_TIMEOUT_MS)
        expect(page.locator("#mach-status")).to_have_text("done")
        assert "constant" in rows.nth(0).inner_text()
        expect(page.locator("#mach-comparison tr.chosen")).to_have_count(1)
        page.select_option("#mach-pick", "fuzzy/offline")
        with page.expect_response("**/api/machining/choice"):
            page.click("#mach-choose")
        expect(page.locator("#mach-chosen")).to_have_text("chosen: fuzzy / offline")
        settings = api.ok("GET", "/api/machining/settings")
        assert (settings["controller"], settings["compensation"]) == ("fuzzy", "offline")
        assert "CMRR: fuzzy" in api.get("/api/export/rapid").text
        # The plot drew something (a canvas that is not blank; it may draw after the table).
        page.wait_for_function(
            "() => { const c = document.getElementById('mach-plot');"
            " const d = c.getContext('2d').getImageData(0, 0, c.width, c.height).data;"
            " return !d.every((v) => v === 0); }",
            timeout=10_000,
        )
    finally:
        context.close()
        api.cancel_all()
        api.http.close()


@pytest.fixture
def workbench() -> Iterator:
    from app.session import Session
    from app.session.project_file import import_project

    session = Session()
    data = (block_demo_dir() / "project.npz").read_bytes()
    import_project(session, data, "block demo")
    with workbench_on(session) as wb:
        yield wb


def test_the_viser_panel_shows_a_run_and_goes_out_of_date(workbench) -> None:
    from app.gui.panels.machining import MachiningPanel

    (panel,) = [p for p in workbench.studies if isinstance(p, MachiningPanel)]
    session = workbench.session
    wait_for(
        lambda: "No machining result yet" in panel.status.content,
        timeout_s=RUN_TIMEOUT_S,
    )
    panel.service.choose("fuzzy", "off")  # e.g. from the REST API: the panel mirrors it
    wait_for(lambda: panel.controller.value == "fuzzy", timeout_s=30.0)
    panel._start("run")
    wait_for(lambda: "fuzzy" in panel.table.content, timeout_s=RUN_TIMEOUT_S)
    assert "Rule's pick" in panel.table.content
    wait_for(lambda: len(panel.force_plot.data[0]) > 100, timeout_s=RUN_TIMEOUT_S)
    x, force, _, reference, limit = panel.force_plot.data
    assert limit[0] == 150.0 and reference[0] == pytest.approx(105.0)
    assert force.max() > 0.5 * reference[0]
    # The scene is drawn after the plots, in the same refresh: wait for it too.
    wait_for(lambda: set(panel._nodes) == {"stock", "wall"}, timeout_s=30.0)

    session.delete_guide_point(0)
    wait_for(lambda: "Out of date" in panel.status.content, timeout_s=RUN_TIMEOUT_S)
    assert session.status()["machining"] == "stale"
