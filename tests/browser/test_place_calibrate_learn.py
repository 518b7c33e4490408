"""Issue 31's acceptance, in a real browser on the viser workbench: a part the project never saw,
whose cell holds it turned, placed in the GUI, its work object calibrated by touching three
faces of the real part (a fixture error of about 3 mm and 1.5 deg, and the casting's
deviations), then one click proposes its groove's wall, and the program learned there and
downloaded from the Export panel is within 0.3 mm of the real wall, in at most 20 actions.

The person's actions are counted as they are made (an upload with its file dialog is one, each
number typed is one, an orbit of the camera is one, each click on a button or the part is one)
and printed with ``-s``, beside the program's error against the real wall, measured here from
the downloaded file (``export.read_back``) against a section of the real part's mesh, and the
CAD-only program's error before and after the calibration for scale.

The workbench runs in this process over an unpaced session (the test reads the camera to
aim its clicks, as ``test_pointing`` does); the part's error is the world's, set before the
page opens, from a fresh seed whose drawn fixture error is 3 +- 0.3 mm and 1.5 +- 0.15 deg.
Screenshots of each stage go to the system's temporary folder (``robomach-browser-shots``).
"""

from __future__ import annotations

import math
import random
import tempfile
from pathlib import Path

import numpy as np
import pytest
from playwright.sync_api import Page, expect

from app.session import Session
from robomach_core.export.read_back import read_program
from robomach_core.learning.walls import section_loops
from robomach_core.part import PartDeviation
from robomach_core.part.real_part import fixture_error
from tests.browser.conftest import (
    drawn_whole,
    frames_drawn,
    new_context,
    wait_for,
    workbench_on,
)
from tests.browser.test_pointing import _click_at
from tests.generated_parts import cam_plate

pytestmark = pytest.mark.slow

VIEWPORT = {"width": 1400, "height": 900}
MAX_ACTIONS = 20
MAX_WALL_ERROR_MM = 0.3
PLACEMENT = (790.0, 150.0, 0.0, 0.0, 0.0, 25.0)  # the cam plate's cell: turned 25 deg
FIXTURE_SHIFT_MM, FIXTURE_TURN_DEG = 3.0, 1.5  # the real part's error (about)
# The faces touched (work object, mm; a point and its outward normal): the top and the two
# sides at the corner the camera looks at, away from the robot.
TOP = ((120.0, -70.0, 20.0), (0.0, 0.0, 1.0))
SIDE_Y = ((110.0, -90.0, 10.0), (0.0, -1.0, 0.0))
SIDE_X = ((150.0, -60.0, 10.0), (1.0, 0.0, 0.0))
ISLAND_WALL = (60.0, -49.0, 18.0)  # the groove's island wall, facing the corner
CORNER_VIEW = {
    "look_at_mm": (110.0, -60.0, 12.0),
    "direction": (1.0, -1.0, 1.15),
    "distance_m": 0.42,
}
PLACEMENT_LABELS = ("x (mm)", "y (mm)", "z (mm)", "rx (deg)", "ry (deg)", "rz (deg)")
TIMEOUT_S = 600.0  # generous: the machine's cores are shared


class Actions:
    """The person's actions, each named (printed at the end)."""

    def __init__(self) -> None:
        self.names: list[str] = []

    def __call__(self, name: str) -> None:
        self.names.append(name)

    def __len__(self) -> int:
        return len(self.names)


def _realistic_seed(rng: random.Random) -> int:
    """A fresh seed of the realistic preset whose fixture error is about 3 mm and 1.5 deg."""
    while True:
        seed = rng.randrange(2**31)
        drawn = fixture_error(PartDeviation.realistic(seed))
        shift = math.hypot(*drawn.shift_m[:2]) * 1e3
        turn = abs(math.degrees(drawn.rotation_rad))
        if abs(shift - FIXTURE_SHIFT_MM) < 0.3 and abs(turn - FIXTURE_TURN_DEG) < 0.15:
            return seed


def _shot(page: Page, name: str) -> None:
    folder = Path(tempfile.gettempdir()) / "robomach-browser-shots"
    folder.mkdir(exist_ok=True)
    page.screenshot(path=str(folder / f"acceptance_{name}.png"))


def _base(session, p_mm) -> np.ndarray:
    """A point of the CAD (work object, mm) in the base frame, where the scene draws it."""
    T = session.robot.workpiece.cad().T_base_wobj
    return T[:3, :3] @ (np.asarray(p_mm, dtype=float) * 1e-3) + T[:3, 3]


