"""The viser workbench around the cell (issue 31), in process (no browser needed): a placement
tried moves the part in the scene and nothing else, then places it; a cell change frames the
part from where the arm is not in the way, and leaves nothing of the old cell drawn; the check
before a run is shown above Run with each finding's severity."""

from __future__ import annotations

import random
from contextlib import contextmanager
from types import SimpleNamespace

import numpy as np
import pytest

from app.session import Session
from robomach_core.cell import ROBOT_NAMES
from robomach_core.project import wobj_transform
from robomach_core.transforms import matrix_from_quaternion
from tests.browser.conftest import wait_for, workbench_on
from tests.jobs import done

pytestmark = pytest.mark.slow  # a viser server and a session per test


@pytest.fixture
def workbench():
    with workbench_on(Session(real_time=False)) as wb:
        yield wb


def _node_pose(node) -> np.ndarray:
    T = np.eye(4)
    T[:3, :3] = matrix_from_quaternion(np.asarray(node.wxyz, dtype=float))
    T[:3, 3] = node.position
    return T


def test_a_placement_tried_moves_the_part_and_nothing_else_until_it_is_placed(workbench):
    wb, session = workbench, workbench.session
    session.pointing.propose(np.array([0.0, -0.065, 0.0175]))
    placed = session.robot.workpiece.cad().T_base_wobj
    values = (790.0, 150.0, 5.0, 0.0, 0.0, 25.0)
    for control, v in zip((*wb.placement.position, *wb.placement.angles), values, strict=True):
        control.value = v
    wb.placement._try()  # what each widget's update does
    wait_for(lambda: wb.scene.placement_previewed, timeout_s=10)
    assert np.allclose(_node_pose(wb.scene.workpiece_node), wobj_transform(values), atol=1e-9)
    assert np.allclose(session.robot.workpiece.cad().T_base_wobj, placed)  # not applied
    assert session.pointing.proposal() is not None and not wb.placement.place.disabled
    assert "Trying the numbers above" in wb.placement.note.content
    # A click on the part drawn where it is not placed does nothing.
    assert wb.scene.hit_part(np.array([0.8, 0.16, 0.3]), np.array([0.0, 0.0, -1.0])) is None
    wb.placement._place()
    wait_for(lambda: not wb.scene.placement_previewed, timeout_s=10)
    assert np.allclose(session.robot.workpiece.cad().T_base_wobj, wobj_transform(values))
    assert session.project().cell.wobj_mm_deg == values
    assert session.pointing.proposal() is None and len(session.project().guide_points) == 0
    assert np.allclose(_node_pose(wb.scene.workpiece_node), wobj_transform(values), atol=1e-9)
    wait_for(lambda: wb.placement.place.disabled and "Trying" not in wb.placement.note.content)
    # The click meets the part where it now is.
    hit = wb.scene.hit_part(
        wobj_transform(values)[:3, 3] + np.array([0.0, 0.0, 0.3]), np.array([0.0, 0.0, -1.0])
    )
    assert hit is not None and hit[0][2] == pytest.approx(0.020, abs=1e-6)  # the plate's top


class _Camera:
    fov = np.radians(50.0)
    position = look_at = up_direction = None


@contextmanager
def _nothing():
    yield


