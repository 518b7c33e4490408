"""Controller invariants: saturation, anti-windup, staged output, protection stop, LQ design."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from robomach_core.cmrr import (
    AdaptiveLqSettings,
    AdaptivePiSettings,
    FixedPiSettings,
    FuzzySettings,
    Measurement,
    TwoStageSettings,
    build_scenario,
    make_controller,
)
from robomach_core.cmrr.controllers.fuzzy import RULE_BASE
from robomach_core.cmrr.errors import CmrrSettingsError

DESIGN = build_scenario("milling-steps").control_design()
forces = st.lists(st.floats(0.0, 800.0), min_size=1, max_size=300)


def _run(controller, force_seq, feed=0.02):
    state = controller.initial_state()
    outs = []
    for f in force_seq:
        state, out = controller.step(state, Measurement(float(f), feed))
        outs.append(out)
    return state, outs


@settings(max_examples=40, deadline=None)
@given(seq=forces)
def test_pi_controllers_stay_inside_the_saturation_limits(seq):
    for s in (FixedPiSettings(), AdaptivePiSettings()):
        _, outs = _run(make_controller(s, DESIGN), seq)
        ratios = np.array([o.speed_ratio for o in outs])
        assert np.all(ratios >= DESIGN.min_speed_ratio - 1e-12)
        assert np.all(ratios <= 1.0 + 1e-12)


def test_fixed_pi_anti_windup_reacts_at_once_after_long_saturation():
    ctrl = make_controller(FixedPiSettings(), DESIGN)
    state, outs = _run(ctrl, [100.0] * 2500)  # 10 s far below the reference: saturated at 1
    assert outs[-1].speed_ratio == 1.0
    state, out = ctrl.step(state, Measurement(300.0, 0.03))
    assert out.speed_ratio < 1.0  # no wound-up integral to unwind first


@settings(max_examples=40, deadline=None)
@given(seq=forces)
def test_fuzzy_never_commands_below_its_lowest_stage_unless_stopped(seq):
    for s in (FuzzySettings(), TwoStageSettings()):
        ctrl = make_controller(s, DESIGN)
        stages = ctrl.fuzzy.stages
        _, outs = _run(ctrl, seq)
        for out in outs:
            if out.stop:
                assert out.speed_ratio == 0.0
            else:
                assert out.speed_ratio in stages
                assert out.speed_ratio >= stages[0]
        stopped = [o.stop for o in outs]
        if True in stopped:  # latched: once stopped, stays stopped
            assert all(stopped[stopped.index(True) :])


def test_fuzzy_protection_rule_stops_the_robot_when_the_lowest_stage_is_not_enough():
    ctrl = make_controller(FuzzySettings(), DESIGN)
    fr = DESIGN.reference_force_N
    # Far too much force: the controller walks down to the lowest stage, then stops.
    _, outs = _run(ctrl, [2.0 * fr] * 500)
    ratios = [o.speed_ratio for o in outs]
    first_stop = next(i for i, o in enumerate(outs) if o.stop)
    assert min(ratios[:first_stop]) == ctrl.fuzzy.stages[0]
    assert all(r == 0.0 for r in ratios[first_stop:])
    # High force at the lowest stage for less than the hold time (0.2 s) does not stop it.
    first_low = ratios.index(ctrl.fuzzy.stages[0])
    hold_samples = int(ctrl.fuzzy.stop_hold_s / DESIGN.dt_s)
    assert first_stop - first_low >= hold_samples - 1
    seq = [2.0 * fr] * (first_low + hold_samples // 2) + [fr] * 100
    _, outs2 = _run(ctrl, seq)
    assert not any(o.stop for o in outs2)


def test_fuzzy_rule_base_has_the_three_groups():
    outputs = {rule[3] for rule in RULE_BASE}
    assert "STOP" in outputs
    trend_rules = [r for r in RULE_BASE if r[1] in ("P", "N")]
    limit_rules = [r for r in RULE_BASE if r[1] == "Z"]
    assert len(limit_rules) == 5 and len(trend_rules) == 10


def test_fuzzy_slows_on_a_steep_rise_before_the_reference_is_reached():
    ctrl = make_controller(TwoStageSettings(), DESIGN)
    fr = DESIGN.reference_force_N
    ramp = np.linspace(0.3 * fr, 0.8 * fr, 40)  # 0.16 s, still below Fr at the end
    _, outs = _run(ctrl, [0.3 * fr] * 50 + list(ramp))
    assert outs[-1].speed_ratio == 0.5


def test_invalid_settings_are_rejected():
    with pytest.raises(CmrrSettingsError):
        FuzzySettings(stages=(0.4, 0.2, 1.0))
    with pytest.raises(CmrrSettingsError):
        FuzzySettings(stages=(0.2, 0.6))
    with pytest.raises(CmrrSettingsError):
        FixedPiSettings(loop_gain=-1.0)
    with pytest.raises(CmrrSettingsError):
        AdaptivePiSettings(forgetting_factor=1.5)
    with pytest.raises(CmrrSettingsError):
        TwoStageSettings(low_speed_ratio=1.0)
    with pytest.raises(CmrrSettingsError):
        AdaptiveLqSettings(input_weight=0.0)


@pytest.mark.parametrize("df_n_s_mm", [0.5, 1.0, 2.0, 4.0])
def test_lq_design_is_stabilizing_for_the_nominal_model(df_n_s_mm):
    design = build_scenario("lund-df").control_design()
    ctrl = make_controller(AdaptiveLqSettings(), design)
    lq = ctrl.solve(df_n_s_mm)
    # Rebuild the closed loop from the same discretization the design used.
    phi, gamma = _augmented(ctrl, df_n_s_mm)
    eig = np.linalg.eigvals(phi - np.outer(gamma, lq.gain))
    assert np.max(np.abs(eig)) < 1.0
    assert lq.feedforward > 0.0


def _augmented(ctrl, removal):
    """The augmented discrete model [x, delayed, F, xi] of the LQ design, for the check."""
    import scipy.linalg

    a, b, c = ctrl.design.feed_dynamics.state_space()
    n, kf, dt = a.shape[0], ctrl.kf, ctrl.design.dt_s
    m = n + 2
    ac = np.zeros((m + 1, m + 1))
    ac[:n, :n] = a
    ac[:n, m] = b
    ac[n, :n] = kf * c
    ac[n, n] = -kf / removal
    ac[n + 1, n] = -1.0
    ex = scipy.linalg.expm(ac * dt)
    phi_p, gamma_p = ex[:m, :m], ex[:m, m]
    # One sample of control delay (the scenario's default).
    size = m + 1
    phi = np.zeros((size, size))
    gamma = np.zeros(size)
    idx = [*range(n), n + 1, n + 2]
    phi[np.ix_(idx, idx)] = phi_p
    phi[idx, n] = gamma_p
    gamma[n] = 1.0
    return phi, gamma
