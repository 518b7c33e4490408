"""Walls of a mesh at one height, and the wall a picked point belongs to."""

from __future__ import annotations

import numpy as np
import pytest
import trimesh

from robomach_core.errors import InvalidInputError
from robomach_core.learning.walls import WallLoop, pick_wall, section_loops
from robomach_core.part.workpiece import block, water_pump

PICK = {"tool_radius_m": 0.001, "gap_m": 0.001, "height_above_floor_m": 0.003}


def test_the_pump_has_three_closed_walls_at_machining_height_the_true_one_among_them():
    pump = water_pump()
    loops = section_loops(pump.mesh, 0.017)
    assert [lp.closed for lp in loops] == [True, True, True]
    plate, outer, island = loops  # longest first
    assert plate.length_m == pytest.approx(0.860, abs=1e-6)
    _, pts = outer.sample(5e-4)
    assert pump.wall.distance(pts).max() < 1e-5  # the groove's outer wall, exactly
    # Material on the right: inside the groove is the free side of both groove walls.
    in_groove = np.array([[0.0, -0.0625]])
    assert outer.signed_distance(in_groove)[0] == pytest.approx(0.0025, abs=1e-5)
    assert island.signed_distance(in_groove)[0] == pytest.approx(0.0025, abs=1e-5)
    assert outer.signed_distance(np.array([[0.0, -0.070]]))[0] < 0  # in the rim's material


def test_an_unclosed_surface_gives_an_open_wall():
    strip = trimesh.Trimesh(
        [[0, 0, 0], [0.05, 0, 0], [0.05, 0, 0.01], [0, 0, 0.01],
         [0.08, 0.02, 0], [0.08, 0.02, 0.01]],
        [[0, 1, 2], [0, 2, 3], [1, 4, 5], [1, 5, 2]],
    )  # fmt: skip
    (wall,) = section_loops(strip, 0.005)
    assert not wall.closed
    assert wall.length_m == pytest.approx(0.05 + np.hypot(0.03, 0.02), abs=1e-9)


def test_a_wall_loop_measures_points_and_pieces():
    square = WallLoop(np.array([[0, 0], [0, 1], [1, 1], [1, 0]], dtype=float), 0.0, True)
    # Clockwise square: the material (inside) is on the right.
    assert square.signed_distance(np.array([[0.5, 0.5]]))[0] == pytest.approx(-0.5, abs=1e-4)
    assert square.signed_distance(np.array([[-0.2, 0.5]]))[0] == pytest.approx(0.2, abs=1e-4)
    assert square.free_normal_at(np.array([0.5]))[0] == pytest.approx([-1.0, 0.0])
    corner = square.free_normal_at(np.array([1.0]))[0]  # the bisector at a sharp corner
    assert corner == pytest.approx([-(0.5**0.5), 0.5**0.5])
    piece = square.piece(3.5, 0.5)  # over the start
    assert not piece.closed and piece.length_m == pytest.approx(1.0)


@pytest.mark.parametrize("closed", [True, False])
def test_a_wall_loop_projects_exactly_onto_its_nearest_point(closed: bool) -> None:
    """``project`` and ``signed_distance`` (shapely's R-tree over the segments) are the foot
    of the perpendicular on the nearest of every segment, found by brute force, on random
    polygons with points near and far, over fresh seeds."""
    seed = int(np.random.default_rng().integers(2**32))
    rng = np.random.default_rng(seed)
    for _ in range(20):
        n = int(rng.integers(3, 60))
        angle = np.sort(rng.uniform(0, 2 * np.pi, n))[::-1]  # clockwise: material inside
        radius = rng.uniform(0.02, 0.1) * rng.uniform(0.6, 1.0, n)
        wall = WallLoop(
            np.column_stack([np.cos(angle), np.sin(angle)]) * radius[:, None], 0.0, closed
        )
        xy = rng.uniform(-0.12, 0.12, (200, 2))
        chain = wall.points_m if not closed else np.vstack([wall.points_m, wall.points_m[:1]])
        a, d = chain[:-1], np.diff(chain, axis=0)
        u = np.clip(np.einsum("kij,ij->ki", xy[:, None] - a, d) / np.sum(d * d, axis=1), 0, 1)
        feet = a + u[..., None] * d
        gap = np.linalg.norm(xy[:, None] - feet, axis=2)
        best = np.argmin(gap, axis=1)
        want_s = wall.cumulative_m[best] + u[np.arange(len(xy)), best] * np.linalg.norm(
            d[best], axis=1
        )
        got_s = wall.project(xy)
        ds = np.abs(got_s - wall.wrap(want_s))
        ds = np.minimum(ds, wall.length_m - ds) if closed else ds
        ties = np.sort(gap, axis=1)[:, 1] - gap.min(axis=1) < 1e-12  # two segments as near
        assert np.all((ds < 1e-12) | ties), f"seed {seed}"
        np.testing.assert_allclose(np.abs(wall.signed_distance(xy)), gap.min(axis=1), atol=1e-15,
                                   err_msg=f"seed {seed}")  # fmt: skip


