"""The machining run on a program along the water pump's true wall: physics invariants,
compensation, the finished wall, errors, progress and cancel."""

from __future__ import annotations

import threading
from dataclasses import replace

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from robomach_core.cell import true_joint_compliance
from robomach_core.errors import CancelledError
from robomach_core.machining import (
    MachiningSettings,
    SampleLimitError,
    StockError,
    builtin_stock,
    identify_stiffness,
    run_machining,
    stock_from_profile,
)
from robomach_core.machining.run import cut_program, finished_wall

MM = 1e-3


@pytest.fixture(scope="module")
def short_stock(short_program):
    return builtin_stock(short_program.position_m, seed=0)


def test_no_stock_means_no_force_no_deflection_and_a_perfect_wall(robot, short_program):
    # A noise-free sensor: online compensation would otherwise follow the noise (micrometres).
    stock = stock_from_profile(short_program.position_m, [(0.0, 0.0)])
    for mode in ("off", "offline", "online"):
        run = run_machining(
            robot,
            short_program,
            None,
            stock,
            MachiningSettings(compensation=mode, sensor_noise_N=0.0),
        )
        assert np.all(run.trace.force_N == 0.0)
        assert np.all(run.trace.deflection_m == 0.0)
        # Compensation is zero at zero load: the tool runs on the nominal wall.
        assert np.max(np.abs(run.trace.tool_normal_m)) == 0.0
        assert run.summary["wall_error_max_mm"] == 0.0


def test_constant_feed_keeps_the_force_limit_and_bends_the_arm_off_the_wall(
    robot, short_program, short_stock
):
    run = run_machining(
        robot, short_program, None, short_stock, MachiningSettings(controller="constant")
    )
    s = run.summary
    assert s["completed"]
    feed = s["constant_feed_mm_s"]
    # The greatest safe feed, rounded down to the 0.01 mm/s every exported program writes.
    expected = MachiningSettings().safe_constant_feed_m_s(short_stock.max_allowance_m) / MM
    assert expected - 0.01 < feed <= expected and round(feed * 100) == pytest.approx(feed * 100)
    assert np.all(run.program.speed_m_s <= feed * MM + 1e-12)
    # The deflection only makes the cut shallower: the limit holds (up to the lag's ripple).
    assert s["force_peak_N"] <= 1.01 * s["force_limit_N"]
    # The force pushes the tool off the wall: material is left, never overcut.
    assert s["material_left_max_mm"] > 0.01 and s["overcut_max_mm"] == 0.0
    # Deflection follows the true compliance: about 1 um per newton at this pose.
    loaded = run.trace.force_N > 50
    ratio = run.trace.deflection_m[loaded] / run.trace.force_N[loaded]
    assert 1e-7 < ratio.min() and ratio.max() < 3e-6
    # Where the stock was thicker than the deflection, the tool's own pass bounds the wall:
    # never above where its edge was, never below the nominal wall (the force pushes off it).
    deep = run.trace.depth_m > 0.5 * MM
    left = run.trace.wall_error_m[deep]
    # (Within one 0.1 mm station the deflection varies by less than a micrometre.)
    assert np.all(left <= run.trace.deflection_m[deep] + 1e-6) and np.all(left >= 0.0)
    assert s["wall_error_max_mm"] == pytest.approx(s["deflection_max_mm"], rel=0.1)


@pytest.mark.parametrize("mode", ["offline", "online"])
def test_compensation_removes_most_of_the_deflection_error(robot, short_program, short_stock, mode):
    model = identify_stiffness(robot.name, seed=0).model
    off = run_machining(robot, short_program, None, short_stock, MachiningSettings())
    on = run_machining(
        robot,
        short_program,
        None,
        short_stock,
        MachiningSettings(compensation=mode),
        compensation_model=model,
    )
    assert on.summary["wall_error_max_mm"] < 0.3 * off.summary["wall_error_max_mm"]
    assert on.stiffness_model is model


def test_the_identified_stiffness_is_close_to_but_not_the_truth(robot):
    ident = identify_stiffness(robot.name, seed=0)
    k = np.asarray(ident.model.stiffness_Nm_rad)
    truth = np.asarray(true_joint_compliance(robot.name).stiffness_Nm_rad)
    assert not np.array_equal(k, truth)
    assert np.max(np.abs(k[:5] / truth[:5] - 1.0)) < 0.3


def test_finished_wall_is_the_ball_envelope_clipped_by_the_stock():
    ds, r = 0.1 * MM, 1.0 * MM
    s_st = np.arange(101) * ds
    allowance = np.full(101, 0.5 * MM)
    # The tool sits 0.2 mm off the wall everywhere except one sample 0.1 mm into it at 5 mm.
    path = np.arange(0, 101) * ds
    h = np.full(101, 0.2 * MM)
    h[50] = -0.1 * MM
    wall = finished_wall(s_st, allowance, path, h, r)
    assert wall.finished_m[50] == pytest.approx(-0.1 * MM)
    # One station further the ball's surface is r - sqrt(r^2 - ds^2) higher.
    assert wall.finished_m[51] == pytest.approx(-0.1 * MM + r - np.sqrt(r**2 - ds**2))
    assert wall.finished_m[0] == pytest.approx(0.2 * MM)
    # Where the tool stayed above the stock, the stock remains.
    wall = finished_wall(s_st, allowance, path, np.full(101, 0.8 * MM), r)
    assert wall.finished_m == pytest.approx(allowance)


