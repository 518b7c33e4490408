"""Teaching by pointing in a real browser (viser's scene, headless chromium): click the pump's
wall to teach each point, propose the guide points for its groove with one click, and the same
for an uploaded mesh; each then learns and post-processes within 0.3 mm.

The clicks land on the wall through viser's own picking: the test points the camera at the
wall (the user's orbit, counted as an action) and clicks where the camera projects a wall point.
Per point the actions and the seconds from the click to the recorded point are printed (``-s``);
the session is unpaced, so a person's wait is measured by benchmarks/bench_pointing.py.
"""

from __future__ import annotations

import time
from collections.abc import Iterator

import numpy as np
import pytest
from playwright.sync_api import Page, expect

from robomach_core.transforms import matrix_from_quaternion
from tests.browser.conftest import (
    box_of,
    drawn_whole,
    frames_drawn,
    new_context,
    wait_for,
    workbench_on,
)
from tests.generated_parts import grooved_plate
from tests.jobs import done

pytestmark = pytest.mark.slow

VIEWPORT = {"width": 1400, "height": 900}
MAX_ACTIONS_PER_POINT = 2
# The session is unpaced: what a person waits from a click to its recorded point (the paced
# motion) is measured by benchmarks/bench_pointing.py. This bound only catches a click that
# hangs.
CLICK_HANG_S = 30.0
MAX_DEVIATION_MM = 0.3
CAMERA_DISTANCE_M = 0.11
# The pump groove's outer wall, on each straight run the example operator uses (work object,
# mm; the wall's foot at mid-depth and its normal into the groove), in the wall's direction.
PUMP_WALL_POINTS = [
    ((-84.0, -65.0), (0, 1)), ((-40.0, -65.0), (0, 1)), ((0.0, -65.0), (0, 1)),
    ((40.0, -65.0), (0, 1)), ((84.0, -65.0), (0, 1)), ((100.0, -52.7), (-1, 0)),
    ((100.0, 52.7), (-1, 0)), ((84.0, 65.0), (0, -1)), ((40.0, 65.0), (0, -1)),
    ((0.0, 65.0), (0, -1)), ((-40.0, 65.0), (0, -1)), ((-84.0, 65.0), (0, -1)),
    ((-100.0, 52.7), (1, 0)), ((-100.0, -52.7), (1, 0)),
]  # fmt: skip
WALL_MID_Z_MM = 17.5


class Actions:
    """The user's actions, counted."""

    def __init__(self) -> None:
        self.count = 0


@pytest.fixture
def workbench() -> Iterator:
    """The workbench in process over an unpaced session: the clicks, the points they record and
    what they learn are the subject here; the wall-clock wait is benchmarks/bench_pointing.py's."""
    from app.session import Session

    with workbench_on(Session(real_time=False)) as wb:
        yield wb


def _open(browser, workbench) -> tuple[Page, object]:
    context = new_context(browser, viewport=VIEWPORT)  # closed after the test (conftest)
    context.set_default_timeout(60_000)
    page = context.new_page()
    page.goto(f"http://127.0.0.1:{workbench.server.get_port()}")
    expect(page.get_by_text("Teach by pointing")).to_be_visible()
    wait_for(lambda: len(workbench.server.get_clients()) > 0)
    client = next(iter(workbench.server.get_clients().values()))
    # The push handle's gizmo sits on the tool and takes the clicks near it: hidden (the
    # default). The scene came with the page; the first orbit waits for the browser to draw.
    expect(page.get_by_label("Show push handle")).not_to_be_checked()
    assert not workbench.leadthrough.show_handle.value
    return page, client


def _look_at_wall(client, workbench, xy_mm, normal_xy, z_mm=WALL_MID_Z_MM) -> np.ndarray:
    """Orbit the camera to look at a wall point from the free side and above: the user's
    action before a click. Returns the point in the base frame."""
    T = workbench.session.robot.workpiece.cad().T_base_wobj
    p = T[:3, :3] @ np.array([xy_mm[0], xy_mm[1], z_mm]) * 1e-3 + T[:3, 3]
    n = T[:3, :3] @ np.array([normal_xy[0], normal_xy[1], 0.0])
    eye = p + CAMERA_DISTANCE_M * (0.55 * n + 0.83 * np.array([0.0, 0.0, 1.0]))
    with client.atomic():
        client.camera.up_direction = (0.0, 0.0, 1.0)
        client.camera.position = tuple(eye)
        client.camera.look_at = tuple(p)
    # The setters stamp the camera themselves: the orbit is done when the browser reports this
    # camera back after that (it has drawn the new view). A late report of the previous orbit
    # does not count: a click then would pick through the previous view.
    sent = client.camera.update_timestamp
    wait_for(
        lambda: (
            client.camera.update_timestamp > sent
            and np.linalg.norm(np.asarray(client.camera.position) - eye) < 1e-4
        ),
        timeout_s=30,
        describe=lambda: f"camera at {client.camera.position}, not {eye}",
    )
    return p