def test_a_pick_on_the_pump_groove_keeps_its_height_or_says_why_not():
    pick = pick_wall(water_pump().mesh, [0.0, -0.065, 0.019], **PICK)
    assert pick.floor_z_m == pytest.approx(0.014) and pick.top_z_m == pytest.approx(0.020)
    assert pick.z_m == pytest.approx(0.019, abs=1e-9)  # the click's own height
    assert pick.loop.length_m == pytest.approx(0.7576, abs=1e-3)
    assert len(pick.others) == 2 and not pick.notes
    assert np.allclose(pick.T_wobj_floor, np.eye(4))  # a level part: the work object's frame
    low = pick_wall(water_pump().mesh, [0.0, -0.065, 0.0145], **PICK)
    assert low.z_m == pytest.approx(0.017, abs=1e-9)  # the set 3 mm above the floor
    assert "0.5 mm above the floor" in low.notes[0] and "clear the floor" in low.notes[0]
    rim = pick_wall(water_pump().mesh, [0.0, -0.065, 0.0198], **PICK)
    assert rim.z_m == pytest.approx(0.017, abs=1e-9) and "below its rim" in rim.notes[0]


def test_an_outside_edge_is_worked_where_the_spindle_stays_above_the_part():
    kept = pick_wall(block().mesh, [0.0, -0.025, 0.035], **PICK, tool_reach_m=0.020)
    assert kept.floor_z_m == pytest.approx(0.0)  # the table
    assert kept.z_m == pytest.approx(0.035) and not kept.notes
    pick = pick_wall(block().mesh, [0.0, -0.025, 0.010], **PICK, tool_reach_m=0.020)
    assert pick.z_m == pytest.approx(0.040 - 0.020 + 0.005)
    assert "spindle" in pick.notes[0]


@pytest.mark.parametrize(
    "point, message",
    [
        ([0.0, -0.0625, 0.014], "floor or a top"),  # the groove floor
        ([0.0, 0.0, 0.020], "floor or a top"),  # the island's top
        ([0.0, -0.0625, 0.030], "off the part"),  # above it
        ([0.0, -0.0625, 0.0215], "from the part's surface"),  # in the air above the groove
    ],
)
def test_a_pick_off_a_wall_says_what_to_pick(point, message):
    with pytest.raises(InvalidInputError, match=message):
        pick_wall(water_pump().mesh, point, **PICK)


def test_a_wall_too_low_for_the_cutter_is_refused():
    step = trimesh.creation.box(extents=(0.1, 0.1, 0.0015))
    step.apply_translation([0, 0, 0.00075])
    with pytest.raises(InvalidInputError, match="too low"):
        pick_wall(step, [0.0, -0.05, 0.001], **PICK)


def test_a_normal_of_any_finite_length_picks_as_its_unit_does():
    """The normal a click sends may have any length (the API says so): scaled by 1e-300 to
    1e300 as a whole or component by component (a fresh draw each run), it picks the same wall
    at the same height as its unit; zero is refused. A normal of 1e285 overflowed the norm, its
    unit came out zero and the server answered 503 (an assertion inside)."""
    import random

    seed = random.randrange(2**32)
    rng = random.Random(seed)
    mesh = water_pump().mesh
    point, unit = [0.0, -0.065, 0.019], np.array([0.0, 1.0, 0.0])  # the groove's outer wall
    want = pick_wall(mesh, point, unit, **PICK)
    for _ in range(8):
        scaled = unit * 10.0 ** rng.uniform(-300, 300)
        tiny = [10.0 ** rng.uniform(-300, -200) * rng.choice((-1, 1)), 0.0, 0.0]
        lopsided = unit + np.array(tiny) if rng.random() < 0.5 else scaled
        for normal in (scaled, lopsided):
            got = pick_wall(mesh, point, normal, **PICK)
            where = f"seed {seed}: normal {normal}"
            assert got.z_m == want.z_m and got.loop.length_m == want.loop.length_m, where
    with pytest.raises(InvalidInputError, match="must not be zero"):
        pick_wall(mesh, point, np.zeros(3), **PICK)
