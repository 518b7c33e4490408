"""Issue 28's five reproducers, and open slots and clicks between walls, as properties.

Each reproducer is the scenario the issue names (its "Why" section), with what is left open
drawn per run from a fresh seed (``ROBOMACH_SEED`` replays it): where the person starts,
their gaps, which wall. Programs are measured against the true walls by the tests' own
measure (``tests.learning_outcome``); the stages are the project's (``run_demo`` where the
issue runs ``robomach demo``).
"""

from __future__ import annotations

import json
import re
import zlib

import numpy as np
import pytest

from robomach_core.cell import TOOL_DOWN
from robomach_core.errors import RouteRefusedError
from robomach_core.learning.settings import PathLearningSettings
from robomach_core.pipeline import run_demo
from robomach_core.project import CellSettings, Project
from tests.envelope import (
    DENSE_SAMPLES,
    GRID_WITHIN_MM,
    HEIGHT_MM,
    part_named,
    replay,
    run_seed,
)
from tests.envelope_parts import tilted
from tests.learning_outcome import Outcome, as_set, judge, learn_set
from tests.people_points import PeopleSet, people_points, place_points

SEED = run_seed()
BOTH_WALLS = re.compile(r"\bboth\b|\btwo walls\b|\bbetween\b", re.IGNORECASE)


def _check(ok: bool, why: str) -> None:
    """Fail with ``why`` alone (the outcome's line and the set), not the objects' reprs."""
    if not ok:
        pytest.fail(why, pytrace=False)


def _rng(*key: object) -> np.random.Generator:
    return np.random.default_rng([SEED, zlib.crc32(repr(key).encode())])


def _demo(
    part_name: str, wall: str, *, seed: int, guide_points_csv: str | None = None, **learning
) -> tuple[Outcome, object]:
    """``robomach demo`` (``run_demo``) on a built-in part, judged against ``wall``; a
    refusal before learning is the outcome "refused"."""
    part = part_named(part_name)
    settings = PathLearningSettings(**learning)
    job = Project(cell=CellSettings(workpiece=part_name, seed=seed))
    try:
        result = run_demo(job, settings, guide_points_csv=guide_points_csv)
    except RouteRefusedError as exc:
        return Outcome("refused", reason=f"refused: {exc}"), None
    r = job.cell.tool_radius_m
    pset = as_set(
        part, result.workpiece, r, result.guides, "the example operator", wall=wall,
        closed=settings.closed, side=settings.wall_side,
    )  # fmt: skip
    processed = result.project.processed
    note = f"{settings.force_N:g} N, {settings.speed_m_s * 1e3:g} mm/s"
    base = Outcome("", settings=note, description=pset.description)
    return judge(part, result.workpiece, r, pset, result.recording, processed, base), result


# --- why 1: slow feeds -----------------------------------------------------------------------


@pytest.mark.slow
@pytest.mark.parametrize(("force_N", "speed_mm_s"), [(10.0, 0.5), (20.0, 1.0)])
def test_slow_feeds_learn_the_pump_without_climbing_out_of_the_groove(force_N, speed_mm_s):
    """``robomach demo --speed 0.5`` and ``--force 20 --speed 1``: the TCP rose in 0.25-0.5 mm
    steps over the 20 mm wall top and the run stopped ("searched 30 mm"). Now: complete,
    within 0.25 mm of the true wall at the taught height, and the 0.5 mm/s recording dense
    (at least 200k samples, as it used to be)."""
    seed = int(_rng("slow", force_N, speed_mm_s).integers(2**31))
    outcome, _ = _demo(
        "water_pump", "outer", force_N=force_N, speed_m_s=speed_mm_s * 1e-3, seed=seed
    )
    why = f"{replay(SEED)} (demo seed {seed}): {outcome.line()}"
    m = outcome.measure
    _check(outcome.kind == "learned", why)
    _check(m.dev_mm <= GRID_WITHIN_MM and m.height_mm <= HEIGHT_MM, why)
    if speed_mm_s == 0.5:
        _check(outcome.samples >= DENSE_SAMPLES, why)


