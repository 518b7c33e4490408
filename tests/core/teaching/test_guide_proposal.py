"""Guide points proposed along a picked wall, and the tool's place for one click."""

from __future__ import annotations

import math

import numpy as np
import pytest
import trimesh
from shapely.geometry import Point

from robomach_core.cell import Cell, CellConfig, cell_supervisor
from robomach_core.errors import InvalidInputError
from robomach_core.learning.walls import section_loops
from robomach_core.part import Workpiece
from robomach_core.part.workpiece import block, water_pump
from robomach_core.teaching import guide_intents, guide_plan
from robomach_core.teaching.pointing import (
    ProposalSettings,
    job_tool_rotation,
    propose_guide_points,
    refuse_unreachable,
    teach_point,
)
from robomach_core.transforms import make_transform, rotation_about
from tests.generated_parts import grooved_plate, l_block, slotted_plate

R = 0.001  # tool radius
GAP = 0.001


def _cell(workpiece: Workpiece, robot: str = "ur10") -> Cell:
    return Cell(CellConfig(robot=robot, workpiece=workpiece))


def _uploaded(part) -> Workpiece:
    from robomach_core.part import mesh_from_bytes
    from robomach_core.part.workpiece import DEFAULT_T_BASE_WOBJ

    return mesh_from_bytes(
        part.stl_bytes(), ".stl", name=part.name, T_base_wobj=DEFAULT_T_BASE_WOBJ
    )


def _propose(workpiece: Workpiece, point_mm, robot: str = "ur10", **kw):
    cell = _cell(workpiece, robot)
    return propose_guide_points(
        workpiece,
        cell.robot,
        np.asarray(point_mm, dtype=float) * 1e-3,
        tool_radius_m=R,
        q_seed=cell.robot.home_rad,
        supervisor=cell_supervisor(cell),
        **kw,
    )


def _check_beside_the_wall(proposal, workpiece: Workpiece) -> None:
    """Every point stands gap + radius off the picked wall, clear of every other wall, and
    every leg's chord keeps the cutter off the picked wall's material."""
    loops = section_loops(workpiece.mesh, proposal.z_m)
    wall = proposal.wall
    xy = np.array([p.position_wobj_m[:2] for p in proposal.points])
    assert np.allclose([p.position_wobj_m[2] for p in proposal.points], proposal.z_m)
    d_wall = wall.signed_distance(xy)
    assert np.all(d_wall > R + 0.2e-3)
    assert np.all(d_wall < R + GAP + 1e-4)
    for loop in loops:
        assert np.all(np.abs(loop.signed_distance(xy)) > R + 0.2e-3)
    legs = len(xy) if proposal.closed else len(xy) - 1
    for k in range(legs):
        a, b = xy[k], xy[(k + 1) % len(xy)]
        chord = a + np.linspace(0, 1, 200)[:, None] * (b - a)
        assert wall.signed_distance(chord).min() > R, f"leg {k + 1} cuts towards the wall"


def test_the_pump_groove_gets_fourteen_points_like_the_example_operator():
    pump = water_pump()
    proposal = _propose(pump, (0.0, -65.0, 17.0))
    assert proposal.closed and proposal.wall_side == "right"
    assert len(proposal.points) == 14
    assert proposal.z_m == pytest.approx(0.017, abs=1e-5)
    assert all(p.reach == "ok" and p.joints_rad is not None for p in proposal.points)
    _check_beside_the_wall(proposal, pump)
    # In order along the wall: counter-clockwise round the groove (material on the right).
    xy = np.array([p.position_wobj_m[:2] for p in proposal.points])
    angles = np.unwrap(np.arctan2(xy[:, 1], xy[:, 0]))
    assert np.all(np.diff(angles) > 0) and angles[-1] - angles[0] > 1.8 * math.pi
    # The example operator's points are the same planner's, placed by an imprecise hand.
    plan = guide_plan(pump, R, np.random.default_rng(0))
    assert len(plan) == len(proposal.points)
    planned = np.array([i.position_m for i in plan])
    proposed = np.array([p.T_base_tcp[:3, 3] for p in proposal.points])
    assert np.linalg.norm(planned[:, None] - proposed[None], axis=2).min(axis=1).max() < 1.7e-3


def test_an_outside_edge_gets_a_point_at_every_sharp_corner():
    proposal = _propose(block(), (0.0, -25.0, 30.0))
    corners = [p for p in proposal.points if p.kind == "outside corner"]
    assert len(corners) == 4
    for p in corners:  # on the bisector, radius + gap off the corner
        x, y = np.abs(p.position_wobj_m[:2])
        d = math.hypot(x - 0.075, y - 0.025)
        assert d == pytest.approx(R + GAP, abs=3e-4)
        assert x - 0.075 == pytest.approx(y - 0.025, abs=3e-4)
    _check_beside_the_wall(proposal, block())


def test_an_l_shaped_block_brackets_its_inside_corner_and_marks_five_outside_ones():
    part = l_block()
    wp = _uploaded(part)
    proposal = _propose(wp, part.picks["outline"])
    assert proposal.closed
    assert sum(p.kind == "outside corner" for p in proposal.points) == 5
    _check_beside_the_wall(proposal, wp)


