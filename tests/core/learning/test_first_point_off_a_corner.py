"""A first guide point off an outside corner, diagonally: the corner's edge is its nearest
wall, no wall face is in front of it, and the way the first leg's chord says the wall lies
may point past the corner into open space. The run started searching that way and stopped,
"the tool searched 30 mm without finding the wall" (issue 28: the envelope's one stop in 600,
a T-boss set). The route now starts towards the corner the point stands by when the chord's
way meets no wall, and walks the loop from there.

Properties over generated sets on the outside walls of the T-boss and the block: G1 0.5-3 mm
off a randomly chosen outside corner along its bisector, the other points along the rest of
the wall; the route starts towards the taught wall and walks the whole loop, or refuses with
its reason. One set per part is learned and judged against the true wall
(``learning_outcome``). A fresh seed each run (``ROBOMACH_SEED`` replays it)."""

from __future__ import annotations

import numpy as np
import pytest

from robomach_core.learning.run import PathLearningSettings
from tests.envelope import part_named, replay, run_seed, set_seeds
from tests.learning_outcome import as_set, learn_set, planned_or_refused
from tests.people_points import nominal_rotation, place_points

SEED = run_seed()
SETS = 12  # per part, planned only: about a tenth of a second each
PARTS = {"tboss": "boss", "block": None}  # None: the part's only wall
CORNER_TURN_DEG = 60.0  # an outside corner: the wall turns round the material by this much
REACH_MM = 0.1  # the start's way meets the wall within this of the cutter's surface


def _wall(part_name: str) -> tuple[object, str]:
    part = part_named(part_name)
    name = PARTS[part_name] or next(iter(part.walls))
    return part, name


def _outside_corners(wall, span_mm: float = 3.0) -> np.ndarray:
    """Arc lengths of the outside corners: where the wall turns right (round the material, on
    the right of travel) by ``CORNER_TURN_DEG`` or more over ``span_mm``, one per corner."""
    s = np.arange(0.0, wall.length_mm, 0.25)
    turn = []
    for v in s:
        a, b = wall.at(float(v) - span_mm)[1], wall.at(float(v) + span_mm)[1]
        turn.append(np.degrees(np.arctan2(a[0] * b[1] - a[1] * b[0], a @ b)))
    right = np.array(turn) <= -CORNER_TURN_DEG
    corners, k = [], 0
    while k < len(s):
        if right[k]:
            j = k
            while j + 1 < len(s) and right[j + 1]:
                j += 1
            corners.append(0.5 * (s[k] + s[j]))
            k = j + 1
        else:
            k += 1
    return np.array(corners)


def _corner_set(part_name: str, set_seed: int):
    """Guide points with G1 diagonally off an outside corner, and that corner's point (mm)."""
    part, name = _wall(part_name)
    wall = part.walls[name]
    rng = np.random.default_rng(set_seed)
    cell = part.cell(set_seed % 2**32)
    r_mm = cell.tool.radius_m * 1e3
    L = wall.length_mm
    s0 = float(rng.choice(_outside_corners(wall)))
    # the other points along the rest of the loop, in order, 10-45 mm of wall apart (sparser
    # legs may cut across the part, which is another property's case)
    ahead = np.cumsum(rng.uniform(10.0, 45.0, int(L // 10)))
    s = np.concatenate([[s0], s0 + ahead[ahead < L - 10.0]]) % L
    n = len(s)
    gaps = np.concatenate([[rng.uniform(0.5, 3.0)], rng.uniform(0.0, 2.0, n - 1)])
    heights = np.array([wall.at(float(v))[2] for v in s]) + r_mm + rng.uniform(0.5, 3.0, n)
    rotations = [nominal_rotation(part, cell)] * n
    guides, kept, _ = place_points(part, cell, name, s, gaps, heights, rotations, rng)
    corner_xy = wall.at(s0)[0]
    return part, name, cell, guides, kept, gaps[0], corner_xy


@pytest.mark.parametrize("part_name", list(PARTS))
def test_a_first_point_off_an_outside_corner_starts_towards_it_and_walks_the_loop(part_name):
    walked = 0
    for set_seed in set_seeds(SEED + (part_name == "block"), SETS):
        part, name, cell, guides, kept, gap, corner_xy = _corner_set(part_name, set_seed)
        if not kept or kept[0] != 0 or len(guides) < 4:
            continue  # the arm could not stand there: not this property's case
        where = f"{replay(SEED)}, set {set_seed}: G1 {gap:.2f} mm off the corner at {corner_xy}"
        settings = PathLearningSettings(closed=True, wall_side="right")
        route = planned_or_refused(guides, cell, settings, where)
        if route is None:
            continue  # refused before any motion, with the reason
        assert route.start_towards_wall is not None and route.walks, (
            f"{where}: the run would search for the wall by force along the chord's side"
        )
        assert route.walks[-1].reached, f"{where}: the walk does not close the loop"
        # the way the run starts meets the taught wall about where G1 stands off it
        wall = part.walls[name]
        r_mm = cell.tool.radius_m * 1e3
        p0 = guides[0].position_m
        steps = np.linspace(0.0, (gap + r_mm + 2.0) * 1e-3, 200)
        ray = p0 + steps[:, None] * route.start_towards_wall
        d = wall.signed_distance(part.to_part_mm(cell.workpiece, ray))[0] - r_mm
        assert float(d.min()) <= REACH_MM, (
            f"{where}: the start's way passes {float(d.min()):.2f} mm off the taught wall"
        )
        walked += 1
    assert walked >= SETS // 3, f"{replay(SEED)}: only {walked} of {SETS} sets walked"


@pytest.mark.slow
@pytest.mark.parametrize("part_name", list(PARTS))
def test_a_first_point_off_an_outside_corner_is_learned_on_the_taught_wall(part_name):
    settings = PathLearningSettings(closed=True, wall_side="right")
    for set_seed in set_seeds(SEED + 2 + (part_name == "block"), 6):
        part, name, cell, guides, kept, gap, corner_xy = _corner_set(part_name, set_seed)
        if not kept or kept[0] != 0 or len(guides) < 4:
            continue
        if planned_or_refused(guides, cell, settings, f"{replay(SEED)}, set {set_seed}") is None:
            continue  # refused before any motion, with the reason: the other test's case
        break
    else:
        pytest.fail(f"{replay(SEED)}: no set of 6 kept its first point at the corner and planned")
    pset = as_set(
        part, cell.workpiece, cell.tool.radius_m, guides, "a person", wall=name, side="right"
    )
    outcome, _ = learn_set(part, cell, pset, force_N=15.0, speed_mm_s=5.0)
    assert outcome.kind == "learned", (
        f"{replay(SEED)}, set {set_seed}: G1 {gap:.2f} mm off the corner at {corner_xy}: {outcome}"
    )