def test_view_the_part_frames_it_with_the_arm_out_of_the_way():
    """Arms (three drawn per run) at their home pose, every built-in part and an uploaded
    plate, placed at random about the default place and turned: the camera stands outside
    the arm and sees the part's centre and the corners of its top past the arm and its
    spindle, with the whole part in view."""
    from app.gui.camera import blocked_rays, part_view_pose
    from tests.generated_parts import cam_plate

    rng = random.Random()
    seed = rng.randrange(2**32)
    rng.seed(seed)
    session = Session(real_time=False)
    try:
        with workbench_on(session) as wb:
            for robot in ["ur10", *rng.sample(ROBOT_NAMES, 2)]:
                for workpiece in ("water_pump", "block", "cam_plate"):
                    if workpiece == "cam_plate":
                        session.set_cell(robot=robot, wobj_mm_deg=None)
                        session.upload_workpiece(cam_plate().stl_bytes(), "cam_plate.stl")
                    else:
                        session.set_cell(robot=robot, workpiece=workpiece, wobj_mm_deg=None)
                    T = session.robot.workpiece.cad().T_base_wobj
                    values = (*(T[:3, 3] * 1e3 + [rng.uniform(-60, 60), rng.uniform(-60, 60), 0]),
                              0.0, 0.0, rng.uniform(-45, 45))  # fmt: skip
                    session.set_cell(wobj_mm_deg=values)
                    wait_for(lambda r=robot: wb.scene._robot_name == r, timeout_s=30)
                    pose = session.robot.snapshot()
                    arm = wb.scene.arm_mesh(pose.joints_rad, pose.T_base_tcp)
                    bounds = session.robot.workpiece.cad().mesh_in_base().bounds
                    eye, centre = part_view_pose(bounds, _Camera.fov, arm)
                    context = f"seed {seed}: {robot}, {workpiece} at {np.round(values, 1)}"
                    corners = [[x, y, bounds[1, 2]] for x in bounds[:, 0] for y in bounds[:, 1]]
                    inset = centre + 0.8 * (np.array(corners) - centre)
                    inset[:, 2] = bounds[1, 2]
                    assert blocked_rays(arm, eye, np.vstack([centre, inset])) == 0, context
                    radius = 0.5 * np.linalg.norm(bounds[1] - bounds[0])
                    to_centre = np.linalg.norm(centre - eye)
                    assert to_centre * np.sin(0.5 * _Camera.fov) >= radius, context
    finally:
        session.close()


def test_a_cell_change_leaves_nothing_of_the_old_cell_drawn_and_says_what_it_cleared(workbench):
    wb, session = workbench, workbench.session
    from robomach_core import project as core

    session.commit(lambda p: core.choose(p, "fuzzy", "off"), "post")
    session.pointing.pick(np.array([0.0, -0.065, 0.0175]), np.array([0.0, 1.0, 0.0]))
    notes = []
    client = SimpleNamespace(
        camera=_Camera(), atomic=_nothing, add_notification=lambda *a, **k: notes.append(a)
    )
    wb.server.get_clients = lambda: {0: client}  # one browser, seen by the workbench
    session.set_cell(robot="kr270")
    wait_for(lambda: notes, timeout_s=10)
    assert notes[0][0] == "Machining choice cleared" and "fuzzy / off" in notes[0][1]
    # The camera framed the new part (on the KR 270's stand, 600 mm up).
    assert client.camera.look_at[2] > 0.6
    assert wb.scene.workpiece_node.position[2] == pytest.approx(0.6)


def test_each_finding_is_marked_by_its_severity_and_a_refusal_stands_out():
    from app.gui.panels.robot_wiring import findings_markdown
    from robomach_core.choices import TEXTS
    from robomach_core.learning.findings import GuideWarning

    found = [
        GuideWarning(2, "leg_through_part", "the leg G2 -> G3 runs through the part.", "info"),
        GuideWarning(0, "wall_side", "auto cannot tell the wall side.", "refusal"),
        GuideWarning(3, "wrist_turn", "axis 6 cannot turn that far.", "warning"),
    ]
    lines = findings_markdown(found).splitlines()
    assert [line.split(" ")[1] for line in lines] == [
        TEXTS["severity_icon"][s] for s in ("refusal", "warning", "info")
    ]  # refusals first
    assert f"**{TEXTS['severity']['refusal']}**" in lines[0]  # bold: learning will not start
    assert f"*{TEXTS['severity']['info']}*" in lines[2] and "**" not in lines[2]
    assert lines[0].endswith("auto cannot tell the wall side.")  # whole sentences, not cut