def _click_at(page: Page, client, p_base: np.ndarray) -> None:
    """Click where the camera shows ``p_base`` (viser's camera: OpenCV axes, +z forward)."""
    cam = client.camera
    R = matrix_from_quaternion(np.asarray(cam.wxyz))
    pc = R.T @ (np.asarray(p_base) - np.asarray(cam.position))
    W, H = cam.image_width, cam.image_height
    f = 0.5 * H / np.tan(0.5 * cam.fov)
    box = box_of(page.locator("canvas").first)
    u = (W / 2 + f * pc[0] / pc[2]) * box["width"] / W
    v = (H / 2 + f * pc[1] / pc[2]) * box["height"] / H
    page.mouse.click(box["x"] + u, box["y"] + v)


def _choose_mode(page: Page, mode: str) -> None:
    page.get_by_label("Click on the part").click()  # viser's dropdown: a select box
    page.get_by_role("option", name=mode).click()


def _learn_and_postprocess(page: Page, workbench) -> float:
    """Run path learning and post-processing from the page; the program's max deviation
    from the (true) wall, mm."""
    session = workbench.session
    learned_before = session.project().recording
    wait_for(lambda: not session.jobs.active(), 300)  # the accepted points' moves have ended
    page.get_by_role("button", name="Run path learning").click()
    wait_for(
        lambda: session.project().recording is not learned_before and not session.robot.busy(),
        300,
        describe=lambda: f"jobs {[(j.kind, j.status, j.error) for j in session.jobs.list()]}",
    )
    rec = session.project().recording
    assert rec.completed, rec.stop_reason
    page.get_by_role("button", name="Run post-processing").click()
    wait_for(lambda: session.project().status()["postprocess"] == "current", 120)
    outcome = session.project().processed
    comparison = outcome.cad_comparison
    assert comparison is not None
    return max(comparison.learned.max_m, outcome.score.max_m if outcome.score else 0.0) * 1e3


def test_click_to_teach_the_pump_then_learn_within_a_third_of_a_mm(browser, workbench):
    page, client = _open(browser, workbench)
    session = workbench.session
    _choose_mode(page, "teach a point")  # once, before the points
    timings = []
    for k, (xy, normal) in enumerate(PUMP_WALL_POINTS):
        actions = Actions()
        p = _look_at_wall(client, workbench, xy, normal)
        actions.count += 1
        started = time.monotonic()
        _click_at(page, client, p)
        actions.count += 1
        wait_for(lambda k=k: len(session.project().guide_points) == k + 1, timeout_s=30)
        seconds = time.monotonic() - started
        timings.append(seconds)
        print(f"G{k + 1}: {actions.count} actions, {seconds:.1f} s "
              f"(server {workbench.pointing.last_click_s:.1f} s)")  # fmt: skip
        assert actions.count <= MAX_ACTIONS_PER_POINT
        assert seconds <= CLICK_HANG_S, f"G{k + 1} took {seconds:.1f} s"
    guides = list(session.project().guide_points)
    T = session.robot.workpiece.cad().T_base_wobj
    for g, (xy, normal) in zip(guides, PUMP_WALL_POINTS, strict=True):
        wobj = (g.position_m - T[:3, 3]) @ T[:3, :3] * 1e3
        expected = np.array(xy) + 2.0 * np.array(normal)  # radius + gap off the wall
        assert np.linalg.norm(wobj[:2] - expected) < 0.6, (wobj, expected)
    assert session.pointing.learning_side() is None  # path learning decides it, once
    # Each point redraws the guide points and their labels: drawn whole before the screenshot
    # (it was taken mid-redraw once the clicks no longer waited a frame).
    frames_drawn(page)
    page.screenshot(path=str(_shot("click_to_teach")))
    deviation = _learn_and_postprocess(page, workbench)
    assert session.project().recording.wall_side == "right"  # from the mesh: beside the wall
    print(f"click-to-teach: {len(guides)} points, mean {np.mean(timings):.1f} s per point, "
          f"learned within {deviation:.3f} mm")  # fmt: skip
    assert deviation <= MAX_DEVIATION_MM


