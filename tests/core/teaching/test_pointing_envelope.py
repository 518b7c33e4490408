"""The guide-point planner over the envelope a user can set: generated plates level, tilted
10-20 deg in their mesh (the tool vertical) or by their work object (the tool normal to the
plate), grooves round an island, outside edges and stepped floors; any tool radius, gap and
height the planner accepts. Seeds are drawn by hypothesis on every run and a failure prints
its seed (``tests.generated_parts.drawn_plate``)."""

from __future__ import annotations

import math
import re

import numpy as np
import pytest
import shapely
from hypothesis import given, settings
from hypothesis import strategies as st

from robomach_core.cell import Robot
from robomach_core.errors import InvalidInputError
from robomach_core.learning.thresholds import (
    CONTACT_BELOW_TOP_M,
    CONTACT_BELOW_TOP_RADII,
    CUTTER_FLOOR_CLEARANCE_M,
    MIN_SPACING_M,
)
from robomach_core.part import Workpiece
from robomach_core.teaching.pointing import ProposalSettings, propose_guide_points, teach_point
from robomach_core.transforms import make_transform
from tests.generated_parts import DrawnPlate, drawn_plate

ROBOT = Robot("ur10")
WOBJ_M = np.array([0.80, 0.16, 0.0])  # an uploaded part's place in front of a UR10
TOL_M = 5e-5  # the section's facets and the ray's float32 precision
# Beside the wall: where a point stands on a rounded corner, its normal is the chord's over
# +-0.5 mm (walls.NORMAL_WINDOW_M), and the gap comes out up to ~0.06 mm short on a 10 mm radius
GAP_TOL_M = 1e-4
seeds = st.integers(0, 2**32 - 1)
tilts = st.sampled_from(["level", "mesh", "wobj"])


def _workpiece(plate: DrawnPlate, tilt: str) -> Workpiece:
    """The plate as a workpiece: its mesh as drawn (tilted or level) in a level work object,
    or (``tilt == "wobj"``) its level mesh in a work object tilted as the plate was."""
    if tilt != "wobj":
        return Workpiece("drawn", plate.mesh, make_transform(np.eye(3), WOBJ_M))
    R = plate.T_mesh_plate[:3, :3]
    level = plate.mesh.copy()
    level.apply_transform(np.linalg.inv(plate.T_mesh_plate))
    return Workpiece("drawn", level, make_transform(R, WOBJ_M + [0.0, 0.0, 0.03]))


def _plate_frame(plate: DrawnPlate, tilt: str) -> DrawnPlate:
    """The plate as the work object sees it (level in its mesh when the work object tilts)."""
    if tilt != "wobj":
        return plate
    from dataclasses import replace

    return replace(plate, mesh=None, T_mesh_plate=np.eye(4))


