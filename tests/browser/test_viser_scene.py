"""The viser workbench: the browser draws the robot and follows it; the spring handle pushes;
the panels follow changes made through the session (as the REST API makes them)."""

from __future__ import annotations

import io
import time
from collections.abc import Iterator

import httpx
import numpy as np
import pytest
from PIL import Image
from playwright.sync_api import Page, expect

from tests.browser.conftest import (
    Served,
    box_of,
    frames_drawn,
    new_context,
    wait_for,
    workbench_on,
)
from tests.jobs import done

pytestmark = pytest.mark.slow

SETTLE_TIMEOUT_S = 60.0  # the scene fades in over a few seconds under SwiftShader
SCENE_VIEWPORT = {"width": 1200, "height": 720}  # software rendering: fewer pixels, faster


def canvas_pixels(page: Page) -> np.ndarray:
    """(h, w, 3) int pixels of the 3D canvas (a page screenshot clipped to it: an element
    screenshot waits for the always-animating canvas to be "stable")."""
    box = box_of(page.locator("canvas").first)
    assert box["width"] > 0 and box["height"] > 0, "no canvas on the page"
    png = page.screenshot(clip=box)
    return np.asarray(Image.open(io.BytesIO(png)).convert("RGB"), dtype=int)


def changed_fraction(a: np.ndarray, b: np.ndarray, threshold: int = 40) -> float:
    return float((np.abs(a - b).sum(axis=-1) > threshold).mean())


def settled_canvas(page: Page) -> np.ndarray:
    """The canvas once two screenshots a second apart (nearly) agree."""
    deadline = time.monotonic() + SETTLE_TIMEOUT_S
    last = canvas_pixels(page)
    while time.monotonic() < deadline:
        page.wait_for_timeout(1000)
        now = canvas_pixels(page)
        if changed_fraction(last, now) < 0.002:
            return now
        last = now
    return last


def test_viser_page_draws_the_robot(served: Served, api: httpx.Client, browser) -> None:
    context = new_context(browser, viewport=SCENE_VIEWPORT)
    context.set_default_timeout(60_000)
    page = context.new_page()
    page.goto(served.viser_url)
    expect(page.get_by_text("Connected")).to_be_visible()
    expect(page.get_by_text("Lead-through")).to_be_visible()  # the workbench's panels
    before = settled_canvas(page)
    background = np.array([255, 255, 255])
    drawn = float((np.abs(before - background).sum(axis=-1) > 30).mean())
    assert drawn > 0.05, f"the scene is blank ({drawn:.1%} of the canvas drawn)"

    # Lower the tool by ~19 cm, into the camera's view: the arm must move on screen.
    r = api.post("/api/leadthrough/push", json={"force_N": [0, 0, -25], "duration_s": 4.0})
    assert r.status_code == 200, r.text
    moved = 0.0
    deadline = time.monotonic() + SETTLE_TIMEOUT_S
    while moved <= 0.005 and time.monotonic() < deadline:
        frames_drawn(page, 1)  # the page's next frame (two a second: conftest)
        moved = max(moved, changed_fraction(before, canvas_pixels(page)))
    assert moved > 0.005, f"the robot did not move on screen ({moved:.2%} of the pixels changed)"
    context.close()


# --- the workbench in-process: spring handle and panels, no browser needed ------------------


@pytest.fixture
def workbench() -> Iterator:
    from app.session import Session

    with workbench_on(Session()) as wb:
        yield wb


def test_spring_handle_pushes_the_robot(workbench) -> None:
    session, lead = workbench.session, workbench.leadthrough
    p0 = session.robot.snapshot().position_m.copy()
    lead.spring.value = 2.0  # N/mm: 20 mm of offset push 40 N, the robot follows in ~1 s
    frames = workbench.frames_drawn
    workbench.scene.handle.position = p0 + np.array([0.0, 0.0, 0.020])
    lead.arm()
    wait_for(lambda: session.robot.snapshot().position_m[2] - p0[2] > 0.005)
    assert workbench.frames_drawn > frames
    assert lead.push_N is not None and lead.push_N[2] > 0
    # The robot stops at the handle (within the admittance's 1 N deadband: 0.5 mm at 2 N/mm).
    wait_for(lambda: abs(session.robot.snapshot().position_m[2] - (p0[2] + 0.020)) < 0.002)
    np.testing.assert_allclose(session.robot.snapshot().position_m[:2], p0[:2], atol=5e-4)

    # A move the spring did not make (a jog, an API push) releases the handle onto the tool.
    session.teach.jog("z", 0.005)
    wait_for(lambda: lead.push_N is None)
    wait_for(
        lambda: np.allclose(
            workbench.scene.handle.position, session.robot.snapshot().position_m, atol=1e-6
        )
    )