# --- why 2: floors that are not level --------------------------------------------------------


@pytest.mark.slow
@pytest.mark.parametrize("source", ["14 points", "proposal"])
def test_a_plate_tilted_15_deg_in_the_mesh_is_learned_with_the_tool_vertical(source):
    """A plate tilted 15 deg with a groove round an island, the tool kept vertical, taught
    with 14 points: it stopped 27 mm into the second leg (6 % of the wall); pointing at it
    proposed 11 points on a horizontal section and stopped 35 mm off. Now: 100 % of the wall
    within 0.25 mm, at the taught height (the tilt's azimuth and the start drawn per run)."""
    from tests.envelope import learn_tilted

    rng = _rng("tilted 15", source)
    part = tilted(part_named("grooved_plate"), 15.0, float(rng.uniform(0, 360)), "mesh")
    run = learn_tilted(part, "hand" if source == "14 points" else "proposal", rng)
    _check(not run.problems, f"{replay(SEED)}: {'; '.join(run.problems)}\n{run.description}")


# --- why 3: points resting on the floor ------------------------------------------------------


@pytest.mark.slow
def test_points_resting_on_the_pump_groove_floor_keep_their_height():
    """12 points on the pump's groove floor (z = 15 mm in the base frame: the cutter on the
    14 mm floor), 0.3-2.5 mm off the outer wall, led to from a CSV (``robomach demo
    --guide-points``) with the side given: the height ramped from 15.5 to 22.4 mm on one leg
    and the tool left the groove (57 % of the wall). Now: the whole wall within 0.3 mm, at
    the floor height plus the floor clearance (where along the wall drawn per run)."""
    rng = _rng("floor")
    part = part_named("water_pump")
    wall = part.walls["outer"]
    wp = part.workpiece(0)
    n = 12
    s = rng.uniform(0, wall.length_mm) + (np.arange(n) + rng.uniform(-0.4, 0.4, n)) * (
        wall.length_mm / n
    )
    rows = []
    for si, gap in zip(s, rng.uniform(0.3, 2.5, n), strict=True):
        c, t, _ = wall.at(float(si))
        xy = c + np.array([-t[1], t[0]]) * (1.0 + gap)
        x, y, _ = part.to_base_m(wp, np.array([[*xy, 14.0]]))[0] * 1e3
        rows.append(f"{x:.2f},{y:.2f},15.00")
    seed = int(rng.integers(2**31))
    outcome, _ = _demo(
        "water_pump", "outer", guide_points_csv="\n".join(rows), wall_side="right", seed=seed
    )
    why = f"{replay(SEED)} (demo seed {seed}): {outcome.line()}\n" + "\n".join(rows)
    _check(outcome.kind == "learned", why)
    _check(outcome.measure.height_mm <= HEIGHT_MM, why)


# --- why 4: the person's explicit side -------------------------------------------------------


@pytest.mark.slow
@pytest.mark.parametrize(
    ("part_name", "side"), [("narrow_groove", "right"), ("cam_groove", "left")]
)
def test_the_side_the_person_sets_wins_over_points_nearer_the_other_wall(part_name, side):
    """``--wall-side right`` with 8 sloppy points in a 3.5 mm groove, 7 of them nearer the
    other wall: the program followed the right wall within 0.207 mm over all of it, yet was
    NOT FIT "the wrong wall". The same on a cam groove with ``--wall-side left``. Now the
    setting wins: learned on the wall on that side, and no NOT FIT."""
    rng = _rng("side", part_name, side)
    part = part_named(part_name)
    wall = str(rng.choice(list(part.walls)))
    seed = int(rng.integers(2**31))
    cell = part.cell(seed)
    pset = people_points(
        part, cell, rng, wall=wall, closed=True, forward=side == "right", count=(8, 8),
        side_mode="given", nearer_other=7,
    )  # fmt: skip
    assert pset.wall_side == side
    outcome, _ = learn_set(part, cell, pset)
    why = f"{replay(SEED)}: {outcome.line()}\n{pset.description}"
    _check(not outcome.failure, why)
    _check(outcome.kind == "learned", why)


