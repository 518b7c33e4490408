"""The papers' experiments in simulation, as tests of the behaviour they report."""

from __future__ import annotations

import threading

import numpy as np
import pytest

from robomach_core.cmrr import (
    AdaptiveLqSettings,
    build_scenario,
    run_study,
)
from robomach_core.cmrr.errors import CancelledError, UnknownControllerError, UnknownScenarioError

MM = 1e-3


@pytest.fixture(scope="module")
def milling():
    sc = build_scenario("milling-steps")
    return {c: run_study(sc, c) for c in ("fixed-pi", "adaptive-pi")}


def _segments(result):
    return {seg["label"]: seg for seg in result.summary["segments"]}


def test_fixed_pi_tuned_for_1mm_goes_unstable_at_3mm(milling):
    seg = _segments(milling["fixed-pi"])
    assert seg["1 mm"]["stable"] and seg["2 mm"]["stable"]
    assert not seg["3 mm"]["stable"]
    # The limit cycle spans the whole saturation range, as in the paper's fig. 11.
    assert seg["3 mm"]["settled_speed_ratio_min"] == pytest.approx(0.1)
    assert seg["3 mm"]["settled_speed_ratio_max"] == pytest.approx(1.0)
    assert not milling["fixed-pi"].summary["stable"]


def test_self_tuning_pi_holds_at_every_depth(milling):
    result = milling["adaptive-pi"]
    assert result.summary["stable"]
    seg = _segments(result)
    assert all(s["stable"] for s in seg.values())
    assert seg["3 mm"]["settled_force_mean_N"] == pytest.approx(250.0, abs=2.5)
    assert seg["3 mm"]["settled_force_std_N"] < 5.0
    assert (
        result.summary["force_rms_error_N"]
        < 0.25 * milling["fixed-pi"].summary["force_rms_error_N"]
    )


def test_at_1_and_2mm_the_lab_fit_stays_under_250N_at_full_speed(milling):
    # Why the 2 mm segment cannot show the paper's vibration: the reference is out of reach.
    sc = milling["fixed-pi"].scenario
    assert sc.process.steady_force(2 * MM, sc.command_speed_m_s) < sc.reference_force_N
    seg = _segments(milling["fixed-pi"])
    assert seg["1 mm"]["settled_speed_ratio_min"] == 1.0
    assert seg["2 mm"]["settled_speed_ratio_min"] == 1.0


def test_two_stage_deburring_stays_under_the_spindle_limit_at_100mm_s():
    sc = build_scenario("deburr-burrs")
    two = run_study(sc, "two-stage").summary
    const = run_study(sc, "constant").summary
    assert const["peak_force_N"] > sc.force_limit_N  # full speed without CMRR would stall
    assert two["completed"] and not two["protection_stop"]
    assert two["peak_force_N"] < sc.force_limit_N
    assert two["force_over_limit_time_s"] == 0.0
    # Faster than the paper's conservative constant feed (35 mm/s) and than the greatest safe
    # constant feed of this simulated process.
    assert two["cycle_time_s"] < two["conservative_cycle_time_s"] / 2
    assert two["cycle_time_s"] < two["baseline_cycle_time_s"]
    ratios = set(np.unique(run_study(sc, "two-stage").trace.speed_ratio))
    assert ratios <= {0.5, 1.0}


@pytest.fixture(scope="module")
def lund_lq():
    return run_study("lund-df", "adaptive-lq")


def test_adaptive_lq_follows_steps_and_ramp_of_df(lund_lq):
    result = lund_lq
    s = result.summary
    assert s["stable"] and s["completed"]
    for seg in s["segments"]:
        assert seg["settled_force_mean_N"] == pytest.approx(20.0, abs=0.5), seg["label"]
    tr = result.trace
    late = tr.engaged & (tr.time_s > 1.0)
    est = tr.estimates["removal_N_s_m"][late]
    true = tr.truths["removal_N_s_m"][late]
    assert np.median(np.abs(est / true - 1.0)) < 0.05


def test_lq_without_adaptation_is_slower_after_a_df_step(lund_lq):
    adaptive = lund_lq.summary
    fixed = run_study("lund-df", AdaptiveLqSettings(adapt=False)).summary
    assert fixed["force_rms_error_N"] > adaptive["force_rms_error_N"]


def test_learned_path_scenario_runs_standalone_from_meshes():
    sc = build_scenario("learned-path", burr_count=2, seed=3)
    assert sc.depth_profile.max() > 1.0 * MM  # allowance 0.5 mm plus a burr of 1-2 mm
    result = run_study(sc, "two-stage")
    assert result.summary["completed"]


def test_spindle_current_feedback_gives_a_similar_result():
    sc = build_scenario("deburr-burrs", feedback="spindle_current")
    s = run_study(sc, "two-stage").summary
    assert s["feedback"] == "spindle_current"
    assert s["completed"] and s["peak_force_N"] < sc.force_limit_N


def test_studies_are_deterministic_per_seed_and_differ_across_seeds():
    a = run_study("milling-steps", "adaptive-pi", seed=1).trace
    b = run_study("milling-steps", "adaptive-pi", seed=1).trace
    c = run_study("milling-steps", "adaptive-pi", seed=2).trace
    np.testing.assert_array_equal(a.measured_force_N, b.measured_force_N)
    assert not np.array_equal(a.measured_force_N[:100], c.measured_force_N[:100])


def test_progress_is_monotone_and_cancel_stops_the_study():
    seen: list[float] = []
    run_study("deburr-burrs", "constant", progress=seen.append)
    assert seen[-1] == 1.0
    assert all(b >= a for a, b in zip(seen, seen[1:], strict=False))
    assert len(seen) > 10
    flag = threading.Event()

    def cancel_half_way(fraction: float) -> None:
        if fraction > 0.5:
            flag.set()

    with pytest.raises(CancelledError):
        run_study("deburr-burrs", "constant", progress=cancel_half_way, cancel=flag)


def test_unknown_names_raise_user_errors():
    with pytest.raises(UnknownScenarioError):
        run_study("nope", "constant")
    with pytest.raises(UnknownControllerError):
        run_study("milling-steps", "nope")