@given(
    seed=seeds,
    tilt=tilts,
    kind=st.sampled_from(["groove outer", "groove island", "edge outline", "stepped outer"]),
    radius_mm=st.floats(1.0, 2.0),
    gap_share=st.floats(0.0, 1.0),
    along=st.floats(0.0, 1.0),
    height_share=st.floats(0.0, 1.0),
)
@settings(max_examples=40, deadline=None)
def test_a_proposal_follows_the_picked_wall_beside_it_at_the_height_above_the_floor(
    seed, tilt, kind, radius_mm, gap_share, along, height_share
):
    shape, wall = kind.split()
    angle = 0.0 if tilt == "level" else 10.0 + 10.0 * np.random.default_rng(seed).random()
    plate = drawn_plate(seed, shape, angle)
    wp = _workpiece(plate, tilt)
    frame = _plate_frame(plate, tilt)
    r = radius_mm * 1e-3
    gap = 5e-4 + gap_share * (min(1.5e-3, 0.5 * plate.width_m - r - 3e-4) - 5e-4)
    low = r + CUTTER_FLOOR_CLEARANCE_M + 1e-4
    low = max(low, 0.0025) if shape == "stepped" else low  # above the step (2 mm) everywhere
    high = 0.005 if shape != "edge" else plate.top_z_m - max(0.5 * r, CONTACT_BELOW_TOP_M) - 1e-4
    low = max(low, 0.006) if shape == "edge" else low  # the spindle clears the part's top
    height = low + height_share * (high - low)
    point, normal = frame.pick(wall, along, height)
    proposal = propose_guide_points(
        wp, ROBOT, point, normal, tool_radius_m=r, settings=ProposalSettings(gap_m=gap),
        q_seed=ROBOT.home_rad,
    )  # fmt: skip
    outline = plate.walls[wall]
    assert proposal.closed
    assert not [n for n in proposal.notes if "leg" in n], proposal.notes  # every leg bracketed
    tcp = np.array([p.position_wobj_m for p in proposal.points])
    # (points placed exactly MIN_SPACING_M apart come out 2e-18 m short in floating point)
    assert np.linalg.norm(tcp - np.roll(tcp, 1, axis=0), axis=1).min() >= MIN_SPACING_M - 1e-12
    assert proposal.wall.length_m == pytest.approx(outline.length, rel=1e-3)
    kept = abs(proposal.height_above_floor_m - height) < 1e-6
    assert kept or (tilt == "mesh" and any("spindle" in n for n in proposal.notes)), (
        proposal.height_above_floor_m, height, proposal.notes,
    )  # fmt: skip
    xyz = frame.in_plate(np.array([p.position_wobj_m for p in proposal.points]))
    d = shapely.distance(shapely.points(xyz[:, :2]), outline)
    assert np.all(np.abs(d - (r + gap)) < GAP_TOL_M), np.abs(d - (r + gap)).max()
    # On the free side: outside the material (an edge's outline, the island) or in the groove.
    inside = shapely.contains_xy(shapely.Polygon(outline), xyz[:, 0], xyz[:, 1])
    assert np.all(inside == (wall == "outer"))
    floors = np.array([plate.floor_z(x, y) for x, y in xyz[:, :2]])
    above = xyz[:, 2] - floors
    assert np.all(np.abs(above - proposal.height_above_floor_m) < TOL_M), above
    assert all(p.reach != "unreachable" for p in proposal.points), [
        p.message for p in proposal.points
    ]
    tool_axis = np.array([p.T_base_tcp[:3, 2] for p in proposal.points])
    assert np.allclose(tool_axis, -wp.T_base_wobj[:3, 2], atol=1e-9)  # the job's orientation


@given(
    seed=seeds,
    tilt=st.sampled_from(["level", "wobj"]),
    wall=st.sampled_from(["outer", "island"]),
    radius_mm=st.floats(1.5, 2.0),
    gap_mm=st.floats(0.2, 0.35),  # the smallest gap a proposal takes, and a little more
    along=st.floats(0.0, 1.0),
)
@settings(max_examples=25, deadline=None)
def test_a_cutter_nearly_as_wide_as_the_groove_gets_every_leg_bracketed(
    seed, tilt, wall, radius_mm, gap_mm, along
):
    """A groove a few tenths wider than the cutter and its two gaps, round an island whose
    corners are sharp where the plate's are tighter than the groove is wide: every leg keeps
    the cutter off the wall, each point its gap. Round a sharp corner the places stand on the
    arc round its tip, and a point is added between the tip's and the straight's where the
    chord would cut under the cutter (it had no room by the worst place, and the planner said
    "the leg ... leaves the wall" for a groove the cutter fits)."""
    angle = 0.0 if tilt == "level" else 10.0 + 10.0 * np.random.default_rng(seed).random()
    r, gap = radius_mm * 1e-3, gap_mm * 1e-3
    plate = drawn_plate(seed, "groove", angle, width_m=2 * (r + gap) + 6e-4)
    wp = _workpiece(plate, tilt)
    frame = _plate_frame(plate, tilt)
    point, normal = frame.pick(wall, along, r + CUTTER_FLOOR_CLEARANCE_M + 5e-4)
    proposal = propose_guide_points(
        wp, None, point, normal, tool_radius_m=r, settings=ProposalSettings(gap_m=gap)
    )
    assert not [n for n in proposal.notes if "leg" in n], proposal.notes
    xyz = frame.in_plate(np.array([p.position_wobj_m for p in proposal.points]))
    d = shapely.distance(shapely.points(xyz[:, :2]), plate.walls[wall])
    assert np.all(np.abs(d - (r + gap)) < GAP_TOL_M), np.abs(d - (r + gap)).max()