def _orbit(client, session, look_at_mm, direction, distance_m) -> None:
    """The person's orbit: the camera looks at a point of the part from ``direction`` (work
    object axes); done when the browser reports the new view back."""
    T = session.robot.workpiece.cad().T_base_wobj
    target = _base(session, look_at_mm)
    d = T[:3, :3] @ np.asarray(direction, dtype=float)
    eye = target + distance_m * d / np.linalg.norm(d)
    with client.atomic():
        client.camera.up_direction = (0.0, 0.0, 1.0)
        client.camera.position = tuple(eye)
        client.camera.look_at = tuple(target)
    sent = client.camera.update_timestamp
    wait_for(
        lambda: (
            client.camera.update_timestamp > sent
            and np.linalg.norm(np.asarray(client.camera.position) - eye) < 1e-4
        ),
        timeout_s=60,
    )


def _notes_of(client) -> list[str]:
    """The notifications the page is sent from now on (what a failure shows the person)."""
    notes: list[str] = []
    send = client.add_notification

    def noted(title, body="", *args, **kwargs):
        notes.append(f"{title}: {body}")
        return send(title, body, *args, **kwargs)

    client.add_notification = noted
    return notes


def _open_folder(page: Page, title: str) -> None:
    page.get_by_text(title, exact=True).first.click()


def _type(page: Page, label: str, value: float) -> None:
    field = page.get_by_label(label, exact=True)
    field.fill(f"{value:g}")
    field.press("Tab")


def _real_wall_error_mm(session, program_text: str, filename: str) -> float:
    """The downloaded program's largest error from the real part's wall [mm]: its moves read
    back (base frame), sampled every 0.1 mm, against the real part's section (the casting
    without its burrs) at the program's height: the ball's centre distance minus its radius."""
    from robomach_core.scoring.cad_program import score_against_wall

    path = read_program("urscript", {filename: program_text})
    real = session.robot.workpiece  # the part in the cell (its own mesh, where it really is)
    T = real.T_base_wobj
    wobj = (path.position_m - T[:3, 3]) @ T[:3, :3]
    z = float(np.median(wobj[:, 2]))
    loops = section_loops(real.scoring_mesh(), z)
    distance = [float(np.abs(loop.signed_distance(wobj[:, :2])).mean()) for loop in loops]
    wall = loops[int(np.argmin(distance))]
    radius = session.robot.cell.tool.radius_m
    return score_against_wall(path.position_m, wall, T, radius, closed=True).max_m * 1e3


