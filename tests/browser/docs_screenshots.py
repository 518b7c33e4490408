"""The screenshots of docs/workbench.md for issue 31's points 1-7, made in a real browser
(Debian's chromium) on the viser workbench over a real session, as a person would get them:

    python -m tests.browser.docs_screenshots [folder]   (default docs/images)

Each shot is what the doc says it shows; look at every one after a run. The realistic part's
seed is fresh each run (printed), so the figures in the shots vary a little.
"""

from __future__ import annotations

import math
import random
import sys
import tempfile
from pathlib import Path

import numpy as np
from playwright.sync_api import Page, expect, sync_playwright

from app.session import Session
from robomach_core import project as core
from robomach_core.cell import TOOL_DOWN, GuidePoint
from robomach_core.part import PartDeviation
from robomach_core.transforms import rotation_about
from tests.browser.conftest import CHROMIUM, CHROMIUM_ARGS, new_context, wait_for, workbench_on
from tests.browser.test_place_calibrate_learn import (
    CORNER_VIEW,
    ISLAND_WALL,
    PLACEMENT,
    PLACEMENT_LABELS,
    SIDE_X,
    SIDE_Y,
    TOP,
    _base,
    _open_folder,
    _orbit,
    _realistic_seed,
    _type,
)
from tests.browser.test_pointing import _click_at
from tests.generated_parts import cam_plate
from tests.jobs import done

VIEWPORT = {"width": 1500, "height": 900}
TIMEOUT_S = 600.0
# The pump groove's outer wall, 2.5 mm off it (work object, mm): a loop of 12 points.
PUMP_LOOP_MM = [
    (-85, -62.5), (0, -62.5), (85, -62.5), (98, -50), (98, 0), (98, 50),
    (85, 62.5), (0, 62.5), (-85, 62.5), (-98, 50), (-98, 0), (-98, -50),
]  # fmt: skip


def _page(browser, wb) -> tuple[Page, object]:
    context = new_context(browser, viewport=VIEWPORT, accept_downloads=True)
    context.set_default_timeout(120_000)
    page = context.new_page()
    page.goto(f"http://127.0.0.1:{wb.server.get_port()}")
    expect(page.get_by_text("Teach by pointing")).to_be_visible()
    wait_for(lambda: len(wb.server.get_clients()) > 0)
    client = next(iter(wb.server.get_clients().values()))
    page.wait_for_timeout(2000)
    _close_webgl_note(page)
    return page, client


def _close_webgl_note(page: Page) -> None:
    """The browser's own "software WebGL" note is not the workbench's: closed for the shots."""
    note = page.locator(".mantine-Notification-root", has_text="Software WebGL")
    if note.count():
        note.first.locator("button").click()


def _close_notes(page: Page) -> None:
    for note in page.locator(".mantine-Notification-root").all():
        note.locator("button").first.click()


def _shot(page: Page, folder: Path, name: str, show: str | None = None) -> None:
    """Scroll the panel to ``show`` (a text in it), let the scene draw, save ``name``."""
    if show is not None:
        page.get_by_text(show, exact=False).first.scroll_into_view_if_needed()
    page.wait_for_timeout(4000)  # software WebGL at two frames a second (conftest)
    page.screenshot(path=str(folder / name))
    print(f"  {folder / name}")


def _wait_jobs(session) -> None:
    wait_for(lambda: not session.jobs.active(), TIMEOUT_S)