def test_a_drag_is_not_undone_before_it_arms(workbench) -> None:
    """viser sets the handle's position, then calls ``arm``: a scene tick in between, with the
    robot standing still, must leave the dragged handle where the user put it (it used to put
    it back on the tool, and the drag then pushed nothing)."""
    session, lead = workbench.session, workbench.leadthrough
    p0 = session.robot.snapshot().position_m.copy()
    dragged = p0 + np.array([0.0, 0.0, 0.020])
    workbench.scene.handle.position = dragged
    lead.tick(session.robot.snapshot())
    np.testing.assert_allclose(workbench.scene.handle.position, dragged, atol=1e-9)


def test_panels_follow_session_changes(workbench) -> None:
    session = workbench.session
    session.record_guide_point()
    wait_for(lambda: "G1" in workbench.guide_points.selected.options)
    assert "G1" in workbench.guide_points.table.content
    session.robot.select(["z", "rx"], "tool")
    # the panel sets its widgets one after the other: wait for the last of them
    wait_for(lambda: workbench.leadthrough.frame.value == "tool")
    assert workbench.leadthrough.axes["rx"].value
    assert not workbench.leadthrough.axes["x"].value
    session.clear_guide_points()
    wait_for(lambda: workbench.guide_points.selected.options == ("none",))
    session.set_cell(workpiece="block")
    wait_for(lambda: "block" in workbench.cell.info.content)
    assert workbench.cell.workpiece.value == "block"

    # An uploaded mesh (mm) joins the workpiece choices; it has no true wall to score against.
    import trimesh

    stl = trimesh.creation.box(extents=(120.0, 80.0, 30.0)).export(file_type="stl")
    session.upload_workpiece(stl, "bracket.stl")
    # The panel fills the choices, then chooses: wait for both (the full suite once read the
    # value between the two).
    wait_for(
        lambda: (
            "bracket" in workbench.cell.workpiece.options
            and workbench.cell.workpiece.value == "bracket"
        ),
        describe=lambda: f"{workbench.cell.workpiece.value} of {workbench.cell.workpiece.options}",
    )
    assert "no ground truth" in workbench.cell.info.content


def test_the_pose_readout_shows_where_the_robot_stopped(workbench) -> None:
    """Two jogs back to back: the second ends inside the readout's 10 Hz limit, and the
    readout still catches up with the robot once it stands."""
    session = workbench.session
    for _ in range(2):
        session.teach.jog("z", 0.004, frame="base")
    stopped_mm = session.robot.snapshot().position_m * 1e3
    row = f"| mm | {stopped_mm[0]:.2f} | {stopped_mm[1]:.2f} | {stopped_mm[2]:.2f} |"
    wait_for(lambda: row in workbench.leadthrough.pose.content)


def test_the_wall_to_follow_is_shown_before_the_run_and_the_side_is_checked(workbench) -> None:
    """After the example's lead-through, the path-learning panel says which wall the run
    will follow and why (the pushes), and the scene highlights it; set to the other side, the
    rules panel says every point is nearer the wall on the right."""
    session = workbench.session
    job = session.learning.start_example()
    done(session, job, 180.0)
    panel = workbench.path_learning
    wait_for(lambda: "follows the wall on the right" in panel.wall_note.content)
    assert "pushed back from the right" in panel.wall_note.content
    panel.wall_side.value = "left"
    wait_for(lambda: "nearer the wall on the right" in workbench.guide_rules.warnings.content)
    wait_for(lambda: "follows the wall on the left" in panel.wall_note.content)
    panel.wall_side.value = "auto"
    wait_for(lambda: "follows the wall on the right" in panel.wall_note.content)
    panel.refresh_stop()  # no recording yet: no stop marker (and no error drawing it)