def test_place_calibrate_propose_learn_export_within_a_third_of_a_mm_in_twenty_actions(
    browser, tmp_path
):
    rng = random.Random()
    seed = _realistic_seed(rng)
    print(f"seed {seed}: {fixture_error(PartDeviation.realistic(seed)).describe()}")
    part = cam_plate()
    stl = tmp_path / "cam_plate.stl"
    stl.write_bytes(part.stl_bytes())
    act = Actions()
    with workbench_on(Session(real_time=False)) as wb:
        session = wb.session
        session.set_cell(part_deviation=PartDeviation.realistic(seed))  # the world's part
        context = new_context(browser, viewport=VIEWPORT, accept_downloads=True)
        context.set_default_timeout(120_000)
        page = context.new_page()
        page.goto(f"http://127.0.0.1:{wb.server.get_port()}")
        expect(page.get_by_text("Teach by pointing")).to_be_visible()
        wait_for(lambda: len(wb.server.get_clients()) > 0)
        client = next(iter(wb.server.get_clients().values()))
        notes = _notes_of(client)

        # 1. Upload the part and place it where its cell holds it.
        with page.expect_file_chooser() as chooser:
            page.get_by_role("button", name="Upload mesh (STL/OBJ/PLY, mm)").click()
        chooser.value.set_files(str(stl))
        act("upload cam_plate.stl")
        wait_for(lambda: session.robot.workpiece.cad().name == "cam_plate", TIMEOUT_S)
        _open_folder(page, "Place the part")
        act("open Place the part")
        placed = session.preview.placed()
        for k, label in enumerate(PLACEMENT_LABELS):
            if abs(placed[k] - PLACEMENT[k]) > 1e-6:
                _type(page, label, PLACEMENT[k])
                act(f"type {label} = {PLACEMENT[k]:g}")
        wait_for(lambda: session.preview.values() == PLACEMENT, 60,
                 describe=lambda: str(session.preview.values()))  # fmt: skip
        _shot(page, "1_placement_tried")
        page.get_by_role("button", name="Place the part here").click()
        act("Place the part here")
        wait_for(lambda: session.project().cell.wobj_mm_deg == PLACEMENT, 60)

        # 2. Calibrate: touch the top and two sides at one corner of the real part.
        _open_folder(page, "Calibrate by touch")
        act("open Calibrate by touch")
        page.get_by_role("button", name="Touch faces").click()
        act("Touch faces")
        wait_for(lambda: session.pointing.click_mode == "touch", 60)
        _orbit(client, session, **CORNER_VIEW)
        act("orbit to the corner")
        _shot(page, "2_corner")
        for (point, _normal), touches in zip((TOP, SIDE_Y, SIDE_X), (4, 7, 9), strict=True):
            _click_at(page, client, _base(session, point))
            act(f"click the face at {point}")
            wait_for(
                lambda n=touches: len(session.calibration.state().touches) == n,
                TIMEOUT_S,
                describe=lambda: f"{len(session.calibration.state().touches)} touches; {notes}",
            )
        state = session.calibration.state()
        assert state.fit is not None, state.fit_error
        print(state.fit.describe())
        expect(page.get_by_text("Accept the calibration")).to_be_enabled()
        page.wait_for_timeout(3000)  # the touches and the fitted CAD drawn (software WebGL)
        _shot(page, "3_calibration_fit")
        page.get_by_role("button", name="Accept the calibration").click()
        act("Accept the calibration")
        wait_for(lambda: session.project().cell.registration is not None, 60)
        wait_for(lambda: session.pointing.click_mode == "propose", 60)

        # 3. One click on the groove's wall proposes its guide points; accept them.
        wait_for(lambda: wb.pointing.mode.value == "propose the wall", 60)
        _click_at(page, client, _base(session, ISLAND_WALL))
        act("click the island wall")
        wait_for(
            lambda: session.pointing.proposal() is not None,
            TIMEOUT_S,
            describe=lambda: f"picked {wb.pointing.picked}; notes {notes}",
        )
        proposal = session.pointing.proposal()
        assert proposal.closed
        expect(page.get_by_text(f"{len(proposal.points)} proposed points")).to_be_visible()
        frames_drawn(page)  # the proposed points, sent before their text
        drawn_whole(page)  # and their labels
        _shot(page, "4_proposal")
        page.get_by_role("button", name="Accept proposal").click()
        act("Accept proposal")
        wait_for(
            lambda: (
                len(session.project().guide_points) == len(proposal.points)
                and not session.jobs.active()
            ),
            TIMEOUT_S,
        )

        # 4. Learn, post-process, download the program.
        page.get_by_role("button", name="Run path learning").click()
        act("Run path learning")
        wait_for(
            lambda: session.project().recording is not None and not session.jobs.active(),
            TIMEOUT_S,
            describe=lambda: str([(j.kind, j.status, j.error) for j in session.jobs.list()]),
        )
        recording = session.project().recording
        assert recording.completed, recording.stop_reason
        page.get_by_role("button", name="Run post-processing").click()
        act("Run post-processing")
        wait_for(lambda: session.project().status()["postprocess"] == "current", TIMEOUT_S)
        wait_for(lambda: "What learning buys" in wb.pointing.compare.content, 60)
        expect(page.get_by_text("What learning buys", exact=True)).to_be_visible()
        frames_drawn(page)  # both programs, drawn before the comparison's table
        _shot(page, "5_learned_vs_cad_only")
        _open_folder(page, "Export")
        act("open Export")
        with page.expect_download() as download:
            page.get_by_role("button", name="program.script").first.click()
        act("download program.script")
        text = Path(download.value.path()).read_text()

        error_mm = _real_wall_error_mm(session, text, "program.script")
        comparison = session.project().processed.cad_comparison
        print("actions:", "; ".join(f"{k + 1}. {a}" for k, a in enumerate(act.names)))
        print(
            f"acceptance: {len(act)} actions; the downloaded program within {error_mm:.3f} mm "
            f"of the real wall (the project's score {comparison.learned.max_m * 1e3:.3f} mm); "
            f"CAD-only {comparison.cad_only.max_m * 1e3:.3f} mm calibrated, "
            f"{comparison.cad_only_unregistered.max_m * 1e3:.3f} mm as placed"
        )
        assert len(act) <= MAX_ACTIONS, act.names
        assert error_mm <= MAX_WALL_ERROR_MM
        # Without the calibration a CAD program misses by about the fixture error.
        assert comparison.cad_only_unregistered.max_m * 1e3 > 1.5
