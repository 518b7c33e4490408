"""Robot feed dynamics, process force models, sensors and depth profiles."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from robomach_core.cmrr import (
    Burr,
    FeedDynamics,
    LundForceModel,
    MeshDepthError,
    PowerLawForceModel,
    SpindleCurrentModel,
    burr_depth_profile,
    depth_along_path,
    random_burrs,
    step_depth_profile,
    synthetic_burr_block,
)
from robomach_core.cmrr.errors import CmrrSettingsError
from robomach_core.cmrr.process import LowPassFilter, process_step
from robomach_core.transforms import arc_length_m

MM = 1e-3


def test_eq1_is_stable_non_minimum_phase_with_the_slow_pole_at_66_5():
    fd = FeedDynamics()
    poles = fd.poles()
    assert np.all(poles.real < 0)
    assert np.all(fd.zeros().real > 0)  # non-minimum phase
    assert np.min(np.abs(poles.real)) == pytest.approx(66.5, abs=0.1)
    assert fd.dc_gain == pytest.approx(4330000 / 4313000)


def test_discrete_feed_model_reaches_the_static_gain_and_integrates_position():
    fd = FeedDynamics()
    model = fd.discretize(0.004)
    x = model.initial_state()
    for _ in range(500):  # 2 s, far beyond the 15 ms slow time constant
        x = model.step(x, 0.03)
    assert model.feed(x) == pytest.approx(0.03 * fd.dc_gain, rel=1e-6)
    x2 = model.step(x, 0.03)
    assert x2[-1] - x[-1] == pytest.approx(0.004 * 0.03 * fd.dc_gain, rel=1e-6)


def test_unstable_feed_dynamics_are_rejected():
    with pytest.raises(CmrrSettingsError):
        FeedDynamics(num=(1.0,), den=(1.0, -1.0))


def test_lab_fit_eq6_known_values():
    model = PowerLawForceModel()
    # F = 23 d^0.9 f^0.5 with d in mm and f in mm/s.
    assert model.steady_force(1 * MM, 30 * MM) == pytest.approx(23 * 30**0.5)
    assert model.steady_force(2 * MM, 30 * MM) == pytest.approx(23 * 2**0.9 * 30**0.5)
    assert model.steady_force(3 * MM, 0.0) == 0.0
    assert model.force_gain_N(3 * MM) == pytest.approx(23 * 3**0.9)


@given(
    depth_mm=st.floats(0.1, 5.0),
    force=st.floats(1.0, 1000.0),
    beta=st.floats(0.2, 1.2),
)
def test_power_law_feed_for_force_inverts_the_force(depth_mm, force, beta):
    model = PowerLawForceModel(feed_exponent=beta)
    feed = model.feed_for_force(force, depth_mm * MM)
    assert model.steady_force(depth_mm * MM, feed) == pytest.approx(force, rel=1e-9)


def test_lund_model_settles_to_df_times_v_with_time_constant_df_over_kf():
    model = LundForceModel(stiffness_N_m=50e3, removal_N_s_m=1e3)
    depth, v, dt = 2 * MM, 0.01, 0.001
    tau = model.lag_s(depth)
    assert tau == pytest.approx(2e3 / 50e3)
    f = 0.0
    for _ in range(int(round(tau / dt))):
        f = process_step(model, f, depth, v, dt)
    target = model.steady_force(depth, v)
    assert target == pytest.approx(2e3 * v)
    assert f == pytest.approx(target * (1 - np.exp(-1)), rel=1e-6)


def test_low_pass_filter_has_unit_dc_gain_and_attenuates_noise():
    filt = LowPassFilter.butterworth(20.0, 2, 0.004)
    state = filt.initial_state()
    rng = np.random.default_rng(0)
    ys = []
    for x in 100.0 + rng.standard_normal(2000):
        state, y = filt.step(state, float(x))
        ys.append(y)
    ys = np.array(ys[500:])
    assert np.mean(ys) == pytest.approx(100.0, abs=0.1)
    assert np.std(ys) < 0.6  # white noise of std 1 through a 20 Hz filter at 250 Hz


def test_spindle_current_converts_back_to_force():
    spindle = SpindleCurrentModel()
    current = spindle.current_A(250.0, noise=0.0)
    assert current == pytest.approx(spindle.offset_A + 250.0 * spindle.amps_per_N)
    assert spindle.force_from_current(current) == pytest.approx(250.0)


def test_step_profile_has_the_papers_depths_in_each_segment():
    profile = step_depth_profile((1 * MM, 2 * MM, 3 * MM), 0.09)
    assert profile(0.045) == pytest.approx(1 * MM)
    assert profile(0.135) == pytest.approx(2 * MM)
    assert profile(0.225) == pytest.approx(3 * MM)
    assert profile.length_m == pytest.approx(0.27)


@settings(max_examples=25, deadline=None)
@given(seed=st.integers(0, 10_000), count=st.integers(0, 4))
def test_random_burrs_are_seeded_sorted_and_do_not_overlap(seed, count):
    a = random_burrs(np.random.default_rng(seed), count, 0.6)
    b = random_burrs(np.random.default_rng(seed), count, 0.6)
    assert a == b
    assert len(a) == count
    for left, right in zip(a, a[1:], strict=False):
        assert right.center_m - left.center_m >= 0.5 * (left.width_m + right.width_m)
    profile = burr_depth_profile(a, 0.6, base_depth_m=0.5 * MM)
    assert profile.values.min() == pytest.approx(0.5 * MM)
    if a:
        assert profile.max() <= 0.5 * MM + max(x.height_m for x in a) + 1e-12


def test_depth_along_path_recovers_allowance_and_burrs_from_the_meshes():
    burrs = [Burr(0.06, 1.5 * MM, 0.03), Burr(0.14, 2.0 * MM, 0.02)]
    nominal, stock, path, axis = synthetic_burr_block(burrs, allowance_m=0.5 * MM, path_points=201)
    depth = depth_along_path(path, nominal, stock, axis)
    s = path[:, 0]
    expected = 0.5 * MM + sum(b.height_at(s) for b in burrs)
    # The stock outline is sampled every 0.25 mm; linear facets differ from the cosine by less.
    assert np.max(np.abs(depth - expected)) < 0.02 * MM
    # A TCP offset along the tool axis (ball centre above the surface) does not change it.
    lifted = depth_along_path(path + 3 * MM * axis, nominal, stock, axis)
    np.testing.assert_allclose(lifted, depth, atol=1e-9)
    assert arc_length_m(path)[-1] == pytest.approx(path[-1, 0] - path[0, 0])


def test_depth_along_path_rejects_points_off_the_part():
    nominal, stock, path, axis = synthetic_burr_block([], path_points=11)
    with pytest.raises(MeshDepthError):
        depth_along_path(path + np.array([1.0, 0.0, 0.0]), nominal, stock, axis)
    with pytest.raises(MeshDepthError):
        depth_along_path(path[:, :2], nominal, stock, axis)
