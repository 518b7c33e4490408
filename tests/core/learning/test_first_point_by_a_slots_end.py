"""A first guide point near a slot's end, nearer the slot's other wall than the taught one,
with the next point a few millimetres along: the wall it stands by (the other side) runs round
the slot's end to the taught one, so a walk from it set off the wrong way. The first leg, being
short, watched the nearest approach to its end from its start, and the walk receding the wrong
way "passed" it within 1.5 mm: that walk won (shorter than the chord's) and the program ran
7 mm along the other wall and round the end before the taught one, with no NOT FIT (issue 28: a
wrong program that passed, 1 S-slot set in 600). A leg's end now counts the nearest approach
only while the tool has not gone back along the leg (``walk.LegEnd``).

Properties over generated open sets on the built-in S-slot, either side taught (the side is
"right": the parts' walls run with their material on the right): G1 a slot's width to 15 mm
from the wall's end, 0.1-0.8 mm off the other wall; G2 2-5.5 mm further along; the rest 10-30
mm apart to the other end. The route's first leg walks the taught wall, or the route is refused
with its reason. (Nearer the end than the slot's width, the fan's outermost ray from such a G1
may meet the end cap first, and the run starts there: docs/learning_model.md, known limits.)
A fresh seed each run (``ROBOMACH_SEED`` replays it)."""

from __future__ import annotations

import numpy as np
import pytest

from robomach_core.learning.run import PathLearningSettings
from tests.envelope import part_named, replay, run_seed, set_seeds
from tests.learning_outcome import planned_or_refused
from tests.people_points import nominal_rotation, place_points

SEED = run_seed()
SETS = 16  # per side, planned only
ON_WALL_MM = 0.5  # the first leg's walk stays this near the taught wall (its ball on it)


@pytest.mark.parametrize("side", ["right side", "left side"])
def test_a_first_point_by_a_slots_other_wall_walks_the_taught_wall_forward(side):
    part = part_named("s_groove")
    wall, other = part.walls[side], part.walls[part.walls[side].other]
    walked = 0
    for set_seed in set_seeds(SEED + (side == "left side"), SETS):
        rng = np.random.default_rng(set_seed)
        cell = part.cell(set_seed % 2**32)
        r_mm = cell.tool.radius_m * 1e3
        across = wall.free_mm - 2 * r_mm  # the gap from one wall to the other
        s0 = rng.uniform(wall.free_mm, 15.0)
        s = np.concatenate([[s0, s0 + rng.uniform(2.0, 5.5)]])
        s = np.concatenate([s, s[-1] + np.cumsum(rng.uniform(10.0, 30.0, 20))])
        s = s[s < wall.length_mm - 5.0]
        n = len(s)
        gaps = np.concatenate([[across - rng.uniform(0.1, 0.8)], rng.uniform(0.0, 1.5, n - 1)])
        heights = np.array([wall.at(float(v))[2] for v in s]) + r_mm + rng.uniform(0.5, 3.0, n)
        rotations = [nominal_rotation(part, cell)] * n
        guides, kept, _ = place_points(part, cell, side, s, gaps, heights, rotations, rng)
        if len(kept) < 3 or kept[:2] != [0, 1]:
            continue  # the arm could not stand there: not this property's case
        where = f"{replay(SEED)}, set {set_seed}: G1 {gaps[0]:.2f} mm off '{side}', s={s0:.1f}"
        settings = PathLearningSettings(closed=False, wall_side="right")
        route = planned_or_refused(guides, cell, settings, where)
        if route is None:
            continue  # refused before any motion, with the reason
        assert route.walks and route.walks[0].reached, f"{where}: the first leg is not walked"
        first = part.to_part_mm(cell.workpiece, route.walks[0].points_m)
        off = np.abs(wall.signed_distance(first)[0]) - r_mm
        on_other = np.abs(other.signed_distance(first)[0]) - r_mm
        worst = int(np.argmax(off))
        assert off[worst] <= ON_WALL_MM, (
            f"{where}: the first leg's walk passes {off[worst]:.2f} mm off the taught wall "
            f"({on_other[worst]:.2f} mm from the other) at {first[worst].round(1)}"
        )
        walked += 1
    assert walked >= SETS // 2, f"{replay(SEED)}: only {walked} of {SETS} sets walked"
