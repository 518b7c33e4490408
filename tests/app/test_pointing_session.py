"""Teaching by pointing in the session (``app/session/pointing.py``): click-to-teach, the
proposal and its edits, accepting it, learning from it, and a cell change that drops it."""

from __future__ import annotations

import numpy as np
import pytest

from app.session import NotFoundError, Session
from robomach_core.errors import InvalidInputError, UnreachableTargetError
from robomach_core.learning.walls import section_loops
from robomach_core.part import PartDeviation
from tests.jobs import finished

WOBJ_M = np.array([0.80, 0.16, 0.0])  # the water pump's work object (rotation: identity)
ON_WALL = np.array([0.0, -0.065, 0.017])  # the groove's outer wall, 3 mm above its floor (wobj)


@pytest.fixture
def fast() -> Session:
    s = Session(real_time=False)
    yield s
    s.close()


def test_a_click_on_the_wall_moves_the_tool_beside_it_and_records_the_point(fast: Session):
    taught = fast.pointing.teach_at_surface(ON_WALL + [0.04, 0, 0])
    assert taught.entry.index == 0 and taught.arrival.reached and taught.notice == ""
    p = fast.robot.snapshot().position_m - WOBJ_M
    assert p == pytest.approx([0.04, -0.063, 0.017], abs=4e-4)
    assert not fast.robot.snapshot().in_contact
    (g,) = list(fast.project().guide_points)
    assert np.allclose(g.position_m, fast.robot.snapshot().position_m)
    # Drag to adjust: the same point taught again further along the wall replaces it.
    fast.pointing.teach_at_surface(ON_WALL + [0.0, 0, 0])
    fast.pointing.teach_at_surface(ON_WALL + [-0.04, 0, 0], replace_index=0)
    first = fast.project().guide_points[0].position_m - WOBJ_M
    assert first[0] == pytest.approx(-0.04, abs=4e-4) and len(fast.project().guide_points) == 2
    with pytest.raises(NotFoundError, match="G5"):
        fast.pointing.teach_at_surface(ON_WALL, replace_index=4)
    with pytest.raises(InvalidInputError, match="floor or a top"):
        fast.pointing.teach_at_surface(np.array([0.0, -0.0625, 0.014]))


def test_clicked_points_leave_the_wall_side_to_path_learning_which_reads_the_mesh(
    fast: Session,
):
    from robomach_core.learning.part_walls import PartWalls
    from robomach_core.learning.route import mean_tool_axis, resolve_wall_side

    cad = fast.robot.workpiece.cad()
    for order, side in (((-0.04, 0.04), "right"), ((0.04, -0.04), "left")):
        fast.clear_guide_points()
        for x in order:
            fast.pointing.teach_at_surface(ON_WALL + [x, 0, 0])
        assert fast.pointing.learning_side() is None  # no proposal: decided once, by learning
        guides = list(fast.project().guide_points)
        walls = PartWalls(cad, mean_tool_axis(guides), fast.robot.cell.tool.radius_m)
        decided = resolve_wall_side(guides, "auto", walls=walls)
        assert decided.side == side, decided  # along the wall's own direction: right


