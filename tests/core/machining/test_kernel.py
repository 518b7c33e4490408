"""The compiled machining loop (``machining._kernel``) equals its Python reference
(``machining._loop.cut_loop``, the controllers through ``_fast``, itself tested against each
controller's public step), sample for sample, over generated stocks and settings, including
the adaptive LQ's growing table of designs, stops and the online compensation.

Equal to the last bit, not within a tolerance: the two run the same operations in the same
order (the LQ's command is one function both call), and must. A tolerance hid an ulp that the
adaptive LQ's Df grid switch turned, at a knife edge, into a switch a sample later and a cut
6 samples longer (issue 29: seed 3961, adaptive-lq/online, limit 228 N, material 2.5)."""

from __future__ import annotations

from dataclasses import replace

import numpy as np
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from robomach_core.machining import (
    MACHINING_CONTROLLERS,
    MachiningSettings,
    builtin_stock,
    identify_stiffness,
)
from robomach_core.machining._kernel import pack_controller
from robomach_core.machining.run import cut_program, plan_cut

TRACE = ("path_m", "feed_m_s", "speed_ratio", "depth_m", "force_N", "tool_normal_m")


def _same(a, b) -> None:
    assert len(a.trace) == len(b.trace)
    for name in TRACE:
        x, y = getattr(a.trace, name), getattr(b.trace, name)
        np.testing.assert_array_equal(x, y, err_msg=name)
    for key in (
        "completed", "stop_reason", "cycle_time_s", "stop_time_s", "force_peak_N",
        "wall_error_max_mm",
    ):  # fmt: skip
        assert a.summary[key] == b.summary[key], key


@given(
    seed=st.integers(0, 2**31 - 1),
    controller=st.sampled_from(MACHINING_CONTROLLERS),
    compensation=st.sampled_from(["off", "online"]),
    limit=st.floats(60.0, 400.0),
    material=st.floats(0.6, 2.5),
    noise=st.floats(0.0, 8.0),
)
@settings(max_examples=24, deadline=None, suppress_health_check=[HealthCheck.too_slow])
def test_the_compiled_loop_equals_the_reference(
    robot, short_program, seed, controller, compensation, limit, material, noise
):
    print(f"seed {seed} {controller}/{compensation} limit {limit:g} material {material:g}")
    stock = replace(builtin_stock(short_program.position_m, seed=seed), material_factor=material)
    s = MachiningSettings(
        controller=controller, compensation=compensation, force_limit_N=limit,
        sensor_noise_N=noise, seed=seed,
    )  # fmt: skip
    model = identify_stiffness(robot.name, seed=0).model
    fast = cut_program(robot, short_program, None, stock, s, model=model)
    slow = cut_program(robot, short_program, None, stock, s, model=model, compiled=False)
    _same(fast, slow)


@given(
    seed=st.integers(0, 2**31 - 1),
    stages=st.lists(st.sampled_from([0.2, 0.25, 0.4, 0.5, 0.6, 0.8, 1.0]), min_size=1, max_size=12),
    limit=st.floats(60.0, 400.0),
    material=st.floats(0.6, 2.5),
)
@settings(max_examples=16, deadline=None, suppress_health_check=[HealthCheck.too_slow])
def test_the_compiled_loop_equals_the_reference_on_a_planned_schedule(
    robot, short_program, seed, stages, limit, material
):
    """The loop's new input (issue 29): a stage schedule planned offline as the program's
    speeds, cut with no feed control (``feed="program"``), the stages drawn per stretch."""
    from robomach_core.machining.schedule import scheduled_program

    print(f"seed {seed} stages {stages} limit {limit:g} material {material:g}")
    stock = replace(builtin_stock(short_program.position_m, seed=seed), material_factor=material)
    s = MachiningSettings(controller="two-stage", force_limit_N=limit, seed=seed)
    s_st = plan_cut(robot, short_program, None, stock, s).s_st
    rng = np.random.default_rng(seed)
    cuts = np.sort(rng.integers(0, len(s_st), len(stages) - 1))
    ratio = np.asarray(stages)[np.searchsorted(cuts, np.arange(len(s_st)), side="right")]
    program = scheduled_program(short_program, s_st, ratio)
    fast = cut_program(robot, program, None, stock, s, feed="program")
    slow = cut_program(robot, program, None, stock, s, feed="program", compiled=False)
    assert fast.summary["feed"] == "program" and fast.summary["controller_design"] is None
    _same(fast, slow)


