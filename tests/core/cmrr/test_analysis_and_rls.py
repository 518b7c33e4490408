"""The PI design of the MRR paper (eqs. (12)-(15)) and the RLS of eq. (16)."""

from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from robomach_core.cmrr import (
    PowerLawEstimator,
    closed_loop_poles,
    critical_loop_gain,
    damping_ratio,
    dominant_pole_pair,
)
from robomach_core.cmrr.controllers import RlsState, pi_gains, rls_update

MM = 1e-3


def test_design_gain_28_84_gives_a_dominant_pair_with_damping_0_7():
    poles = closed_loop_poles(28.84)
    assert np.all(poles.real < 0)
    pair = dominant_pole_pair(poles)
    assert pair.size == 2
    assert damping_ratio(pair[0]) == pytest.approx(0.7, abs=0.02)
    # The PI zero (-66.5) nearly cancels the slow robot pole: a real pole stays next to it.
    assert np.min(np.abs(poles - (-66.5))) < 1.0


def test_critical_gain_lies_between_the_design_gain_and_the_3mm_gain():
    g_crit = critical_loop_gain()
    assert 28.84 < g_crit
    poles = closed_loop_poles(0.99 * g_crit)
    assert np.max(poles.real) < 0
    assert np.max(closed_loop_poles(1.01 * g_crit).real) > 0
    # A PI designed at 28.84 for 1 mm sees k(d) / k(d0) = (d / d0)^(alpha / beta) times that
    # gain deeper (alpha = 0.9, beta = 0.5).
    g_3mm = 28.84 * (3 * MM / (1 * MM)) ** (0.9 / 0.5)
    assert g_3mm > g_crit


def test_eq15_self_tuning_gains_hold_the_loop_gain():
    vr, k = 0.03, 529.0  # 30 mm/s; k = 23^2 for 1 mm at beta = 0.5
    kp, ki = pi_gains(28.84, vr, k, 66.5)
    assert ki * (vr / 1e-3) * k == pytest.approx(28.84)
    assert kp * (vr / 1e-3) * k == pytest.approx(28.84 / 66.5)
    assert kp * (vr / 1e-3) * k == pytest.approx(0.432, abs=0.005)  # eq. (15)


@settings(max_examples=30, deadline=None)
@given(
    a=st.floats(-5, 5),
    b=st.floats(-5, 5),
    seed=st.integers(0, 1000),
)
def test_rls_recovers_a_noise_free_linear_model(a, b, seed):
    rng = np.random.default_rng(seed)
    state = RlsState(np.zeros(2), 1e6 * np.eye(2))
    for x1 in rng.uniform(-2, 2, 200):
        x = np.array([1.0, x1])
        state = rls_update(state, x, a + b * x1, forgetting=0.98)
    np.testing.assert_allclose(state.theta, [a, b], atol=1e-5)


def _excited_feed(t: float) -> float:
    return 0.02 + 0.008 * math.sin(2 * math.pi * 1.5 * t)  # 12 to 28 mm/s


def test_power_law_rls_converges_to_true_k_and_beta_on_noise_free_data():
    true_kf, true_beta = 23.0 * 2.0**0.9, 0.5
    est = PowerLawEstimator(
        command_speed_m_s=0.03,
        forgetting=0.98,
        initial_force_gain_N=10.0,
        initial_feed_exponent=0.8,
        initial_variances=(1.0, 1.0),
        max_variances=(1.0, 1.0),
    )
    state = est.initial_state()
    for k in range(750):
        f = _excited_feed(k * 0.004)
        state = est.update(state, true_kf * (f / 1e-3) ** true_beta, f)
    kf, beta = est.estimate(state)
    assert kf == pytest.approx(true_kf, rel=1e-4)
    assert beta == pytest.approx(true_beta, abs=1e-4)


@pytest.mark.parametrize("estimate_beta", [True, False])
def test_power_law_rls_tracks_a_step_in_depth(estimate_beta):
    est = PowerLawEstimator(
        command_speed_m_s=0.03, forgetting=0.95, estimate_feed_exponent=estimate_beta
    )
    state = est.initial_state()
    dt = 0.004
    for depth_mm, n in ((1.0, 500), (2.0, 125)):  # the step, then 0.5 s at 2 mm
        kf_true = 23.0 * depth_mm**0.9
        for k in range(n):
            f = _excited_feed(k * dt)
            state = est.update(state, kf_true * (f / 1e-3) ** 0.5, f)
        kf, beta = est.estimate(state)
        # The force predicted at the operating feeds (12-28 mm/s) follows within 1-2 %.
        tolerance = 0.02 if estimate_beta else 0.01
        for f in (0.012, 0.02, 0.028):
            predicted = kf * (f / 1e-3) ** beta
            expected = kf_true * (f / 1e-3) ** 0.5
            assert predicted == pytest.approx(expected, rel=tolerance), depth_mm
        if estimate_beta:
            # The step moves beta a little (depth and feed change together); its small
            # variance cap lets it return only slowly, and Kf at 1 mm/s extrapolates that.
            assert beta == pytest.approx(0.5, abs=0.03)
            assert kf == pytest.approx(kf_true, rel=0.1)
        else:
            assert kf == pytest.approx(kf_true, rel=0.01)


def test_rls_covariance_stays_bounded_without_excitation():
    est = PowerLawEstimator(command_speed_m_s=0.03)
    state = est.initial_state()
    for _ in range(5000):  # saturated at full speed: the regressor never changes
        state = est.update(state, 126.0, 0.03)
    assert np.all(np.diagonal(state.covariance) <= np.asarray(est.max_variances) * (1 + 1e-9))
    assert est.estimate(state)[1] == pytest.approx(0.5)  # beta is not touched by this data