# --- why 5: wrong programs that pass ---------------------------------------------------------


@pytest.mark.slow
def test_the_s_slot_taught_without_open_is_learned_open_or_refused():
    """``robomach demo --workpiece s_groove`` without ``--open``: the closing leg ran back
    along the slot's other wall, 4.2 mm off by the project's own deviation, and exited 0 with
    no problem. Now the open wall is learned open, or refused before any motion."""
    seed = int(_rng("s_groove").integers(2**31))
    outcome, _ = _demo("s_groove", "right side", closed=True, seed=seed)
    why = f"{replay(SEED)} (demo seed {seed}): {outcome.line()}"
    _check(not outcome.failure, why)
    _check(outcome.kind in ("learned", "refused"), why)


P10_MM = [
    (715, 97, 17), (800, 97, 17), (885, 97, 17), (898, 110, 17), (898, 210, 17),
    (885, 223, 17), (800, 223, 17), (715, 223, 17), (702, 210, 17), (702, 110, 17),
]  # fmt: skip  # the pump's outer wall, 2 mm off (tests/core/learning/test_people_guide_points.py)


@pytest.mark.slow
@pytest.mark.parametrize("taught", ["pushed", "free"])
def test_the_wall_side_set_against_the_points_is_followed_and_the_points_named(taught):
    """``--wall-side left`` on points taught at the pump's outer wall (the example's, pushed
    against it; or ten free points 2 mm off it, from a CSV): the program was 3.3 mm off the
    outer wall and reported as "follows the taught wall at all 9 guide points". Now the
    setting wins: the island wall (on the left) learned within 0.3 mm and fit, with a
    warning naming the points that disagree; or refused, saying why."""
    rng = _rng("left", taught)
    seed = int(rng.integers(2**31))
    csv = None
    if taught == "free":
        jitter = rng.uniform(-1.0, 1.0, (len(P10_MM), 2))
        csv = "\n".join(f"{x + dx:.2f},{y + dy:.2f},{z}" for (x, y, z), (dx, dy) in zip(
            P10_MM, jitter, strict=True))  # fmt: skip
    outcome, result = _demo(
        "water_pump", "island", wall_side="left", seed=seed, guide_points_csv=csv
    )
    why = f"{replay(SEED)} (demo seed {seed}): {outcome.line()}"
    _check(not outcome.failure, why)
    _check(outcome.kind in ("learned", "refused"), why)
    if outcome.kind == "learned":  # the points against the setting are named: in the
        # summary the CLI prints from, or by the checks the workbench shows before learning
        from robomach_core.learning.checks import guide_point_warnings
        from robomach_core.learning.run import PathLearningSettings

        texts = _strings(result.summary())
        named = [t for t in texts if re.search(r"\bG\d+\b", t) and "follows the" not in t]
        found = guide_point_warnings(
            result.guides,
            PathLearningSettings(wall_side="left"),
            workpiece=result.workpiece.cad(),
            tool_radius_m=result.project.cell.tool_radius_m,
        )
        named += [w.message for w in found if w.point >= 1 and w.severity == "warning"]
        assert named, f"no warning names the points taught at the outer wall: {why}\n{texts}"


def _strings(value: object) -> list[str]:
    """Every string in a summary document (nested dicts and lists)."""
    if isinstance(value, str):
        return [value]
    if isinstance(value, dict):
        return [s for v in value.values() for s in _strings(v)]
    if isinstance(value, (list, tuple)):
        return [s for v in value for s in _strings(v)]
    return []