@given(seed=seeds, tilt=tilts, offset_share=st.floats(-1.0, 1.0), width_mm=st.floats(2.6, 3.9))
@settings(max_examples=30, deadline=None)
def test_a_point_between_two_walls_is_refused_naming_both_and_one_off_the_middle_is_not(
    seed, tilt, offset_share, width_mm
):
    angle = 0.0 if tilt == "level" else 10.0 + 10.0 * np.random.default_rng(seed).random()
    plate = drawn_plate(seed, "groove", angle, width_m=width_mm * 1e-3)
    wp = _workpiece(plate, tilt)
    frame = _plate_frame(plate, tilt)
    r, w = 1e-3, width_mm * 1e-3
    on_outer, normal = frame.pick("outer", 0.3, 0.003)
    free = normal / np.linalg.norm(normal)
    off = 0.5 * w + offset_share * (0.5 * w - 2e-4)  # from the outer wall, across the groove
    point = on_outer + free * off
    between = abs(off - 0.5 * w) < 0.45 * r  # the two distances within 0.9 tool radii
    clear = abs(off - 0.5 * w) > 0.55 * r
    if between:
        with pytest.raises(InvalidInputError, match="between two walls") as info:
            propose_guide_points(wp, None, point, tool_radius_m=r)
        assert len(re.findall(r"\(-?\d+\.\d, -?\d+\.\d, -?\d+\.\d\) mm", str(info.value))) == 3
    elif clear:
        proposal = propose_guide_points(wp, None, point, tool_radius_m=r)
        picked = "outer" if off < 0.5 * w else "island"
        assert proposal.wall.length_m == pytest.approx(plate.walls[picked].length, rel=1e-3)


@given(seed=seeds, tilt=st.sampled_from(["level", "wobj"]), height_mm=st.floats(0.0, 6.0))
@settings(max_examples=25, deadline=None)
def test_a_click_keeps_its_height_or_says_why_and_where_the_tool_works(seed, tilt, height_mm):
    plate = drawn_plate(seed, "groove", 0.0 if tilt == "level" else 15.0)
    wp = _workpiece(plate, tilt)
    frame = _plate_frame(plate, tilt)
    r, h = 1e-3, height_mm * 1e-3
    point, normal = frame.pick("outer", 0.6, h)
    taught, _ = teach_point(wp, ROBOT, point, normal, tool_radius_m=r, q_seed=ROBOT.home_rad)
    floor, top = 0.014, 0.020
    low = r + CUTTER_FLOOR_CLEARANCE_M
    high = top - floor - max(CONTACT_BELOW_TOP_RADII * r, CONTACT_BELOW_TOP_M)
    above = frame.in_plate(taught.position_wobj_m)[0, 2] - floor
    if low <= h <= high:
        assert above == pytest.approx(h, abs=1e-6) and taught.message == ""
    else:
        assert low - 1e-9 <= above <= high + 1e-9
        said = re.search(r"the point is (-?\d+\.\d) mm above the floor", taught.message)
        assert said and abs(float(said.group(1)) - h * 1e3) <= 0.051, taught.message  # 0.05 rounds
        assert f"the tool works {above * 1e3:.1f} mm above the floor instead" in taught.message
        assert ("clear the floor" if h < low else "below its rim") in taught.message
    assert math.isfinite(above)