def test_a_stock_on_another_path_is_refused(robot, short_program, wall_program):
    stock = builtin_stock(wall_program.position_m, seed=0)
    with pytest.raises(StockError, match="build the stock on the program's path"):
        run_machining(robot, short_program, None, stock, MachiningSettings())


def test_a_run_over_the_sample_cap_is_refused_before_it_starts(robot, short_program, short_stock):
    settings = MachiningSettings(controller="constant", constant_feed_m_s=1e-4, max_samples=1000)
    with pytest.raises(SampleLimitError, match="more than the cap of 1000"):
        run_machining(robot, short_program, None, short_stock, settings)


def test_progress_rises_to_one_and_cancel_stops_the_run(robot, short_program, short_stock):
    """A cut runs compiled in a few milliseconds: it reports when it is done, and a cancel
    stops it before it starts; offline compensation reports each rehearsal and stops between
    them. The reference loop checks the flag as it goes."""
    seen: list[float] = []
    run_machining(
        robot, short_program, None, short_stock, MachiningSettings(), progress=seen.append
    )
    assert seen[-1] == 1.0 and np.all(np.diff(seen) >= 0.0)
    seen.clear()
    offline = MachiningSettings(compensation="offline")
    run_machining(robot, short_program, None, short_stock, offline, progress=seen.append)
    assert seen[-1] == 1.0 and np.all(np.diff(seen) >= 0.0) and len(seen) >= 2
    flag = threading.Event()

    def stop_after_the_first(fraction: float) -> None:
        if fraction > 0.0:
            flag.set()

    with pytest.raises(CancelledError):
        run_machining(
            robot, short_program, None, short_stock, offline, progress=stop_after_the_first,
            cancel=flag,
        )  # fmt: skip
    flag = threading.Event()
    flag.set()
    with pytest.raises(CancelledError):
        run_machining(robot, short_program, None, short_stock, MachiningSettings(), cancel=flag)
    with pytest.raises(CancelledError):
        cut_program(
            robot, short_program, None, short_stock, MachiningSettings(), cancel=flag,
            compiled=False,
        )  # fmt: skip


def test_summary_and_trace_carry_units_and_the_same_samples(robot, short_program, short_stock):
    run = run_machining(robot, short_program, None, short_stock, MachiningSettings())
    keys = {
        "controller", "compensation", "cycle_time_s", "force_peak_N", "force_limit_N",
        "force_rms_error_N", "wall_error_max_mm", "wall_error_rms_mm",
        "wall_error_max_at_path_mm", "material_left_max_mm", "overcut_max_mm",
        "mrr_mean_mm3_s", "realtime_factor",
    }  # fmt: skip
    assert keys <= set(run.summary)
    n = len(run.trace)
    for name in run.trace.__dataclass_fields__:
        assert getattr(run.trace, name).shape == (n,)
    assert run.summary["cycle_time_s"] == pytest.approx(run.trace.time_s[-1])
    assert run.trace.path_m[-1] >= run.wall.s_m[-1] - 0.1 * MM - 1e-9 or run.summary["completed"]


def test_offline_program_moves_the_targets_against_the_predicted_force(
    robot, short_program, short_stock
):
    """The corrected targets sit -n^T C_hat u F_pred from the nominal path, inside the wall."""
    from robomach_core.machining.path import wall_normals_from_path
    from robomach_core.stiffness import CompensationSettings

    ident = identify_stiffness(robot.name, seed=0)
    settings = CompensationSettings(robot.name, ident.model.stiffness_Nm_rad, mode="offline")
    run = run_machining(
        robot,
        short_program,
        None,
        short_stock,
        MachiningSettings(compensation="offline", controller="constant"),
        compensation_model=settings,
    )
    assert run.stiffness_model == ident.model
    program, nominal = run.program, run.nominal
    assert len(program) == len(nominal) > len(short_program)  # targets where the force changes
    assert run.summary["rehearsals"] >= 1
    from robomach_core.transforms import arc_length_m

    n = wall_normals_from_path(nominal.position_m)
    shift = np.einsum("ij,ij->i", program.position_m - nominal.position_m, n)
    s = arc_length_m(nominal.position_m)
    deep = short_stock.allowance_m(s) > 1.0 * MM
    assert np.all(shift[deep] < -5e-6)  # into the wall, micrometres to a tenth of a mm
    assert np.all(shift > -0.3 * MM)
    # Planned from the cut: each deep target moves by about the deflection the force met there.
    met = np.interp(s, run.trace.path_m, run.trace.deflection_m)
    assert np.median(np.abs(-shift[deep] - met[deep])) < 0.15 * np.median(met[deep])
    assert np.max(np.abs(program.joints_rad - nominal.joints_rad)) < 1e-3


