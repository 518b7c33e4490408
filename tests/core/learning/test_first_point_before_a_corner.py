"""A first guide point pressed on a straight wall a few millimetres before a rounded corner,
the next point far round it: the first leg's chord cuts the corner, and the way across it (the
side's way) is up to 60 deg off the wall the point is pressed on. The route must start at that
wall, where the point stands, not at the corner ahead: when rays were asked for a wall facing
back within the fan's 60 deg, the point's own wall (at 60 deg) was refused, the corner 6 mm on
was taken, and the program began there (98.7 % of the stretch; envelope set
8437294682105086681, a wrong program that passed). Off a chord any wall facing back is taken;
only the walk's own way, along the wall, asks for one within the fan's angle
(``route.taught_wall_points``: a stepped floor's riser across the groove faces along it).

Properties over generated open stretches on the stepped groove's walls (corners of 10 mm and 4
mm radius, risers across the groove): G1 pressed on a straight 1-12 mm before a corner, G2 15-60
mm round it (the first point of an open route takes its way from the chord to G2 alone), the
rest along the wall. The run's start lies on the taught wall at G1's station (within
``STATION_MM``), or the route is refused with its reason. A fresh seed each run
(``ROBOMACH_SEED`` replays it)."""

from __future__ import annotations

import numpy as np
import pytest

from robomach_core.learning.run import PathLearningSettings
from tests.envelope import part_named, replay, run_seed, set_seeds
from tests.learning_outcome import planned_or_refused
from tests.people_points import nominal_rotation, place_points

SEED = run_seed()
SETS = 10  # per wall, planned only
STATION_MM = 1.5  # the start's foot on the wall, from G1's
TURN_DEG_PER_MM = 2.0  # a corner: the wall turns faster than this


def _corner_starts(wall) -> np.ndarray:
    """Arc lengths where the wall starts turning into a corner (travel order)."""
    s = np.arange(0.0, wall.length_mm, 0.25)
    t = np.array([wall.at(float(v))[1] for v in s])
    turn = np.degrees(
        np.abs(
            np.arctan2(np.roll(t, -1, 0)[:, 1], np.roll(t, -1, 0)[:, 0])
            - np.arctan2(t[:, 1], t[:, 0])
        )
    )
    turn = np.minimum(turn, 360.0 - turn) / 0.25
    turning = turn > TURN_DEG_PER_MM
    return s[turning & ~np.roll(turning, 1)]


@pytest.mark.parametrize("wall_name", ["outer", "island"])
def test_a_first_point_before_a_corner_starts_at_its_own_wall(wall_name):
    part = part_named("stepped_groove")
    wall = part.walls[wall_name]
    corners = _corner_starts(wall)
    started = 0
    for set_seed in set_seeds(SEED + (wall_name == "island"), SETS):
        rng = np.random.default_rng(set_seed)
        cell = part.cell(set_seed % 2**32)
        r_mm = cell.tool.radius_m * 1e3
        s0 = float(rng.choice(corners)) - rng.uniform(1.0, 12.0)
        g2 = rng.uniform(15.0, 60.0)
        s = s0 + np.concatenate([[0.0, g2], g2 + np.cumsum(rng.uniform(20.0, 50.0, 8))])
        s = s[s < s0 + 0.8 * wall.length_mm] % wall.length_mm  # an open stretch
        n = len(s)
        gaps = np.concatenate([[rng.uniform(-0.05, 0.2)], rng.uniform(0.0, 1.0, n - 1)])
        heights = np.array([wall.at(float(v))[2] for v in s]) + r_mm + rng.uniform(0.5, 3.0, n)
        rotations = [nominal_rotation(part, cell)] * n
        guides, kept, _ = place_points(part, cell, wall_name, s, gaps, heights, rotations, rng)
        if not kept or kept[0] != 0 or len(guides) < 4:
            continue  # the arm could not stand there: not this property's case
        where = f"{replay(SEED)}, set {set_seed}: G1 at s={s0 % wall.length_mm:.1f} mm"
        settings = PathLearningSettings(closed=False, wall_side="right")
        route = planned_or_refused(guides, cell, settings, where)
        if route is None:
            continue  # refused before any motion, with the reason
        assert route.start_towards_wall is not None, f"{where}: no start on the wall"
        p0 = guides[0].position_m
        steps = np.linspace(0.0, (gaps[0] + r_mm + 2.0) * 1e-3, 300)
        ray = part.to_part_mm(cell.workpiece, p0 + steps[:, None] * route.start_towards_wall)
        d = np.abs(wall.signed_distance(ray)[0]) - r_mm
        hit = ray[int(np.argmin(d))]
        s_hit = float(wall.project(hit[None, :2])[0])
        off = abs((s_hit - s0 + wall.length_mm / 2) % wall.length_mm - wall.length_mm / 2)
        assert off <= STATION_MM, (
            f"{where}: the run starts {off:.1f} mm along the wall from G1's station"
        )
        started += 1
    assert started >= SETS // 3, f"{replay(SEED)}: only {started} of {SETS} sets planned"
