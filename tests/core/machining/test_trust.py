"""Issue 16 on programs along the water pump's true wall: every controller completes within its
design, the feed is never negative, the fast controller copies equal the public ones, settings
inside the documented ranges never fail as an internal error (issue 19 R5), and the same sweep
gives the same numbers in this process, a process pool and a Dask cluster."""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from robomach_core.cmrr.controllers import ControlDesign, make_controller, settings_for
from robomach_core.cmrr.controllers._fast import fast_stepper
from robomach_core.cmrr.controllers.base import Measurement
from robomach_core.cmrr.process import ForceSensorModel
from robomach_core.errors import InvalidInputError
from robomach_core.limits import (
    MACHINING_DEPTH_EXPONENT,
    MACHINING_FEED_EXPONENT,
    MACHINING_FORCE_LIMIT_N,
    MACHINING_PROCESS_GAIN_N,
)
from robomach_core.machining import (
    MACHINING_CONTROLLERS,
    MachiningSettings,
    builtin_stock,
    identify_stiffness,
    run_machining,
)
from robomach_core.machining.parallel import CutTask, run_tasks
from robomach_core.machining.variation import StockVariation, draw_stocks
from robomach_core.postprocess import Targets
from robomach_core.stiffness import COMPENSATIONS

MM = 1e-3


@pytest.fixture(scope="module")
def wall_cuts(robot, wall_program):
    stock = builtin_stock(wall_program.position_m, seed=0)
    return stock, {
        c: run_machining(robot, wall_program, None, stock, MachiningSettings(controller=c))
        for c in MACHINING_CONTROLLERS
    }


@pytest.mark.parametrize("controller", MACHINING_CONTROLLERS)
def test_every_controller_completes_within_the_limit_and_never_feeds_backwards(
    wall_cuts, controller
):
    run = wall_cuts[1][controller]
    s = run.summary
    assert s["completed"], s["stop_reason"]
    assert s["force_peak_N"] <= 1.2 * s["force_limit_N"]
    assert run.trace.feed_m_s.min() >= 0.0
    assert np.all(np.diff(run.trace.path_m) >= 0.0)  # the TCP never runs backwards


def test_two_stage_slows_at_the_burr_and_finishes_under_the_limit(wall_cuts):
    """MRR paper fig. 9: the low stage is chosen so the deepest cut stays under the limit."""
    stock, runs = wall_cuts
    run = runs["two-stage"]
    low = run.controller_settings.low_speed_ratio
    assert low < 0.5  # the paper's 0.5 would not keep the limit on this stock
    s = run.summary
    assert s["force_peak_N"] <= 1.1 * s["force_limit_N"]
    # On the deepest burr the robot runs at the low stage (the command drops to it there).
    deep = run.trace.depth_m > 0.9 * stock.max_allowance_m
    assert deep.any() and run.trace.speed_ratio[deep].min() == pytest.approx(low)


def test_two_stage_protection_rule_stops_on_a_real_failure(robot, short_program):
    """A casting far harder than designed (K x 2.5): at the low stage the force is still far
    too high, and the failure-protection rule stops the robot (MRR paper sec. III-D c)."""
    stock = replace(builtin_stock(short_program.position_m, seed=0), material_factor=2.5)
    run = run_machining(
        robot, short_program, None, stock, MachiningSettings(controller="two-stage")
    )
    assert not run.summary["completed"]
    assert run.summary["stop_reason"] in ("protection rule", "force supervision")


def test_adaptive_lq_starts_below_the_safe_feed_and_uses_the_arm_stiffness(wall_cuts):
    run = wall_cuts[1]["adaptive-lq"]
    lq = run.controller_settings
    assert 300.0 < lq.stiffness_N_mm < 5000.0  # the UR10's stiffness along the wall normal
    assert lq.initial_removal_N_s_mm > 1.0  # the RLS prior from the nominal process
    start = run.trace.time_s < 0.3
    assert run.trace.force_N[start].max() < run.summary["force_limit_N"]