def cam_plate_shots(browser, folder: Path) -> None:
    """1 placement, 2 calibration, 3 a click through the tool, 7 learned vs CAD-only."""
    seed = _realistic_seed(random.Random())
    part = cam_plate()
    stl = Path(tempfile.mkdtemp()) / "cam_plate.stl"
    stl.write_bytes(part.stl_bytes())
    with workbench_on(Session(real_time=False)) as wb:
        session = wb.session
        session.set_cell(part_deviation=PartDeviation.realistic(seed))
        print(f"cam plate, realistic seed {seed}")
        page, client = _page(browser, wb)
        with page.expect_file_chooser() as chooser:
            page.get_by_role("button", name="Upload mesh (STL/OBJ/PLY, mm)").click()
        chooser.value.set_files(str(stl))
        wait_for(lambda: session.robot.workpiece.cad().name == "cam_plate", TIMEOUT_S)
        expect(page.get_by_text("cam_plate.stl is the workpiece")).to_be_visible()
        _close_notes(page)
        _open_folder(page, "Place the part")
        for k, label in enumerate(PLACEMENT_LABELS):
            if abs(session.preview.placed()[k] - PLACEMENT[k]) > 1e-6:
                _type(page, label, PLACEMENT[k])
        wait_for(lambda: "Trying the numbers" in wb.placement.note.content, 60)
        wb.pointing._view_part(client)  # what View the part does
        _shot(page, folder, "workbench-placement.png", show="Put it back")

        page.get_by_role("button", name="Place the part here").click()
        wait_for(lambda: session.project().cell.wobj_mm_deg == PLACEMENT, 60)
        _open_folder(page, "Calibrate by touch")
        page.get_by_role("button", name="Touch faces").click()
        wait_for(lambda: session.pointing.click_mode == "touch", 60)
        _orbit(client, session, **CORNER_VIEW)
        for (point, _normal), touches in zip((TOP, SIDE_Y, SIDE_X), (4, 7, 9), strict=True):
            _click_at(page, client, _base(session, point))
            wait_for(lambda n=touches: len(session.calibration.state().touches) == n, TIMEOUT_S)
        wait_for(lambda: "**Fit**" in wb.calibration.fit.content, 60)
        _shot(page, folder, "workbench-calibration.png", show="Back to the placement")
        page.get_by_role("button", name="Accept the calibration").click()
        wait_for(lambda: session.pointing.click_mode == "propose", 60)

        # 3. The tool over the island wall, the camera looking past the spindle at the wall.
        T = session.robot.workpiece.cad().T_base_wobj
        over = np.eye(4)
        over[:3, :3] = T[:3, :3] @ TOOL_DOWN
        over[:3, 3] = _base(session, (ISLAND_WALL[0] + 8.0, -52.0, 30.0))
        session.teach.move_to(over, safe_z_m=T[2, 3] + 0.05)
        _orbit(client, session, look_at_mm=ISLAND_WALL, direction=(0.15, -0.55, 1.0),
               distance_m=0.16)  # fmt: skip
        _click_at(page, client, _base(session, ISLAND_WALL))
        wait_for(lambda: session.pointing.proposal() is not None, TIMEOUT_S)
        _shot(page, folder, "workbench-click-through.png", show="Accept proposal")

        page.get_by_role("button", name="Accept proposal").click()
        wait_for(lambda: session.pointing.proposal() is None, TIMEOUT_S)
        _wait_jobs(session)
        page.get_by_role("button", name="Run path learning").click()
        wait_for(lambda: session.project().recording is not None, TIMEOUT_S)
        _wait_jobs(session)
        page.get_by_role("button", name="Run post-processing").click()
        wait_for(lambda: "What learning buys" in wb.pointing.compare.content, TIMEOUT_S)
        _close_notes(page)
        _orbit(client, session, look_at_mm=(40.0, -49.0, 14.0), direction=(0.1, -0.9, 1.2),
               distance_m=0.2)  # fmt: skip
        _shot(page, folder, "workbench-learned-vs-cad.png", show="Show the CAD-only program")


def _wound_loop(session, turns: int) -> list[GuidePoint]:
    """Guide points round the pump's groove with the tool turned ``turns`` times about its
    axis round the loop (each facing the wall turns it once), joints solved from the last as a
    person jogging it there."""
    cell = session.robot.cell
    T_wobj = cell.workpiece.cad().T_base_wobj
    guides, q = [], cell.robot.home_rad
    for x, y in PUMP_LOOP_MM:
        T = np.eye(4)
        T[:3, :3] = T_wobj[:3, :3] @ TOOL_DOWN @ rotation_about("z", -turns * math.atan2(y, x))
        T[:3, 3] = T_wobj[:3, :3] @ np.array([x, y, 17.0]) * 1e-3 + T_wobj[:3, 3]
        q_new = cell.robot.ik(T, q)
        q_new[5] = q[5] + math.remainder(q_new[5] - q[5], 2 * math.pi)
        q = np.clip(q_new, cell.robot.lower_rad, cell.robot.upper_rad)
        guides.append(GuidePoint(T, q.copy(), 0.0))
    return guides