def _propose_accept_learn(page: Page, client, workbench, xy, normal, z_mm) -> float:
    session = workbench.session
    p = _look_at_wall(client, workbench, xy, normal, z_mm)
    started = time.monotonic()
    _click_at(page, client, p)  # the one click (the mode's default is "propose the wall")
    wait_for(lambda: session.pointing.proposal() is not None, timeout_s=30)
    print(f"proposal in {time.monotonic() - started:.1f} s")
    proposal = session.pointing.proposal()
    expect(page.get_by_text(f"{len(proposal.points)} proposed points")).to_be_visible()
    frames_drawn(page)  # the proposal's points, sent before its text
    drawn_whole(page)  # and their labels
    page.screenshot(path=str(_shot("proposal")))
    page.get_by_role("button", name="Accept proposal").click()
    wait_for(
        lambda: (
            len(session.project().guide_points) == len(proposal.points) and not session.robot.busy()
        ),
        timeout_s=300,
    )
    return _learn_and_postprocess(page, workbench)


def test_one_click_proposes_the_pump_groove_then_learns_within_a_third_of_a_mm(browser, workbench):
    page, client = _open(browser, workbench)
    deviation = _propose_accept_learn(page, client, workbench, (40.0, 65.0), (0, -1), 17.5)
    print(f"proposed on the pump: learned within {deviation:.3f} mm")
    assert deviation <= MAX_DEVIATION_MM


def test_one_click_proposes_an_uploaded_mesh_then_learns_within_a_third_of_a_mm(
    browser, workbench, tmp_path
):
    part = grooved_plate()
    stl = tmp_path / "grooved_plate.stl"
    stl.write_bytes(part.stl_bytes())
    page, client = _open(browser, workbench)
    with page.expect_file_chooser() as chooser:
        page.get_by_role("button", name="Upload mesh (STL/OBJ/PLY, mm)").click()
    chooser.value.set_files(str(stl))
    wait_for(lambda: workbench.session.robot.workpiece.cad().name == "grooved_plate", timeout_s=60)
    # the workbench frames the new part on its next tick: an orbit before that is undone (the
    # camera was found at the part's view, not the orbit's, in two full runs). Once framed,
    # the framing was sent before the orbit, which the browser then reports back.
    wait_for(lambda: workbench.part_framed, timeout_s=60)
    x, y, z = part.picks["island"]
    deviation = _propose_accept_learn(page, client, workbench, (x, y), (0, -1), 17.0)
    print(f"proposed on an uploaded mesh: learned within {deviation:.3f} mm")
    assert deviation <= MAX_DEVIATION_MM


def _shot(name: str):
    """Where a screenshot goes (the system's temporary folder: look at them after a run)."""
    import tempfile
    from pathlib import Path

    folder = Path(tempfile.gettempdir()) / "robomach-browser-shots"
    folder.mkdir(exist_ok=True)
    return folder / f"pointing_{name}.png"


def test_a_cell_change_leaves_nothing_of_the_old_cell_in_the_scene() -> None:
    """In process (no browser): learned, compared and proposed on the pump; then the block."""
    from app.session import Session

    with workbench_on(Session(real_time=False)) as wb:
        session = wb.session
        session.pointing.propose(np.array([0.0, -0.065, 0.017]))
        job = session.pointing.accept()
        done(session, job, 300)
        job = session.learning.start_path_learning(10.0, 0.005)
        done(session, job, 300)
        session.learning.run_postprocess()
        wait_for(lambda: "What learning buys" in wb.pointing.compare.content)
        session.pointing.propose(np.array([0.04, -0.065, 0.017]))
        wait_for(lambda: "P14" in wb.pointing.selected.options)
        assert not wb.scene.paths.hidden
        session.set_cell(workpiece="block")
        wait_for(lambda: wb.scene.paths.hidden)
        wait_for(lambda: wb.pointing.selected.options == ("none",))
        wait_for(lambda: wb.pointing.compare.content == "")
        assert wb.guide_points.selected.options == ("none",)
        assert session.project().status()["recording"] == "stale"  # kept in the project, not drawn
