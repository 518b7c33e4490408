"""Which wall a guide point was taught on (``route.taught_wall_points``), the one answer the
taught-wall check and the run's side share: over generated grooves, level and tilted 10-20 deg
(in the mesh with the tool vertical, by the work object with the tool normal) and with a floor
stepping across the groove, with the person's side given and points drawn anywhere across the
groove, up to nearer the other wall than the taught one. Every wall point found must lie on the
taught wall, never the one across: a point found on the other wall is a good program condemned
(issue 28: on a plate tilted in its mesh, a ray cast straight across the tool axis at an
island's corner left the groove under its floor, and the check took the nearer wall across; on
a stepped floor, a riser across the groove met by the fan's outermost ray was taken for the
wall, and a program within 0.184 mm of it was NOT FIT).

A fresh seed each run (``ROBOMACH_SEED`` replays it); the set's own seed is printed."""

from __future__ import annotations

import numpy as np
import pytest

from robomach_core.learning import thresholds as th
from robomach_core.learning.part_walls import PartWalls
from robomach_core.learning.route import mean_tool_axis, taught_wall_points
from tests.envelope import part_named, replay, run_seed, set_seeds, tilted_part
from tests.learning_outcome import planned_or_refused
from tests.people_points import people_points

SEED = run_seed()
SETS = 30  # per case; geometry only (no run): about two seconds a case
ACROSS_SETS = 12  # with the route planned and walked: about a second a set
# Draws for the across-the-chord property: a station 60 deg or more off its chord is drawn in
# one set of two on the pump, but on the rounded plate only 2 of 12 drew one in one run in
# about 15, and the property then failed for having exercised too few, not for a wrong wall.
ACROSS_DRAWS = 4 * ACROSS_SETS
ACROSS_EXERCISED = 3 * ACROSS_SETS // 4  # sets drawn until this many exercise it (about as many
# as 12 draws gave on average before)
ON_WALL_MM = 0.05  # the mesh's facets against the true wall's dense polyline


CASES = ("level", "mesh", "wobj", "stepped")


def _part(case: str, rng: np.random.Generator):
    if case == "level":
        return part_named("grooved_plate")
    if case == "stepped":  # 2 mm risers across the groove: walls a fan's ray may meet
        return part_named("stepped_groove")
    return tilted_part("groove", rng, how=case)


@pytest.mark.parametrize("case", CASES)
def test_every_taught_wall_point_lies_on_the_wall_the_person_chose(case):
    """On the stepped floor, as the check asks it after a run: at the heights the route learns
    the points at (a point taught 1 mm over the low floor, its cutter pressed into a riser, is
    lifted over the step) and with the walk's travel past each point."""
    from robomach_core.learning.run import PathLearningSettings

    stepped = case == "stepped"
    for set_seed in set_seeds(SEED + CASES.index(case), ACROSS_SETS if stepped else SETS):
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
        lifted = travel = None
        if stepped:
            settings = PathLearningSettings(closed=pset.closed, wall_side=pset.wall_side)
            route = planned_or_refused(guides, cell, settings, where)
            if route is None:
                continue  # refused before any motion, with the reason: not a wrong wall
            lifted, travel = route.lifted_m, route.guide_travel
        found = taught_wall_points(guides, pset.wall_side, pset.closed, walls, lifted, travel)
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


def _most_across(wall, s_prev: float, s_next: float) -> tuple[float, float]:
    """The station between two others where the wall's own direction is farthest off the chord
    joining them, and that angle [deg]."""
    a, _, _ = wall.at(s_prev)
    b, _, _ = wall.at(s_next)
    chord = (b - a) / max(float(np.linalg.norm(b - a)), 1e-9)
    s = np.linspace(s_prev, s_next, 400)[5:-5]
    cos = np.array([float(wall.at(float(v))[1] @ chord) for v in s])
    k = int(np.argmin(cos))
    return float(s[k]), float(np.degrees(np.arccos(np.clip(cos[k], -1.0, 1.0))))


@pytest.mark.parametrize("part_name", ["water_pump", "grooved_plate"])
def test_a_point_where_the_wall_runs_across_its_chord_keeps_the_taught_wall(part_name):
    """A point taught at a jog, bay or corner of the wall between neighbours far along it, so
    the chord through its neighbours runs across the wall there (60 deg or more off it, up to
    against it): "the way the wall lies" across that chord points along the groove, at its
    other wall as often as not. The route's walk past the point gives its travel
    (``LearningRoute.guide_travel``), and every wall point is on the taught wall (issue 28: a
    good program on the pump's outer wall was condemned for "the other wall" at such a point, 1
    set in 1,500). The first point is neither moved nor judged: the walk starts from the wall
    its chord gives (a known limit, docs/learning_model.md)."""
    from robomach_core.learning.run import PathLearningSettings
    from tests.people_points import nominal_rotation, place_points

    part = part_named(part_name)
    exercised = 0
    for set_seed in set_seeds(SEED + 4 + (part_name == "grooved_plate"), ACROSS_DRAWS):
        if exercised == ACROSS_EXERCISED:
            break  # drawn until this many sets exercised the property
        rng = np.random.default_rng(set_seed)
        name = str(rng.choice(["outer", "island"])) if part_name == "grooved_plate" else "outer"
        wall = part.walls[name]
        L = wall.length_mm
        cell = part.cell(set_seed % 2**32)
        n = int(rng.integers(5, 9))
        s = np.sort(rng.uniform(0.0, L, n))
        k = int(rng.integers(1, n))  # moved to where the wall runs across its chord (not the
        # first point: the walk starts from the wall its chord gives, docs/learning_model.md)
        s[k], angle = _most_across(wall, s[k - 1], s[(k + 1) % n] + (L if k == n - 1 else 0.0))
        if angle < 60.0:
            continue
        r_mm = cell.tool.radius_m * 1e3
        free = wall.free_mm if wall.free_mm is not None else 6.0
        gaps = rng.uniform(0.0, max(0.1, min(2.0, (free - 2 * r_mm) / 2 - 0.3)), n)
        heights = np.array([wall.at(float(v))[2] for v in s]) + r_mm + rng.uniform(0.5, 3.0, n)
        rotations = [nominal_rotation(part, cell)] * n
        guides, kept, _ = place_points(part, cell, name, s % L, gaps, heights, rotations, rng)
        if k not in kept or len(guides) < 4:
            continue
        settings = PathLearningSettings(closed=True, wall_side="right")
        route = planned_or_refused(guides, cell, settings, f"{replay(SEED)}, set {set_seed}")
        if route is None:
            continue  # refused before any motion, with the reason: not a wrong wall
        exercised += 1
        walls = PartWalls(cell.workpiece, route.axis, cell.tool.radius_m)
        found = taught_wall_points(guides, "right", True, walls, route.lifted_m, route.guide_travel)
        at = kept.index(k)
        where = (
            f"{replay(SEED)}, set {set_seed}: G{at + 1} at s={s[k] % L:.0f} mm of '{name}', "
            f"{angle:.0f} deg off its chord"
        )
        assert found[at] is not None, f"{where}: no wall point"
        for j, p in enumerate(found[1:], start=1):  # the first: the walk's start (see above)
            if p is not None:
                d = abs(float(wall.signed_distance(part.to_part_mm(cell.workpiece, p))[0][0]))
                assert d <= ON_WALL_MM, f"{where}: G{j + 1}'s wall point is {d:.2f} mm off it"
    assert exercised >= ACROSS_SETS // 4, f"{replay(SEED)}: only {exercised} sets exercised"
