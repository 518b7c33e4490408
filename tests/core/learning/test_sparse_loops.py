"""A sparse loop round an island: four points, the first leg spanning a sixth to nearly half
the loop so that its chord cuts across the island, and the wall on the chord's side is the
groove's outer wall; the first point stands by the island, none to two of the others press
it. The run went round the outer wall the other way, met the points out of order, and the
taught-wall check, which reads the wall off the walk, passed it (issue 28, a wrong program
that passed: 4.0 mm from the island, 0 % of it covered). The walk that meets the points in
order, and that the person's pushes agree with, is taken. Properties over generated sets on
two parts' islands, judged against the true walls (``learning_outcome``); a fresh seed each
run (``ROBOMACH_SEED`` replays it)."""

from __future__ import annotations

import numpy as np
import pytest

from tests.envelope import SET_FORCES_N, SET_SPEEDS_MM_S, part_named, replay, run_seed, set_seeds
from tests.learning_outcome import FAILURES, as_set, learn_set
from tests.people_points import nominal_rotation, place_points

SEED = run_seed()
SETS = 10  # per part: a learn each, 1-4 s


@pytest.mark.slow
@pytest.mark.parametrize("part_name", ["stepped_groove", "grooved_plate"])
def test_a_sparse_loop_round_an_island_follows_the_wall_its_points_were_taught_on(part_name):
    part = part_named(part_name)
    wall = part.walls["island"]
    L = wall.length_mm
    learned = 0
    for set_seed in set_seeds(SEED + (part_name == "grooved_plate"), SETS):
        rng = np.random.default_rng(set_seed)
        cell = part.cell(set_seed % 2**32)
        r_mm = cell.tool.radius_m * 1e3
        k_c = cell.workpiece.contact_stiffness_N_m * 1e-3  # N/mm
        forward = bool(rng.random() < 0.5)
        first = rng.uniform(0.15, 0.45)  # of the loop: the first chord cuts across the island
        rest = np.sort(rng.uniform(first + 0.1, 0.95, 2))
        s = rng.uniform(0.0, L) + np.array([0.0, first, *rest]) * L * (1 if forward else -1)
        room = (wall.free_mm - 2 * r_mm) / 2 - 0.3  # nearer the island than the other wall
        gaps = rng.uniform(0.0, room, 4)
        gaps[0] = rng.uniform(0.0, 0.5)
        pushed = 1 + rng.choice(3, size=int(rng.integers(0, 3)), replace=False)
        gaps[pushed] = -rng.uniform(2.0, 10.0, len(pushed)) / k_c
        heights = np.array([wall.at(float(v % L))[2] for v in s]) + r_mm + rng.uniform(0.5, 3, 4)
        rotations = [nominal_rotation(part, cell)] * 4
        guides, kept, _ = place_points(part, cell, "island", s % L, gaps, heights, rotations, rng)
        if len(guides) < 4:
            continue
        side = str(rng.choice(["given", "auto"]))
        pset = as_set(
            part, cell.workpiece, cell.tool.radius_m, guides, "a person", wall="island",
            side=("right" if forward else "left") if side == "given" else "auto",
        )  # fmt: skip
        force = float(rng.choice(SET_FORCES_N))
        speed = float(rng.choice(SET_SPEEDS_MM_S))
        outcome, _ = learn_set(part, cell, pset, force_N=force, speed_mm_s=speed)
        assert outcome.kind not in FAILURES, (
            f"{replay(SEED)}, set {set_seed} ({'forward' if forward else 'reversed'}, first leg "
            f"{first:.0%} of the loop, side {side}), {force:g} N, {speed:g} mm/s: {outcome}"
        )
        learned += outcome.kind == "learned"
    assert learned >= SETS // 2, f"{replay(SEED)}: {learned} of {SETS} sets learned"
