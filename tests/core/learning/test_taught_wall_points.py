"""Which wall a guide point was taught on (``route.taught_wall_points``), the one answer the
taught-wall check and the run's side share: over generated grooves, level and tilted 10-20 deg
(in the mesh with the tool vertical, by the work object with the tool normal), with the person's
side given and points drawn anywhere across the groove, up to nearer the other wall than the
taught one. Every wall point found must lie on the taught wall, never the one across: a point
found on the other wall is a good program condemned (issue 28: on a plate tilted in its mesh, a
ray cast straight across the tool axis at an island's corner left the groove under its floor,
and the check took the nearer wall across).

A fresh seed each run (``ROBOMACH_SEED`` replays it); the set's own seed is printed."""

from __future__ import annotations

import numpy as np
import pytest

from robomach_core.learning import thresholds as th
from robomach_core.learning.part_walls import PartWalls
from robomach_core.learning.route import mean_tool_axis, taught_wall_points
from tests.envelope import part_named, replay, run_seed, set_seeds, tilted_part
from tests.people_points import people_points

SEED = run_seed()
SETS = 30  # per case; geometry only (no run): about two seconds a case
ON_WALL_MM = 0.05  # the mesh's facets against the true wall's dense polyline


def _part(case: str, rng: np.random.Generator):
    if case == "level":
        return part_named("grooved_plate")
    return tilted_part("groove", rng, how=case)


@pytest.mark.parametrize("case", ["level", "mesh", "wobj"])
def test_every_taught_wall_point_lies_on_the_wall_the_person_chose(case):
    for set_seed in set_seeds(SEED + ["level", "mesh", "wobj"].index(case), SETS):
        rng = np.random.default_rng(set_seed)
        part = _part(case, rng)
        wall = str(rng.choice(["outer", "island"]))
        cell = part.cell(set_seed % 2**32)
        pset = people_points(
            part,
            cell,
            rng,
            wall=wall,
            closed=True,
            side_mode="given",
            nearer_other=int(rng.integers(0, 9)),
        )
        where = f"{replay(SEED)}, set {set_seed}: {pset.description}"
        guides = pset.guides
        walls = PartWalls(cell.workpiece, mean_tool_axis(guides), cell.tool.radius_m)
        found = taught_wall_points(guides, pset.wall_side, pset.closed, walls)
        taught, other = part.walls[wall], part.walls[part.walls[wall].other]
        on = [k for k, p in enumerate(found) if p is not None]  # None: no wall within reach
        assert on, f"{where}: no wall point found"
        for k in on:
            p_mm = part.to_part_mm(cell.workpiece, found[k])
            d_taught = abs(float(taught.signed_distance(p_mm)[0][0]))
            d_other = abs(float(other.signed_distance(p_mm)[0][0]))
            assert d_taught <= ON_WALL_MM, (
                f"{where}: G{k + 1}'s wall point is {d_taught:.2f} mm off the taught wall "
                f"'{wall}' ({d_other:.2f} mm from '{taught.other}')"
            )


def test_a_point_whose_leg_cuts_through_the_part_keeps_the_wall_it_stands_by():
    """Round an outside edge (the T-boss), a leg's chord may cut through the part: "the way
    the wall lies" (across the chord) then points off the wall the point stands by. Every point
    taught beside its wall still gets its wall point on that wall: it is where the run starts
    and what the check measures (issue 28: 1 sloppy set in 300 started the wrong way and
    stopped, "searched 30 mm without finding the wall")."""
    part = part_named("tboss")
    for set_seed in set_seeds(SEED + 3, SETS):
        rng = np.random.default_rng(set_seed)
        cell = part.cell(set_seed % 2**32)
        pset = people_points(
            part, cell, rng, wall="boss", closed=bool(rng.random() < 0.5), side_mode="given"
        )
        where = f"{replay(SEED)}, set {set_seed}: {pset.description}"
        guides = pset.guides
        walls = PartWalls(cell.workpiece, mean_tool_axis(guides), cell.tool.radius_m)
        found = taught_wall_points(guides, pset.wall_side, pset.closed, walls)
        taught = part.walls["boss"]
        # the points beside a wall face (the foot of the nearest wall point on a face, within
        # reach), as the rule reads them: beside a corner's edge a point may get none
        pts = np.array([g.position_m for g in guides])
        _, dist, on_face = walls.feet(pts)
        beside = on_face & (dist <= th.AT_WALL_GAP_M + walls.radius)
        for k, p in enumerate(found):
            assert p is not None or not beside[k], f"{where}: G{k + 1} has no wall point"
            if p is None:
                continue
            d = abs(float(taught.signed_distance(part.to_part_mm(cell.workpiece, p))[0][0]))
            assert d <= ON_WALL_MM, f"{where}: G{k + 1}'s wall point is {d:.2f} mm off the wall"