@pytest.mark.slow  # a whole proposal learned
def test_a_proposal_is_shown_edited_and_accepted_then_learned_within_the_wall(fast: Session):
    proposal = fast.pointing.propose(ON_WALL)
    assert len(proposal.points) == 14 and proposal.closed
    assert list(fast.project().guide_points) == []  # nothing recorded, nothing moved yet
    first = proposal.points[0].position_wobj_m
    assert first[:2] == pytest.approx([0.0, -0.063], abs=1e-3)  # the one nearest the click
    xy = np.array([p.position_wobj_m[:2] for p in proposal.points])
    k = int(np.argmin(np.linalg.norm(xy - [-0.084, -0.063], axis=1)))
    moved = fast.pointing.move_proposed(k, np.array([-0.0845, -0.070, 0.017]))
    assert moved.points[k].position_wobj_m[:2] == pytest.approx([-0.0845, -0.063], abs=2e-4)
    # Dragged past its neighbours, a point takes its place among them along the wall.
    swapped = fast.pointing.move_proposed(1, np.array([-0.020, -0.070, 0.017]))
    xs = [p.position_wobj_m[0] for p in swapped.points[:3]]
    assert xs == sorted(xs)
    moved = fast.pointing.move_proposed(0, np.array([0.0, -0.070, 0.017]))
    fewer = fast.pointing.delete_proposed(3)
    assert len(fewer.points) == 13
    # A reader told of the new points (as the GUI and the event stream are) finds them taught
    # by pointing at once: a learn on "auto" then would follow the picked wall, not the forces.
    seen: list[str | None] = []

    def on_change(topic: str) -> None:
        if topic == "guide_points" and len(fast.project().guide_points) == 13:
            seen.append(fast.pointing.learning_side())

    unsubscribe = fast.subscribe(on_change)
    info = finished(fast, fast.pointing.accept())
    unsubscribe()
    assert info.status == "done", info.error
    assert seen and set(seen) == {"right"}, seen
    assert fast.pointing.proposal() is None
    guides = list(fast.project().guide_points)
    assert len(guides) == 13
    planned = np.array([p.T_base_tcp[:3, 3] for p in fewer.points])
    recorded = np.array([g.position_m for g in guides])
    assert np.all(np.linalg.norm(recorded - planned, axis=1) < 3e-3)  # touched the wall
    assert fast.pointing.learning_side() == "right"
    # The check before the run reads the side the run will take, as the wall preview does.
    assert fast.learning.guide_findings() == fast.learning.guide_findings(wall_side="right")
    assert fast.learning.taught_wall_preview()[1].startswith("follows the wall on the right")
    info = finished(fast, fast.learning.start_path_learning(10.0, 0.005))
    assert info.status == "done", info.error
    assert (fast.project().learned and fast.project().learned.settings).wall_side == "right"
    outcome = fast.learning.run_postprocess()
    assert outcome.score.max_m <= 0.3e-3
    assert outcome.cad_comparison.learned.max_m <= 0.3e-3


def test_a_cell_change_drops_the_proposal_and_unreachable_points_are_refused(fast: Session):
    fast.pointing.propose(ON_WALL)
    fast.set_cell(robot="ur3")
    assert fast.pointing.proposal() is None
    with pytest.raises(NotFoundError, match="click a wall"):
        fast.pointing.accept()
    proposal = fast.pointing.propose(ON_WALL)
    assert any(p.reach == "unreachable" for p in proposal.points)
    with pytest.raises(InvalidInputError, match="cannot reach"):
        fast.pointing.accept()
    far = ON_WALL + [-0.085, 0, 0]  # the pump's far corner, beyond a UR3
    with pytest.raises(UnreachableTargetError, match="cannot stand beside the wall"):
        fast.pointing.teach_at_surface(far)


def test_a_realistic_cell_meets_the_real_part_and_teaches_on_the_mesh(fast: Session):
    fast.set_cell(part_deviation=PartDeviation.realistic(0))
    assert fast.project().cell.part_deviation == PartDeviation.realistic(0)
    assert fast.robot.workpiece.cad().nominal is None and fast.robot.workpiece.nominal is not None
    real = section_loops(fast.robot.workpiece.scoring_mesh(), 0.017)[1]
    cad = section_loops(fast.robot.workpiece.cad().mesh, 0.017)[1]
    assert real.length_m != pytest.approx(cad.length_m, abs=1e-5)
    proposal = fast.pointing.propose(ON_WALL)
    xy = np.array([p.position_wobj_m[:2] for p in proposal.points])
    assert np.allclose(cad.signed_distance(xy), 0.002, atol=1e-4)  # placed on the CAD