def _design() -> ControlDesign:
    return ControlDesign(
        dt_s=0.004,
        command_speed_m_s=0.01,
        reference_force_N=105.0,
        nominal_force_gain_N=85.0,
        measurement_filter=ForceSensorModel().make_filter(0.004),
    )


forces = st.lists(st.floats(0.0, 400.0), min_size=20, max_size=300)


@given(
    forces,
    st.sampled_from(["fixed-pi", "adaptive-pi", "fuzzy", "two-stage", "adaptive-lq"]),
    st.sampled_from([0.0, 0.1, 0.02]),
)
@settings(max_examples=25, deadline=None, suppress_health_check=[HealthCheck.too_slow])
def test_the_fast_copy_of_each_controller_equals_its_public_step(values, name, settle_s):
    own = settings_for(name)
    if name in ("fuzzy", "two-stage"):  # with the stage switch's settle time and margin
        own = replace(own, switch_settle_s=settle_s, stage_up_margin=settle_s / 2)
    ctrl = make_controller(own, _design())
    fast = fast_stepper(ctrl)
    state = ctrl.initial_state()
    for k, f in enumerate(values):
        feed = 0.002 + 0.006 * ((k * 7) % 11) / 10
        state, out = ctrl.step(state, Measurement(f, feed))
        ratio, stop = fast(f, feed)
        assert ratio == pytest.approx(out.speed_ratio, rel=1e-9, abs=1e-12)
        assert stop == out.stop


def _tiny(program: Targets, count: int = 16) -> Targets:
    return Targets(
        **{k: np.asarray(getattr(program, k))[:count] for k in program.__dataclass_fields__}
    )