@pytest.mark.parametrize("burr_mm", [6.0, 8.0])
def test_offline_says_when_the_nominal_wall_itself_stops_the_controller(
    robot, short_program, short_stock, burr_mm
):
    """A burr the fuzzy controller's protection rule stops at even on the yielding arm stops it
    on the nominal wall too (a deeper cut): the offline row stops, and its summary says the
    nominal wall's own cut stopped (not the compensation); on the ordinary stock it completes."""
    model = identify_stiffness(robot.name, seed=0).model
    burr = stock_from_profile(
        short_program.position_m,
        [(0, 0), (5, 1.0), (40, 1.0), (42, burr_mm), (46, burr_mm), (48, 1.0)],
    )
    fuzzy = MachiningSettings(controller="fuzzy")
    assert not run_machining(robot, short_program, None, burr, fuzzy).summary["completed"]
    offline = replace(fuzzy, compensation="offline")
    stopped = run_machining(robot, short_program, None, burr, offline, compensation_model=model)
    assert not stopped.summary["completed"]
    assert stopped.summary["offline_nominal_wall_completed"] is False
    ordinary = run_machining(
        robot, short_program, None, short_stock, offline, compensation_model=model
    )
    assert ordinary.summary["completed"]
    assert ordinary.summary["offline_nominal_wall_completed"] is True


@given(seed=st.integers(0, 2**63 - 1))
@settings(max_examples=3, deadline=None)
def test_each_rehearsal_cuts_a_noise_draw_of_its_own_and_the_program_the_settings_one(
    robot, short_program, short_stock, seed
):
    """Offline compensation plans from rehearsals the corrected program's cut never replays:
    every rehearsal (the nominal wall's cut included) meets a sensor-noise draw of its own,
    none the settings' seed, and the corrected program (the table's row) meets the settings'
    draw, as a cell meets one no rehearsal saw. The same seed gives the same run."""
    import robomach_core.machining.run as run_module

    print(f"seed {seed}")
    model = identify_stiffness(robot.name, seed=0).model
    settings_ = MachiningSettings(controller="two-stage", compensation="offline", seed=seed)
    seeds: list[int] = []
    loop = run_module.run_loop

    def spy(inputs, *args, **kwargs):
        seeds.append(int(inputs.seed))
        return loop(inputs, *args, **kwargs)

    runs = []
    for _ in range(2):
        seeds.clear()
        run_module.run_loop = spy
        try:
            runs.append(
                run_machining(
                    robot, short_program, None, short_stock, settings_, compensation_model=model
                )
            )
        finally:
            run_module.run_loop = loop
    *rehearsals, program_cut = seeds
    assert len(rehearsals) == runs[-1].summary["rehearsals"] + 1  # the nominal wall's cut too
    assert program_cut == seed
    assert seed not in rehearsals and len(set(rehearsals)) == len(rehearsals)
    assert runs[0].summary["wall_error_max_mm"] == runs[1].summary["wall_error_max_mm"]
    assert np.array_equal(runs[0].program.position_m, runs[1].program.position_m)


@given(st.integers(0, 2**31 - 1))
@settings(max_examples=25, deadline=None)
def test_the_force_a_station_met_is_the_least_over_the_stretch_its_offset_governs(seed):
    """``offline.force_met_N``: the loop holds station i's offset over [s_i, s_i + ds), so the
    force that station met is the least over the samples there (np.minimum.at); a station no
    sample fell in takes its neighbours' (interpolated), and beyond a stopped run's end none."""
    from types import SimpleNamespace

    from robomach_core.machining.offline import force_met_N

    print(f"seed {seed}")
    rng = np.random.default_rng(seed)
    ds = 1e-4
    s_st = np.arange(200) * ds
    end = rng.uniform(0.3, 1.0) * s_st[-1]
    path = np.sort(rng.uniform(0.0, end, rng.integers(50, 2000)))
    force = rng.uniform(0.0, 150.0, len(path))
    met = force_met_N(SimpleNamespace(trace=SimpleNamespace(path_m=path, force_N=force)), s_st)
    station = np.floor(path / ds).astype(int)
    least = np.full(len(s_st), np.inf)
    np.minimum.at(least, station, force)
    seen = np.isfinite(least)
    np.testing.assert_array_equal(met[seen & (s_st <= path[-1])], least[seen & (s_st <= path[-1])])
    gaps = ~seen & (s_st <= path[-1])
    np.testing.assert_allclose(met[gaps], np.interp(s_st[gaps], s_st[seen], least[seen]))
    assert np.all(met[s_st > path[-1]] == 0.0)