@given(tilt_deg=st.floats(10.0, 20.0), axis_deg=st.floats(0.0, 360.0))
@settings(max_examples=6, deadline=None)
def test_an_l_block_tilted_in_its_stl_gets_its_corners_on_their_bisectors(tilt_deg, axis_deg):
    """Sharp corners from a file (float32 vertices, tilted): a point on each outside corner's
    bisector, radius + gap off its tip, and no leg that needs a point it cannot get."""
    import trimesh

    from robomach_core.part import mesh_from_bytes
    from tests.generated_parts import l_block

    part = l_block()
    a = math.radians(axis_deg)
    R = trimesh.transformations.rotation_matrix(
        math.radians(tilt_deg), [math.cos(a), math.sin(a), 0]
    )
    mesh = part.mesh.copy()
    mesh.apply_transform(R)
    lift = -mesh.bounds[0, 2]
    mesh.apply_translation([0.0, 0.0, lift])
    wp = mesh_from_bytes(
        mesh.export(file_type="stl"),
        ".stl",
        name="l",
        T_base_wobj=make_transform(np.eye(3), WOBJ_M),
    )
    pick = (R[:3, :3] @ np.array(part.picks["outline"]) + [0.0, 0.0, lift]) * 1e-3
    proposal = propose_guide_points(wp, None, pick, tool_radius_m=1e-3, tool_reach_m=None)
    assert not proposal.notes, proposal.notes
    corners = [p for p in proposal.points if p.kind == "outside corner"]
    assert len(corners) == 5
    tips = np.array([(50, -35), (50, 0), (0, 35), (-50, 35), (-50, -35)]) * 1e-3
    inward = np.array([(-1, 1), (-1, -1), (-1, -1), (1, -1), (1, 1)]) / math.sqrt(2)
    xyz = (np.array([p.position_wobj_m for p in corners]) * 1e3 - [0, 0, lift]) @ R[:3, :3] * 1e-3
    for tip, into in zip(tips, inward, strict=True):
        k = int(np.argmin(np.linalg.norm(xyz[:, :2] - tip, axis=1)))
        off = xyz[k, :2] - tip
        assert np.linalg.norm(off) == pytest.approx(2e-3, abs=5e-5)  # radius + gap
        assert off @ into == pytest.approx(-2e-3, abs=5e-5)  # on the bisector, outwards


def _rectangle_loop(w_m: float, h_m: float, spacing_m: float) -> np.ndarray:
    """A sharp rectangle's wall sampled every ``spacing_m``, counter-clockwise from a corner."""
    corners = np.array([[0.0, 0.0], [w_m, 0.0], [w_m, h_m], [0.0, h_m], [0.0, 0.0]])
    pts = []
    for a, b in zip(corners[:-1], corners[1:], strict=True):
        n = max(int(np.ceil(np.linalg.norm(b - a) / spacing_m)), 1)
        pts.extend(a + (b - a) * t for t in np.arange(n) / n)
    return np.array(pts)


@settings(max_examples=40, deadline=None)
@given(seed=seeds)
def test_a_closed_walls_count_starts_where_the_pick_says_not_where_its_loop_starts(seed):
    """The wall a proposal follows, and where its closed loop is counted from, are the same
    whichever vertex the section's loop starts at: a block's two equally long sides are told
    apart by the pick (a section chained by another library started the loop 3 vertices on,
    and the realistic block's proposal then went over the wall's top). Rectangles whose sides
    differ by 5 mm or more, picked on a long side: a pick midway between two equal sides, or
    sides within a millimetre of each other, are a knife edge of the corners' sampling, which
    no rule of this kind settles."""
    from robomach_core.learning.walls import WallLoop
    from robomach_core.teaching.pointing import _wall_extent

    rng = np.random.default_rng(seed)
    w = float(rng.uniform(0.03, 0.2))
    h = w + float(rng.choice([-1.0, 1.0])) * float(rng.uniform(0.005, 0.05))
    h = h if h >= 0.03 else w + float(rng.uniform(0.005, 0.05))  # a block, not a slot
    pts = _rectangle_loop(w, h, float(rng.uniform(0.0005, 0.003)))
    long = max(w, h)  # a pick on one of the two long sides, off its corners
    along = float(rng.uniform(0.1, 0.9)) * long
    if w >= h:
        pick_xy = np.array([along, 0.0]) if rng.random() < 0.5 else np.array([along, h])
    else:
        pick_xy = np.array([0.0, along]) if rng.random() < 0.5 else np.array([w, along])
    starts = []
    for roll in (0, int(rng.integers(1, len(pts))), int(rng.integers(1, len(pts)))):
        rolled = WallLoop(np.roll(pts, -roll, axis=0), 0.02, closed=True)
        s_pick = float(
            rolled.cumulative_m[np.argmin(np.linalg.norm(rolled.points_m - pick_xy, axis=1))]
        )
        wall, closed, _, pick_s, _ = _wall_extent(rolled, s_pick)
        assert closed
        starts.append((wall.points_m[0], wall.point_at(np.array([pick_s]))[0]))
    for start, at_pick in starts[1:]:
        assert np.linalg.norm(start - starts[0][0]) < 1e-3, f"seed {seed}: count starts elsewhere"
        assert np.linalg.norm(at_pick - starts[0][1]) < 1e-3, f"seed {seed}: the pick moved"