def _set_guides(session, guides) -> None:
    session.commit(lambda p: core.with_guide_points(p, guides), "guides", topics=("guide_points",))


def pump_shots(browser, folder: Path) -> None:
    """4 and 6 the check before the run (severities, wall side, axis 6), 5 a cell change."""
    with workbench_on(Session(real_time=False)) as wb:
        session = wb.session
        page, client = _page(browser, wb)
        guides = _wound_loop(session, turns=2)  # facing the wall twice round: axis 6 runs out
        _set_guides(session, guides)
        wait_for(lambda: "axis 6" in wb.path_learning.check.content, 120)
        wb.pointing._view_part(client)
        _shot(page, folder, "workbench-check.png", show="Run path learning")

        # 5. Learned and compared on the pump with a machining choice, then another arm.
        _set_guides(session, ())
        job = session.learning.start_example()
        done(session, job, TIMEOUT_S)
        job = session.learning.start_path_learning(10.0, 0.005)
        done(session, job, TIMEOUT_S)
        session.learning.run_postprocess()
        wait_for(lambda: "What learning buys" in wb.pointing.compare.content, TIMEOUT_S)
        session.commit(lambda p: core.choose(p, "fuzzy", "off"), "post", topics=("machining",))
        wb.pointing._view_part(client)
        page.wait_for_timeout(3000)
        _close_notes(page)
        page.screenshot(path=str(folder / "workbench-before-cell-change.png"))
        page.get_by_label("Robot", exact=True).click()
        page.get_by_role("option", name="kr270").click()
        page.get_by_role("button", name="Apply cell").click()
        wait_for(lambda: session.project().cell.robot == "kr270", TIMEOUT_S)
        wait_for(lambda: wb.scene.paths.hidden, 60)
        _shot(page, folder, "workbench-cell-change.png", show="Apply cell")


def pendant_shot(browser, folder: Path) -> None:
    """4 the pendant (a real ``robomach serve``): the same check, in the same words, with the
    wall side; the Work object card beside it."""
    import httpx

    from tests.api.server_process import start_server

    server = start_server(
        Path(tempfile.mkdtemp()) / "data", env={"ROBOMACH_REAL_TIME": "0"}, start_timeout_s=120
    )
    try:
        api = httpx.Client(base_url=server.base_url, timeout=120.0)
        assert api.post("/api/projects", json={"name": "pendant-shot"}).status_code == 201
        job = api.post("/api/guide-points/example").json()["job_id"]
        wait_for(lambda: api.get(f"/api/jobs/{job}").json()["status"] == "done", TIMEOUT_S)
        context = new_context(browser, viewport={"width": 1500, "height": 1000})
        context.set_default_timeout(120_000)
        page = context.new_page()
        page.goto(f"{server.base_url}/pendant/?viser={server.viser_url}")
        page.select_option("#learn-wall-side", "left")  # against the example's pushes
        expect(page.locator("#learn-warnings li").first).to_be_visible()
        page.locator("#learn-card").scroll_into_view_if_needed()
        page.wait_for_timeout(8000)  # the 3D scene beside it (software WebGL)
        page.screenshot(path=str(folder / "pendant-check.png"))
        print(f"  {folder / 'pendant-check.png'}")
        api.close()
    finally:
        server.stop(kill_on_timeout=True)


def main() -> None:
    folder = Path(sys.argv[1] if len(sys.argv) > 1 else "docs/images")
    folder.mkdir(parents=True, exist_ok=True)
    # a page's text comes after the session's work (a route planned, a mesh loaded): on a
    # loaded machine that takes longer than Playwright's 5 s default
    expect.set_options(timeout=60_000)
    with sync_playwright() as p:
        browser = p.chromium.launch(executable_path=str(CHROMIUM), args=CHROMIUM_ARGS)
        try:
            which = sys.argv[2:] or ["cam", "pump", "pendant"]
            if "cam" in which:
                cam_plate_shots(browser, folder)
            if "pump" in which:
                pump_shots(browser, folder)
            if "pendant" in which:
                pendant_shot(browser, folder)
        finally:
            browser.close()


if __name__ == "__main__":
    main()
