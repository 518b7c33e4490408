"""A staged controller's stage schedule planned offline (``machining.schedule``, issue 29):
offline compensation under fuzzy and two-stage cuts the wall error like the unstaged
controllers on generated stocks, the row's cut is the schedule whatever the cell's noise draw,
and the schedule is the lowest stage of the draws at every station, switching where planned.

Fresh stocks every run (``tests.envelope.run_seed``; replay a failure with the printed
ROBOMACH_SEED)."""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from robomach_core.machining import (
    MachiningSettings,
    builtin_stock,
    identify_stiffness,
    run_machining,
)
from robomach_core.machining.program import SPEED_QUANTUM_M_S
from robomach_core.machining.run import cut_program, plan_cut
from robomach_core.machining.schedule import (
    STAGED_CONTROLLERS,
    scheduled_program,
    stage_ratio_met,
)
from robomach_core.transforms import arc_length_m
from tests.envelope import replay, run_seed

# Share of the uncompensated wall error offline compensation must cut on a generated stock:
# the chapter asks 75 %. Measured on the short program (40 stocks, 2026-12-05): with the
# schedule 94.1-96.6 % under either staged controller; switching online (before issue 29's
# schedule) 51.9-95.8 %, under 85 % on 10 of 22 stocks. Asserted at 85 %, so the old code
# fails on most runs of three stocks and the schedule never does.
CUT_AT_LEAST = 0.85
STOCKS_PER_RUN = 3


@pytest.fixture(scope="module")
def model(robot):
    return identify_stiffness(robot.name, seed=0).model


def _stocks(short_program, seed: int):
    rng = np.random.default_rng(seed)
    for _ in range(STOCKS_PER_RUN):
        stock = builtin_stock(short_program.position_m, seed=int(rng.integers(2**31)))
        yield replace(stock, material_factor=float(rng.uniform(0.9, 1.1))), int(rng.integers(2**31))


def test_offline_compensation_cuts_85_percent_under_the_staged_controllers(
    robot, short_program, model
):
    """Fuzzy and two-stage, offline, on generated stocks and noise draws: the wall error cut
    by >= 85 % (the chapter's 75 % with room), as the unstaged controllers do. A stock whose
    nominal wall the controller's protection rule stops on (the arm held rigid on a burr the
    yielding arm rode over) has no schedule and no correction to judge: not compared."""
    seed = run_seed()
    print(f"{replay(seed)}")
    for stock, noise in _stocks(short_program, seed):
        for controller in STAGED_CONTROLLERS:
            off, offline = (
                run_machining(
                    robot, short_program, None, stock,
                    MachiningSettings(
                        controller=controller, compensation=mode, seed=noise, stages="planned"
                    ),
                    compensation_model=model,
                ).summary
                for mode in ("off", "offline")
            )  # fmt: skip
            if not off["completed"] or not offline["offline_nominal_wall_completed"]:
                print(f"{replay(seed)}: {controller} stops on this stock's nominal wall")
                continue
            assert offline["feed"] == "program"  # the row runs the schedule
            assert offline["wall_error_max_mm"] <= (1 - CUT_AT_LEAST) * off["wall_error_max_mm"], (
                replay(seed), controller, off["wall_error_max_mm"], offline["wall_error_max_mm"],
            )  # fmt: skip


def test_the_rows_cut_is_the_schedule_whatever_the_cells_noise(robot, short_program, model):
    """No online switching in the row's cut: the corrected program cut again on another noise
    draw of the cell gives the very same cut (trace and wall), so the force the correction
    was planned for is the force it meets; its speeds are the program's (the ratio is 1)."""
    seed = run_seed()
    print(f"{replay(seed)}")
    for stock, noise in _stocks(short_program, seed):  # the first stock with a schedule
        s = MachiningSettings(
            controller="two-stage", compensation="offline", seed=noise, stages="planned"
        )
        run = run_machining(robot, short_program, None, stock, s, compensation_model=model)
        if run.summary["feed"] == "program":
            break
        print(f"{replay(seed)}: every cut of this stock's nominal wall stopped; no schedule")
    else:
        raise AssertionError(f"{replay(seed)}: no stock of {STOCKS_PER_RUN} has a schedule")
    again = cut_program(
        robot, run.program, None, stock, replace(s, seed=noise + 1), nominal=run.nominal,
        feed="program",
    )  # fmt: skip
    for name in ("path_m", "feed_m_s", "force_N", "tool_normal_m"):
        np.testing.assert_array_equal(getattr(again.trace, name), getattr(run.trace, name))
    assert np.all(run.trace.speed_ratio == 1.0)
    assert again.summary["wall_error_max_mm"] == run.summary["wall_error_max_mm"]


@given(
    draws=st.lists(
        st.lists(st.sampled_from([0.2, 0.4, 0.6, 0.8, 1.0]), min_size=1, max_size=10),
        min_size=1,
        max_size=4,
    ),
    seed=st.integers(0, 2**31 - 1),
)
@settings(max_examples=30, deadline=None)
def test_the_schedule_is_the_lowest_stage_of_the_draws_where_they_ran_it(
    robot, short_program, draws, seed
):
    """Each draw's stage per station is the least ratio its samples ran there (a station no
    sample fell in: the lesser neighbour); the schedule is their minimum, and the program's
    speed at each station, as the cut maps it, is that stage x the learned speed rounded down
    to 0.01 mm/s: never above it, and switching at the very station planned."""
    print(f"seed {seed} draws {draws}")
    rng = np.random.default_rng(seed)
    stock = builtin_stock(short_program.position_m, seed=0)
    s_st = plan_cut(robot, short_program, None, stock, MachiningSettings()).s_st
    ds = float(s_st[1] - s_st[0])
    # The stages change along the program; the stations past its last target (the loop never
    # reaches them) keep the last stage, as a cut's trace gives them.
    inside = int(np.sum(s_st <= arc_length_m(short_program.position_m)[-1]))
    per_draw = []
    for stages in draws:
        cuts = np.sort(rng.integers(0, inside, len(stages) - 1))
        truth = np.asarray(stages)[np.searchsorted(cuts, np.arange(len(s_st)), side="right")]
        # Samples at 1-3 per station, some stations skipped; the ratio between stations is
        # what the loop runs there (station floor(s / ds)).
        path = np.sort(rng.uniform(0.0, s_st[-1] + ds * 0.999, 2 * len(s_st)))
        ratio = truth[np.clip(np.floor(path / ds).astype(int), 0, len(s_st) - 1)]
        met = stage_ratio_met(path, ratio, s_st)
        station = np.clip(np.floor(path / ds).astype(int), 0, len(s_st) - 1)
        least = np.full(len(s_st), np.inf)
        np.minimum.at(least, station, ratio)
        seen = np.isfinite(least)
        np.testing.assert_array_equal(met[seen], least[seen])
        assert np.all(met >= truth.min()) and np.all(met <= truth.max())
        per_draw.append(met)
    schedule = np.min(per_draw, axis=0)
    program = scheduled_program(short_program, s_st, schedule)

    def station_speed(targets) -> np.ndarray:
        s_t = arc_length_m(targets.position_m)
        seg = np.clip(np.searchsorted(s_t, s_st, side="left"), 1, len(s_t) - 1)
        return np.asarray(targets.speed_m_s, dtype=float)[seg]

    planned = schedule * station_speed(short_program)
    runs = station_speed(program)
    assert np.all(runs <= planned + 1e-12)
    assert np.all(runs > planned - SPEED_QUANTUM_M_S - 1e-12)