def test_the_check_before_the_run_is_shown_above_run_one_line_per_rule(workbench):
    wb, session = workbench, workbench.session
    assert "No guide point breaks a rule" in wb.path_learning.check.content
    job = session.learning.start_example()
    done(session, job, 300)
    wb.path_learning.wall_side.value = "left"  # against the example's pushes
    wb.guide_rules.refresh()  # what the wall side's update does
    content = wb.path_learning.check.content
    assert content == f"**Check before the run**\n\n{wb.guide_rules.warnings.content}"
    lines = [line for line in content.splitlines() if line.startswith("- ")]
    assert len(lines) == 2  # 28 findings: two rules at 14 points each
    assert all("(the same at G2, G3" in line and "G14)" in line for line in lines)


def test_three_clicks_in_the_touch_mode_calibrate_the_part_where_it_really_is():
    """The cam plate placed at random (turned up to 45 deg) on a realistic part of a fresh seed:
    three clicks in the touch mode (the top and two sides at a corner, as the panel's intro
    says) touch 4, 3 and 2 times; the fit drawn in green until it is accepted; accepting it
    places the CAD on the real part (its corners within 1 mm: the casting's 0.5 mm and the
    burrs), the click proposes again, the touches' labels go, and the camera stays."""
    from robomach_core.part import PartDeviation
    from robomach_core.part.real_part import fixture_error
    from tests.generated_parts import cam_plate

    rng = random.Random()
    seed = rng.randrange(2**31)
    rng.seed(seed)
    placement = (790.0 + rng.uniform(-40, 40), 150.0 + rng.uniform(-40, 40), 0.0,
                 0.0, 0.0, rng.uniform(-45, 45))  # fmt: skip
    context = f"seed {seed}: placed at {np.round(placement, 1)}"
    with workbench_on(Session(real_time=False)) as wb:
        session = wb.session
        session.set_cell(part_deviation=PartDeviation.realistic(seed))
        session.upload_workpiece(cam_plate().stl_bytes(), "cam_plate.stl")
        session.set_cell(wobj_mm_deg=placement)
        client = SimpleNamespace(camera=_Camera(), atomic=_nothing, add_notification=print)
        wb.server.get_clients = lambda: {0: client}
        session.pointing.set_settings(click_mode="touch")  # what Touch faces does
        assert session.pointing.click_mode == "touch", context
        faces = [((120, -70, 20), (0, 0, 1)), ((110, -90, 10), (0, -1, 0)),
                 ((150, -60, 10), (1, 0, 0))]  # fmt: skip
        for (point, normal), touches in zip(faces, (4, 7, 9), strict=True):
            wb.pointing._clicked(np.array(point) * 1e-3, np.array(normal, float), client)
            assert len(session.calibration.state().touches) == touches, context
        fit = session.calibration.state().fit
        assert fit is not None, context
        wait_for(lambda: wb.scene.server.scene._handle_from_node_name.get("/calibration/fit"))
        client.camera.position = (9.0, 9.0, 9.0)  # the person's view
        wb.calibration._accept()  # what Accept the calibration does
        assert session.pointing.click_mode == "propose", context
        cad = session.robot.workpiece.cad()
        truth = wobj_transform(placement) @ fixture_error(PartDeviation.realistic(seed)).transform
        corners = np.array([[x, y, 0.02, 1.0] for x in (-0.15, 0.15) for y in (-0.09, 0.09)])
        off = np.linalg.norm((cad.T_base_wobj @ corners.T - truth @ corners.T)[:3], axis=0)
        assert off.max() < 1e-3, f"{context}: the calibrated CAD is {off.max() * 1e3:.2f} mm off"
        wait_for(lambda: wb.calibration.remove.disabled is False)
        nodes = wb.scene.server.scene._handle_from_node_name
        wait_for(lambda: "/calibration/fit" not in nodes)
        assert not [n for n in nodes if n.startswith("/calibration/") and n.endswith("/label")]
        assert client.camera.position == (9.0, 9.0, 9.0), "accepting moved the camera"