def test_the_kernel_covers_every_designed_controller(robot, short_program):
    """No machining configuration falls back to the reference loop (the speed of a sweep)."""
    stock = builtin_stock(short_program.position_m, seed=0)
    for controller in MACHINING_CONTROLLERS:
        plan = plan_cut(robot, short_program, None, stock, MachiningSettings(controller=controller))
        assert pack_controller(plan.controller) is not NotImplemented, controller


def test_the_lq_table_grows_and_the_cut_is_the_same(robot, short_program):
    """A casting far harder than designed drives Df_hat across many grid points: the kernel
    stops at each new one, the design is added, the cut runs again; the result is the
    reference's, and a second cut needs no new design."""
    stock = replace(builtin_stock(short_program.position_m, seed=3), material_factor=2.0)
    s = MachiningSettings(controller="adaptive-lq", force_limit_N=300.0, seed=3)
    fast = cut_program(robot, short_program, None, stock, s)
    slow = cut_program(robot, short_program, None, stock, s, compiled=False)
    _same(fast, slow)
    packed = plan_cut(robot, short_program, None, stock, s).packed
    assert int(packed.lq_have.sum()) > 1
    before = packed.lq_have.copy()
    _same(cut_program(robot, short_program, None, stock, s), fast)
    np.testing.assert_array_equal(packed.lq_have, before)


@given(
    st.lists(st.floats(-2e-4, 2e-4), min_size=3, max_size=400),
    st.floats(1e-7, 1e-5),
    st.integers(2, 40),
)
@settings(max_examples=60, deadline=None)
def test_the_compiled_target_placement_equals_its_reference(shift, tolerance, every):
    """Offline compensation's deviation-height placement of the corrected targets."""
    from robomach_core.machining._kernel import split_by_deviation
    from robomach_core.machining.offline import split_by_deviation_reference

    shift = np.asarray(shift)
    s = np.arange(len(shift)) * 1e-4
    keep = np.zeros(len(s), dtype=bool)
    keep[::every] = True
    keep[[0, -1]] = True
    reference = keep.copy()
    split_by_deviation(s, shift, keep, tolerance)
    split_by_deviation_reference(s, shift, reference, tolerance)
    np.testing.assert_array_equal(keep, reference)


@given(
    st.lists(st.floats(1e-4, 0.02), min_size=2, max_size=300),
    st.floats(1e-9, 1e-4),
    st.lists(st.tuples(st.integers(0, 49), st.floats(-1e-3, 1e-3)), min_size=1, max_size=200),
)
@settings(max_examples=60, deadline=None)
def test_the_stations_kernels_equal_numpy(speeds, step, samples):
    """The planner's ramp (forward then backward, v^2 <= v0^2 + 2 a ds) and the lowest reach
    per station (``np.minimum.at``), compiled, against their numpy forms."""
    from robomach_core.machining._kernel import lowest_reach, speed_profile

    v2 = np.asarray(speeds) ** 2
    ref = v2.tolist()
    for i in range(1, len(ref)):
        ref[i] = min(ref[i], ref[i - 1] + step)
    for i in range(len(ref) - 2, -1, -1):
        ref[i] = min(ref[i], ref[i + 1] + step)
    np.testing.assert_array_equal(speed_profile(v2, step), np.sqrt(ref))
    station = np.array([k for k, _ in samples], dtype=np.int64)
    depth = np.array([h for _, h in samples])
    reach = np.full(50, np.inf)
    np.minimum.at(reach, station, depth)
    np.testing.assert_array_equal(lowest_reach(station, depth, 50), reach)


@given(
    st.lists(st.one_of(st.floats(-2e-3, 2e-3), st.just(np.inf)), min_size=1, max_size=300),
    st.floats(2e-4, 3e-3),
    st.floats(2e-5, 5e-4),
)
@settings(max_examples=60, deadline=None)
def test_the_compiled_ball_envelope_equals_its_reference(reach, radius_m, ds_m):
    """The finished wall's ball envelope over the stations' lowest reach (inf where the tool
    never came), compiled, against its numpy form: the same minima, to the bit."""
    from robomach_core.machining._kernel import ball_envelope
    from robomach_core.machining.summary import ball_envelope_reference, ball_rise_m

    reach = np.asarray(reach, dtype=float)
    rise = ball_rise_m(radius_m, ds_m)
    np.testing.assert_array_equal(ball_envelope(reach, rise), ball_envelope_reference(reach, rise))
