"""Path learning over the envelope a user can set (issue 28): properties over generated cases.

Every run draws its own cases from a fresh seed (``ROBOMACH_SEED`` replays a run; each
failure prints it, and a sloppy set's own seed, which ``python -m tests.envelope --one SEED``
replays alone). The programs are measured against the parts' true walls by the tests' own
measure (``tests.learning_outcome``), not the product's score; the stages are the project's.

- the force x speed grid on the pump and the block, from the example operator's points: a
  few cells per run (the script runs all 36);
- tilted plates (10-20 deg; in the mesh with the tool vertical, by the work object with the
  tool normal), a groove and an outside edge, from a careful person's points and from a
  proposal;
- sloppy sets over eight part families: a sample per run (the script runs 300).
"""

from __future__ import annotations

import zlib

import numpy as np
import pytest

from tests.envelope import (
    GRID_FORCES_N,
    GRID_PARTS,
    GRID_SPEEDS_MM_S,
    grid_problems,
    replay,
    run_grid_cell,
    run_seed,
    run_sloppy_set,
    run_tilted_case,
    set_seeds,
)

SEED = run_seed()
GRID_DRAWS = 3  # the first always the pump at 0.5, 1 or 2 mm/s
SLOPPY_SAMPLE = 12  # about a minute of CPU once compiled
SLOPPY_HALVES = 2  # run in parallel, six sets each


def _rng(*key: object) -> np.random.Generator:
    """The run's generator for one test's draws (stable across processes, unlike hash())."""
    return np.random.default_rng([SEED, zlib.crc32(repr(key).encode())])


# --- (a) the force x speed grid -------------------------------------------------------------


def _grid_cell(k: int) -> tuple[str, float, float]:
    rng = _rng("grid", k)
    force = float(rng.choice(GRID_FORCES_N))
    if k == 0:  # the pump slow (the reproducers run 10 N at 0.5 and 20 N at 1 mm/s)
        return "water_pump", force, float(rng.choice(GRID_SPEEDS_MM_S[:3]))
    return str(rng.choice(GRID_PARTS)), force, float(rng.choice(GRID_SPEEDS_MM_S))


@pytest.mark.slow
@pytest.mark.parametrize("k", range(GRID_DRAWS))
def test_a_cell_of_the_force_speed_grid_learns_the_whole_wall_within_a_quarter_mm(k):
    """Any force in 10-20 N at any speed of the grid (0.5-20 mm/s), from the example
    operator's points: complete, within 0.25 mm of the true wall, at the taught height, and
    at 0.5 mm/s a recording of at least 200k samples on the pump. (Issue 28, why 1: six of
    the pump's cells at 0.5-2 mm/s climbed out of the groove.)"""
    part, force, speed = _grid_cell(k)
    outcome = run_grid_cell(part, force, speed, SEED % 2**32)
    problems = grid_problems(part, speed, outcome)
    if problems:
        pytest.fail(
            f"{replay(SEED)}: {part} at {force:g} N, {speed:g} mm/s: {'; '.join(problems)}\n"
            f"{outcome.line()}"
        )


# --- (b) tilted plates ----------------------------------------------------------------------


@pytest.mark.slow
@pytest.mark.parametrize("source", ["hand", "proposal"])
@pytest.mark.parametrize("kind", ["groove", "boss"])
@pytest.mark.parametrize("how", ["mesh", "wobj"])
def test_a_tilted_plate_is_learned_along_all_its_wall_within_a_quarter_mm(how, kind, source):
    """A plate tilted 10-20 deg about any horizontal axis, in the mesh (the job's tool axis
    vertical) or by the work object (the tool normal to it); a groove round an island (either
    wall) or an outside edge (an L-shaped boss, sharp corners); from a careful person's 14
    points or from pointing at the wall: 100 % of the wall within 0.25 mm, at the taught
    height relative to the part. (Why 2: 6 % of the wall, and a proposal on a horizontal
    section 207 mm long.)"""
    run = run_tilted_case(how, kind, source, _rng("tilted", how, kind, source))
    if run.problems:
        pytest.fail(f"{replay(SEED)}: {'; '.join(run.problems)}\n{run.description}")


# --- (c) sloppy sets ------------------------------------------------------------------------


@pytest.mark.slow
@pytest.mark.parametrize("half", range(SLOPPY_HALVES))
def test_sloppy_sets_learn_their_taught_wall_or_are_refused_saying_why(half):
    """Sets as people leave them, on drawn parts (pump, block, T-boss, tilted groove or boss,
    stepped floor, cam groove, S-slot): learned completely within 0.3 mm of the taught wall,
    or refused before any motion with the reason. Never another wall (or the floor, or a
    slot's closing leg) without NOT FIT, never NOT FIT on the taught wall, never an error: any
    one fails the test. The acceptance is 99 % fine over 300 sets (``python -m tests.envelope``;
    599 of 600 on the current model): a set that stops saying why, or is flagged NOT FIT off
    its wall, is within it, so one such in a half's sample passes (two in either half: 1 run
    in 1,300 at 0.5 %); each is printed with its replay."""
    seeds = set_seeds(SEED, SLOPPY_SAMPLE)[half::SLOPPY_HALVES]
    honest = []
    for seed in seeds:
        run = run_sloppy_set(seed)
        why = (
            f"{replay(SEED)}, set {seed} (python -m tests.envelope --one {seed}), "
            f"{run.family}: {run.outcome.line()}\n{run.outcome.description}"
        )
        if run.outcome.failure or run.outcome.kind == "error":
            pytest.fail(("FAILURE: " if run.outcome.failure else "") + why)
        if not run.outcome.fine:
            print(f"not fine (stopped or flagged, saying why): {why}")
            honest.append(why)
    assert len(honest) <= 1, "\n\n".join(honest)
