"""A first guide point resting on the floor just before a step up in the groove: the route lifts
it over the step (its cutter, and the floor a radius and ``STEP_LOOKAHEAD_M`` ahead along the
wall), but the run started at the height the floor under the first leg's chord gave, and the
chord heads into the island, past the step. The tool met the riser 1 mm on, took it for the wall
and left the wall by 3.4 mm before it came back (issue 28, envelope set
10877618064455963898: NOT FIT for a program the person taught well). The run starts at the
height the walk climbs past the first point, along the wall (``run.run_start``).

Properties over generated closed sets on the stepped groove (``envelope_parts.stepped_groove``,
2 mm risers across the groove at x = -25 and 25 mm), on either wall where the route climbs a
riser: G1 resting on the floor 0.3-2 mm before it, the other points round the loop. The run's
start clears the step's top by the floor clearance, or the route is refused with its reason
(``python -m tests.envelope --one 10877618064455963898`` replays the learned set). A fresh seed
each run (``ROBOMACH_SEED`` replays it)."""

from __future__ import annotations

import numpy as np
import pytest

from robomach_core.learning.run import PathLearningSettings, run_start
from tests.envelope import part_named, replay, run_seed, set_seeds
from tests.learning_outcome import planned_or_refused
from tests.people_points import nominal_rotation, place_points

SEED = run_seed()
SETS = 10  # per wall, planned only
STEP_TOPS_MM = {-25.0: 14.0, 25.0: 16.0}  # each riser's x and the floor past it (steps up +x)
TOL_MM = 0.05  # the floor's facets and the lift's float arithmetic


def _before_a_riser(wall, r_mm: float, rng: np.random.Generator) -> tuple[float, float]:
    """An arc length on ``wall`` where the travel runs +x along a straight (the floor steps
    up ahead), ``r_mm`` + 0.3-2 mm before a riser, and that riser's x."""
    s = np.arange(0.0, wall.length_mm, 0.1)
    pts = np.array([wall.at(float(v))[0] for v in s])
    runs_x = np.array([wall.at(float(v))[1][0] > 0.999 for v in s])
    riser = float(rng.choice(list(STEP_TOPS_MM)))
    x = riser - r_mm - rng.uniform(0.3, 2.0)
    k = int(np.argmin(np.where(runs_x, np.abs(pts[:, 0] - x), np.inf)))
    return float(s[k]), riser


def _set(wall_name: str, set_seed: int):
    part = part_named("stepped_groove")
    wall = part.walls[wall_name]
    rng = np.random.default_rng(set_seed)
    cell = part.cell(set_seed % 2**32)
    r_mm = cell.tool.radius_m * 1e3
    s0, riser = _before_a_riser(wall, r_mm, rng)
    ahead = np.cumsum(rng.uniform(25.0, 60.0, 12))
    s = np.concatenate([[s0], s0 + ahead[ahead < wall.length_mm - 20.0]]) % wall.length_mm
    n = len(s)
    gaps = rng.uniform(0.0, 1.0, n)
    above = np.concatenate([[rng.uniform(0.0, 0.3)], rng.uniform(0.5, 3.0, n - 1)])
    heights = np.array([wall.at(float(v))[2] for v in s]) + r_mm + above  # G1 on the floor
    rotations = [nominal_rotation(part, cell)] * n
    guides, kept, _ = place_points(part, cell, wall_name, s, gaps, heights, rotations, rng)
    return part, cell, guides, kept, riser, r_mm


@pytest.mark.parametrize("wall_name", ["island", "outer"])
def test_a_first_point_on_the_floor_before_a_step_starts_over_the_step(wall_name):
    started = 0
    for set_seed in set_seeds(SEED + (wall_name == "outer"), SETS):
        part, cell, guides, kept, riser, r_mm = _set(wall_name, set_seed)
        if not kept or kept[0] != 0 or len(guides) < 4:
            continue  # the arm could not stand there: not this property's case
        where = f"{replay(SEED)}, set {set_seed}: G1 before the riser at x={riser:g} mm"
        settings = PathLearningSettings(closed=True, wall_side="right")
        route = planned_or_refused(guides, cell, settings, where)
        if route is None:
            continue  # refused before any motion, with the reason
        start, _, _ = run_start(route)
        bottom = float(part.to_part_mm(cell.workpiece, start[None])[0, 2]) - r_mm
        step_top = STEP_TOPS_MM[riser]
        need = step_top + settings.floor_clearance_m * 1e3 - TOL_MM
        assert bottom >= need, (
            f"{where}: the run starts with the cutter's bottom at {bottom:.2f} mm, under the "
            f"step's top {step_top:.2f} mm + the floor clearance"
        )
        started += 1
    assert started >= SETS // 3, f"{replay(SEED)}: only {started} of {SETS} sets planned"