@given(
    gain=st.floats(MACHINING_PROCESS_GAIN_N.min, MACHINING_PROCESS_GAIN_N.max),
    alpha=st.floats(MACHINING_DEPTH_EXPONENT.min, MACHINING_DEPTH_EXPONENT.max),
    beta=st.floats(MACHINING_FEED_EXPONENT.min, MACHINING_FEED_EXPONENT.max),
    limit=st.floats(MACHINING_FORCE_LIMIT_N.min, MACHINING_FORCE_LIMIT_N.max),
    controller=st.sampled_from(MACHINING_CONTROLLERS),
    compensation=st.sampled_from(COMPENSATIONS),
)
@settings(max_examples=40, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@pytest.mark.slow  # a sweep of cuts across the documented ranges
def test_settings_inside_the_documented_ranges_cut_or_say_why(
    robot, short_program, gain, alpha, beta, limit, controller, compensation
):
    """Issue 19 R5: OverflowError at (depth*1e3)**alpha, a NaN position to int. Every setting
    inside the documented ranges gives a run, or an InvalidInputError with a physical message."""
    program = _tiny(short_program)
    stock = builtin_stock(program.position_m, seed=0)
    s = MachiningSettings(
        process_gain_N=gain, depth_exponent=alpha, feed_exponent=beta, force_limit_N=limit,
        controller=controller, compensation=compensation, max_samples=60_000,
    )  # fmt: skip
    model = identify_stiffness(robot.name, seed=0).model
    try:
        run = run_machining(robot, program, None, stock, s, compensation_model=model)
    except InvalidInputError as exc:
        assert "internal" not in str(exc) and len(str(exc)) > 20
        return
    assert np.all(np.isfinite(run.trace.force_N)) and np.all(np.isfinite(run.trace.path_m))
    assert run.trace.force_N.max() <= 2.0 * limit + 1e-9  # the cell's force supervision


def test_the_lq_design_of_a_force_that_hardly_grows_with_the_feed(robot, short_program):
    """The sweep above found it: a 0.1 N process gain with feed exponent 0.01 and a 1400 N
    limit raised (Fref / Kf)^(1 / 0.01) past the largest float (OverflowError in the LQ's
    prior); such a process has no prior, and the cut runs or is refused with a reason."""
    program = _tiny(short_program)
    stock = builtin_stock(program.position_m, seed=0)
    s = MachiningSettings(
        process_gain_N=0.1, depth_exponent=0.0, feed_exponent=0.01, force_limit_N=1400.0,
        controller="adaptive-lq", compensation="off", max_samples=60_000,
    )  # fmt: skip
    model = identify_stiffness(robot.name, seed=0).model
    try:
        run = run_machining(robot, program, None, stock, s, compensation_model=model)
    except InvalidInputError as exc:  # a physical refusal is fine; an OverflowError is not
        assert "internal" not in str(exc) and len(str(exc)) > 20
        return
    assert np.all(np.isfinite(run.trace.force_N))


def test_the_reproducers_of_r5_get_a_result_or_a_physical_message(robot, short_program):
    program = _tiny(short_program)
    stock = builtin_stock(program.position_m, seed=0)
    model = identify_stiffness(robot.name, seed=0).model
    common = {"process_gain_N": 1000.0, "depth_exponent": 3.0}
    cases = [
        {**common, "feed_exponent": 0.5, "controller": "adaptive-pi", "compensation": "online"},
        {**common, "feed_exponent": 0.01, "controller": "fixed-pi", "compensation": "offline"},
        {**common, "feed_exponent": 0.01, "force_limit_N": 1.5, "controller": "constant"},
    ]  # fmt: skip
    for case in cases:
        try:
            run = run_machining(
                robot, program, None, stock, MachiningSettings(**case), compensation_model=model
            )
        except InvalidInputError as exc:
            assert "force limit" in str(exc) or "diverged" in str(exc), exc
        else:
            assert not run.summary["completed"] or run.summary["force_peak_N"] > 0.0


def test_variations_are_seeded_and_within_their_stated_ranges(short_program):
    base = builtin_stock(short_program.position_m, seed=0)
    spec = StockVariation()
    a = draw_stocks(base, 6, 3, spec)
    b = draw_stocks(base, 6, 3, spec)
    assert [s.material_factor for s in a] == [s.material_factor for s in b]
    assert all(spec.material_factor[0] <= s.material_factor <= spec.material_factor[1] for s in a)
    assert len({round(s.max_allowance_m, 9) for s in a}) == 6  # each casting differs
    assert all(np.allclose(s.path_points_m, base.path_points_m) for s in a)


def _sweep_tasks(robot, program) -> list[CutTask]:
    base = builtin_stock(program.position_m, seed=0)
    stocks = draw_stocks(base, 2, 0, StockVariation())
    model = identify_stiffness(robot.name, seed=0).model
    return [
        CutTask(
            robot.name,
            robot.T_flange_tcp,
            program,
            None,
            stock,
            MachiningSettings(),
            controller,
            ("off", "online"),
            model,
        )  # fmt: skip
        for stock in stocks
        for controller in ("constant", "adaptive-pi")
    ]


def _figures(results) -> list[tuple]:
    return [
        (s["cycle_time_s"], s["force_peak_N"], s["wall_error_max_mm"])
        for task in results
        for _, s, _ in task
    ]


@pytest.mark.slow
def test_a_sweep_gives_the_same_numbers_here_in_a_process_pool_and_on_a_dask_cluster(
    robot, short_program
):
    import distributed  # the [cluster] extra, part of [test]

    tasks = _sweep_tasks(robot, _tiny(short_program, 31))
    here = _figures(run_tasks(tasks, workers=1))
    seen: list[float] = []
    pool = _figures(run_tasks(tasks, workers=2, progress=seen.append))
    assert pool == here and seen[-1] == pytest.approx(1.0)
    with distributed.LocalCluster(
        n_workers=2, threads_per_worker=1, processes=True, dashboard_address=None
    ) as cluster:
        dask = _figures(run_tasks(tasks, cluster=cluster.scheduler_address))
    assert dask == here