@pytest.mark.parametrize("wall", ["outer", "island"])
def test_in_a_groove_the_picked_wall_is_the_one_followed(wall):
    part = grooved_plate()
    wp = _uploaded(part)
    proposal = _propose(wp, part.picks[wall])
    xy_mm = np.array([p.position_wobj_m[:2] for p in proposal.points]) * 1e3
    for other, outline in part.walls.items():
        d = np.array([outline.distance(Point(*p)) for p in xy_mm])
        if other == wall:
            assert np.all(d < 2.1)
        else:
            assert np.all(d > 3.5)  # the groove is 6 mm wide: the other wall is 4 mm away
    _check_beside_the_wall(proposal, wp)


def test_a_slot_side_is_an_open_wall_from_end_to_end():
    part = slotted_plate()
    wp = _uploaded(part)
    proposal = _propose(wp, part.picks["right side"])
    assert not proposal.closed
    assert proposal.points[0].kind == "wall end" and proposal.points[-1].kind == "wall end"
    side = part.walls["right side"]
    xy_mm = np.array([p.position_wobj_m[:2] for p in proposal.points]) * 1e3
    along = [side.project(Point(*p)) for p in xy_mm]
    assert np.all(np.diff(along) > 0)  # in order from one end to the other
    assert along[0] < 8 and along[-1] > side.length - 8
    _check_beside_the_wall(proposal, wp)


def test_a_groove_narrower_than_cutter_and_gaps_centres_the_tool_or_refuses():
    plate = trimesh.creation.box(extents=(0.12, 0.08, 0.02))
    plate.apply_translation([0, 0, 0.01])
    cut = trimesh.creation.box(extents=(0.08, 0.0032, 0.01))
    cut.apply_translation([0, 0, 0.02])
    narrow = plate.difference(cut)
    wp = Workpiece("narrow", narrow, make_transform(np.eye(3), np.array([0.8, 0.16, 0.0])))
    proposal = _propose(wp, (0.0, -1.6, 18.0))
    xy = np.array([p.position_wobj_m[:2] for p in proposal.points])
    mid_run = xy[np.abs(xy[:, 0]) < 0.03]
    assert np.allclose(mid_run[:, 1], 0.0, atol=1e-4)  # centred in the 3.2 mm slot
    assert all("centred" in p.message for p in proposal.points if abs(p.position_wobj_m[0]) < 0.03)
    wp2 = Workpiece(
        "too_narrow",
        plate.difference(_slab(0.0018)),
        make_transform(np.eye(3), np.array([0.8, 0.16, 0.0])),
    )
    proposal = _propose(wp2, (0.0, -0.9, 18.0))
    assert any(p.reach == "unreachable" and "too narrow" in p.message for p in proposal.points)
    with pytest.raises(InvalidInputError, match="cannot be reached"):
        refuse_unreachable(proposal)


def _slab(width: float) -> trimesh.Trimesh:
    cut = trimesh.creation.box(extents=(0.08, width, 0.01))
    cut.apply_translation([0, 0, 0.02])
    return cut


def test_points_beyond_a_small_arm_are_marked_unreachable_with_the_reason():
    proposal = _propose(water_pump(), (0.0, -65.0, 19.0), robot="ur3")
    bad = [p for p in proposal.points if p.reach == "unreachable"]
    assert bad and all("reach" in p.message for p in bad)
    assert all(p.joints_rad is None for p in bad)


def test_a_click_places_the_tool_gap_off_the_wall_at_the_click():
    pump = water_pump()
    cell = _cell(pump)
    point, pick = teach_point(
        pump, cell.robot, np.array([0.04, -0.065, 0.0185]), tool_radius_m=R,
        q_seed=cell.robot.home_rad,
    )  # fmt: skip
    assert point.position_wobj_m == pytest.approx([0.04, -0.063, 0.0185], abs=2e-5)  # its height
    assert point.reach == "ok" and point.kind == "taught" and point.message == ""
    T = point.T_base_tcp
    assert T[:3, 2] == pytest.approx([0.0, 0.0, -1.0])  # the tool axis down into the part
    assert np.linalg.norm(cell.robot.fk(point.joints_rad)[:3, 3] - T[:3, 3]) < 1e-6
    wider = teach_point(
        pump, cell.robot, np.array([0.04, -0.065, 0.0185]), tool_radius_m=R,
        settings=ProposalSettings(gap_m=0.0015),
    )[0]  # fmt: skip
    assert wider.position_wobj_m[1] == pytest.approx(-0.0625, abs=2e-5)


def test_the_tool_axis_follows_a_tilted_work_object_and_the_operator_touches_the_wall():
    T = make_transform(rotation_about("z", 0.3) @ rotation_about("x", 0.2), np.zeros(3))
    R_tool = job_tool_rotation(T)
    assert R_tool[:, 2] == pytest.approx(-T[:3, 2])
    flat = make_transform(rotation_about("z", 0.3), np.zeros(3))
    from robomach_core.cell import TOOL_DOWN

    assert job_tool_rotation(flat) == pytest.approx(TOOL_DOWN)
    proposal = _propose(block(), (0.0, -25.0, 30.0))
    intents = guide_intents(proposal)
    for p, intent in zip(proposal.points, intents, strict=True):
        if p.kind == "outside corner":
            assert intent.wall_normal is None  # no push at an outside corner
        else:  # towards the wall: from the point, the wall is that way
            foot = p.position_wobj_m[:2] + intent.wall_normal[:2] * (R + GAP)
            assert abs(proposal.wall.signed_distance(foot[None])[0]) < 2e-4