@pytest.mark.slow
def test_a_click_on_a_plate_edge_keeps_its_height_or_the_terminal_says_why(tmp_path):
    """A click at z = 17 mm on a plate's edge was learned at z = 5 mm and said so only in
    summary.json. Now the height is kept, or the terminal says the change and its reason."""
    from tests.cli import robomach_here

    part = part_named("grooved_plate")
    stl = tmp_path / "plate.stl"
    stl.write_bytes(part.mesh_file()[1])
    y = float(_rng("edge").uniform(-40.0, 40.0))
    proc = robomach_here(
        "demo", "--out", str(tmp_path / "out"), "--no-plot", "--workpiece", str(stl),
        "--propose-guide-points", f"80,{y:.1f},17", "--speed", "10",
    )  # fmt: skip
    assert proc.returncode == 0, proc.stderr[-3000:]
    summary = json.loads((tmp_path / "out" / "summary.json").read_text())
    height = summary["proposed_guide_points"]["height_wobj_mm"]
    if abs(height - 17.0) > HEIGHT_MM:
        said = [line for line in proc.stdout.splitlines() if "height" in line and "mm" in line]
        assert said, f"learned at z = {height} mm, not 17, without a word:\n{proc.stdout}"


# --- open slots taught as loops, and clicks between two walls --------------------------------


@pytest.mark.slow
@pytest.mark.parametrize("part_name", ["s_groove", "s_slot"])
def test_an_open_slot_taught_as_a_loop_is_learned_open_or_refused(part_name):
    """Sloppy points along one side of an S-slot (flat ends, or running out of the plate),
    learned with the route closed: learned open along the taught side within 0.3 mm, or
    refused before any motion; never a closing leg along the other side without NOT FIT."""
    rng = _rng("slot", part_name)
    part = part_named(part_name)
    wall = str(rng.choice(list(part.walls)))
    seed = int(rng.integers(2**31))
    cell = part.cell(seed)
    pset = people_points(
        part, cell, rng, wall=wall, closed=False, learn_closed=True,
        side_mode=str(rng.choice(["given", "auto"])),
    )  # fmt: skip
    outcome, _ = learn_set(part, cell, pset)
    why = f"{replay(SEED)}: {outcome.line()}\n{pset.description}"
    _check(not outcome.failure, why)
    _check(outcome.kind in ("learned", "refused"), why)


@pytest.mark.slow
@pytest.mark.parametrize("spread_mm", [0.0, 0.03])
def test_points_between_the_two_walls_of_a_narrow_groove_are_refused_naming_both(spread_mm):
    """Points halfway between the walls of a 3.5 mm groove (the cutter 0.75 mm from each,
    exactly, as a centred click puts it, or within +-0.03 mm of it), the side left to
    "auto": one wall was learned with no word. Now refused before any motion, the message
    naming both walls."""
    rng = _rng("between", spread_mm)
    part = part_named("narrow_groove")
    wall_name = str(rng.choice(list(part.walls)))
    wall = part.walls[wall_name]
    seed = int(rng.integers(2**31))
    cell = part.cell(seed)
    r_mm = cell.tool.radius_m * 1e3
    n = int(rng.integers(6, 11))
    s = (rng.uniform(0, wall.length_mm) + np.arange(n) * wall.length_mm / n) % wall.length_mm
    gaps = (wall.free_mm - 2 * r_mm) / 2 + rng.uniform(-spread_mm, spread_mm, n)
    floors = np.array([wall.at(float(x))[2] for x in s])
    heights = rng.uniform(floors + r_mm + 0.5, wall.top_mm - 1.0)
    guides, kept, lines = place_points(
        part, cell, wall_name, s, gaps, heights, [TOOL_DOWN] * n, rng
    )
    pset = PeopleSet(
        guides, part.name, wall_name, True, "auto", "right", s[kept], heights[kept],
        "\n".join([f"{n} points half way across the {wall.free_mm} mm groove", *lines]),
    )  # fmt: skip
    outcome, _ = learn_set(part, cell, pset)
    why = f"{replay(SEED)}: {outcome.line()}\n{pset.description}"
    _check(outcome.kind == "refused", why)
    _check(bool(BOTH_WALLS.search(outcome.reason)), why)
