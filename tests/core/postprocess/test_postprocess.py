from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from hypothesis.extra.numpy import arrays

from robomach_core.errors import InvalidInputError
from robomach_core.postprocess import (
    PostprocessSettings,
    curvature_along,
    reduce_deviation_height,
    speeds_by_curvature,
)
from robomach_core.postprocess.targets import (
    deviation_heights,
    force_threshold_mask,
    reduce_deviation_height_reference,
)

walks = arrays(
    np.float64, st.tuples(st.integers(2, 300), st.just(3)), elements=st.floats(-1e-3, 1e-3)
).map(lambda steps: np.cumsum(steps, axis=0))


@st.composite
def dense_curves(draw: st.DrawFn) -> np.ndarray:
    """Recordings as the reduction meets them: a 3-D helix arc sampled densely, with noise, and
    a few repeated samples (the robot standing still)."""
    n = draw(st.integers(3, 1500))
    radius = draw(st.floats(2e-3, 0.2))
    length = draw(st.floats(1e-3, 0.3))
    pitch = draw(st.floats(-0.2, 0.2))
    noise = draw(st.sampled_from([0.0, 1e-7, 1e-6, 1e-5, 5e-5]))
    seed = draw(st.integers(0, 2**32 - 1))
    rng = np.random.default_rng(seed)
    t = np.sort(rng.uniform(0.0, length / radius, n))
    pts = np.stack([radius * np.cos(t), radius * np.sin(t), pitch * radius * t], axis=1)
    pts += rng.normal(0.0, noise, pts.shape)
    stills = rng.integers(1, n, draw(st.integers(0, 5)))
    pts[stills] = pts[stills - 1]
    return pts


@st.composite
def polylines(draw: st.DrawFn) -> np.ndarray:
    """Straight runs joined at corners of any angle, densely sampled (the groove's corners)."""
    corners = draw(
        arrays(
            np.float64, st.tuples(st.integers(2, 6), st.just(3)), elements=st.floats(-0.02, 0.02)
        )
    )
    per_run = draw(st.integers(2, 300))
    noise = draw(st.sampled_from([0.0, 1e-6, 2e-5]))
    f = np.linspace(0.0, 1.0, per_run, endpoint=False)[:, None]
    pts = np.vstack([a + f * (b - a) for a, b in zip(corners[:-1], corners[1:], strict=True)])
    rng = np.random.default_rng(draw(st.integers(0, 2**32 - 1)))
    return pts + rng.normal(0.0, noise, pts.shape)


@st.composite
def spiky_lines(draw: st.DrawFn) -> np.ndarray:
    """A straight pass with sparse spikes across it of about the tolerance (5e-5..5e-3 m)."""
    n = draw(st.integers(5, 120))
    rng = np.random.default_rng(draw(st.integers(0, 2**32 - 1)))
    spikes = rng.normal(0.0, draw(st.floats(5e-5, 5e-3)), (n, 2))
    spikes *= rng.random((n, 2)) < draw(st.floats(0.05, 0.5))
    return np.column_stack([np.linspace(0.0, 0.1, n), spikes])


def assert_fig3_guarantee(points: np.ndarray, kept: np.ndarray, tolerance: float) -> None:
    """Endpoints kept, indices increasing, every dropped sample within tolerance of its chord."""
    assert kept[0] == 0 and kept[-1] == len(points) - 1
    assert np.all(np.diff(kept) > 0)
    for a, b in zip(kept[:-1], kept[1:], strict=True):
        if b - a > 1:
            assert deviation_heights(points, a, b).max() <= tolerance * (1 + 1e-9)


@given(st.one_of(walks, dense_curves(), polylines(), spiky_lines()), st.floats(1e-5, 5e-3))
@settings(max_examples=400, deadline=None)
def test_compiled_reduction_equals_the_literal_fig3_scan(points, tolerance):
    """The kernel behind reduce_deviation_height makes the literal scan's decisions."""
    np.testing.assert_array_equal(
        reduce_deviation_height(points, tolerance),
        reduce_deviation_height_reference(points, tolerance),
    )


@given(dense_curves(), st.floats(1e-5, 1e-3))
@settings(max_examples=150, deadline=None)
def test_reduction_of_dense_3d_recordings_keeps_the_guarantee(points, tolerance):
    assert_fig3_guarantee(points, reduce_deviation_height(points, tolerance), tolerance)


@pytest.mark.parametrize("dims", [1, 2, 4])
def test_reduction_in_other_dimensions_equals_the_literal_scan(dims):
    rng = np.random.default_rng(dims)
    points = np.cumsum(rng.normal(0.0, 1e-3, (400, dims)), axis=0)
    np.testing.assert_array_equal(
        reduce_deviation_height(points, 2e-3), reduce_deviation_height_reference(points, 2e-3)
    )


def test_reduction_of_a_still_robot_keeps_only_the_ends():
    points = np.tile([0.1, 0.2, 0.3], (50, 1))
    np.testing.assert_array_equal(reduce_deviation_height(points, 1e-4), [0, 49])


@pytest.mark.parametrize(
    ("points", "tolerance"),
    [
        (np.zeros((5, 3)), 0.0),
        (np.zeros((5, 3)), -1e-4),
        (np.zeros((5, 3)), np.nan),
        (np.array([[0, 0, 0], [np.nan, 0, 0], [1, 0, 0]]), 1e-4),
        (np.zeros(5), 1e-4),
    ],
)
def test_reduction_refuses_bad_input(points, tolerance):
    with pytest.raises(InvalidInputError):
        reduce_deviation_height(points, tolerance)


@given(walks, st.floats(1e-5, 5e-3))
@settings(max_examples=150, deadline=None)
def test_reduction_keeps_endpoints_and_bounds_every_dropped_sample(points, tolerance):
    assert_fig3_guarantee(points, reduce_deviation_height(points, tolerance), tolerance)


@given(st.one_of(walks, dense_curves()), st.floats(1e-5, 5e-3))
@settings(max_examples=100, deadline=None)
def test_each_segment_is_the_longest_that_fits(points, tolerance):
    """Fig. 3: the chord grows until a deviation height exceeds the tolerance."""
    kept = reduce_deviation_height(points, tolerance)
    for a, b in zip(kept[:-2], kept[1:-1], strict=True):
        assert deviation_heights(points, a, b + 1).max() > tolerance


def test_straight_line_reduces_to_its_ends():
    line = np.linspace([0, 0, 0], [0.1, 0.02, 0], 500)
    np.testing.assert_array_equal(reduce_deviation_height(line, 1e-6), [0, 499])


def test_circle_chords_respect_the_sagitta():
    r, tol = 0.02, 0.0002
    t = np.linspace(0, np.pi, 4000)
    arc = np.stack([r * np.cos(t), r * np.sin(t), 0 * t], 1)
    kept = reduce_deviation_height(arc, tol)
    # A chord of a circle with sagitta h has length 2 sqrt(2 r h - h^2).
    expected = np.pi * r / (2 * np.sqrt(2 * r * tol - tol**2))
    assert abs(len(kept) - 1 - expected) <= 2


def test_force_threshold_filter():
    f = np.array([0.0, 4.9, 5.0, 10.0, 15.0, 15.1, 40.0])
    np.testing.assert_array_equal(
        force_threshold_mask(f, 5.0, 15.0), [False, False, True, True, True, False, False]
    )


def test_speed_is_slower_at_sharp_corners_and_averages_the_mean():
    k = np.array([0.0, 0.0, 50.0, 500.0, 0.0])
    v = speeds_by_curvature(k, speed_mean_m_s=0.01, speed_min_m_s=0.002, curvature_ref_1_m=100.0)
    assert v.mean() == pytest.approx(0.01, rel=1e-6)
    assert v[3] < v[2] < v[0]
    assert v.min() >= 0.002


def test_curvature_of_a_circle():
    t = np.linspace(0, 2 * np.pi, 2000)
    circle = np.stack([0.01 * np.cos(t), 0.01 * np.sin(t), 0 * t], 1)
    assert np.median(curvature_along(circle)) == pytest.approx(100.0, rel=1e-2)


def test_curvature_at_some_points_equals_the_full_evaluation():
    points = np.cumsum(np.random.default_rng(3).normal(0.0, 1e-4, (3000, 3)), axis=0)
    at = np.array([0, 1, 17, 1500, 2998, 2999])
    np.testing.assert_array_equal(curvature_along(points, at=at), curvature_along(points)[at])


@pytest.mark.parametrize(
    "kwargs",
    [{"tolerance_m": 0.0}, {"tolerance_m": -1e-4}, {"force_min_N": 15.0, "force_max_N": 5.0}],
)
def test_bad_settings_are_refused(kwargs):
    with pytest.raises(InvalidInputError):
        PostprocessSettings(**kwargs)


def test_the_force_band_follows_the_learning_force():
    from robomach_core.postprocess import PostprocessSettings

    default = PostprocessSettings()
    assert default.holds_force(10.0)
    assert default == default.with_band_for(10.0)  # 5-15 N at the chapter's 10 N
    assert not default.holds_force(20.0)  # 20 N samples would sit on the 15 N edge
    band = default.with_band_for(20.0)
    assert (band.force_min_N, band.force_max_N) == (10.0, 30.0) and band.holds_force(20.0)
    assert band.tolerance_m == default.tolerance_m


def test_a_gap_whose_chord_would_cut_a_corner_keeps_its_samples():
    """Round a sharp outside corner the ball's centre rolls on an arc out of contact (the force
    filter drops it): bridged by one chord, the program would cut the corner 0.29 mm deep
    (r (1 - cos 45 deg), r = 1 mm). The gap keeps its samples; a gap on a straight stretch,
    whose chord stays within the tolerance, is still bridged."""
    from robomach_core.postprocess.targets import keep_corners

    r = 0.001
    angles = np.linspace(np.pi / 2, 0.0, 50)  # the arc round the corner at the origin
    arc = np.column_stack([r * np.cos(angles), r * np.sin(angles), np.zeros(50)])
    before = np.column_stack([np.linspace(-0.01, 0.0, 20), np.full(20, r), np.zeros(20)])
    after = np.column_stack([np.full(20, r), np.linspace(0.0, -0.01, 20), np.zeros(20)])
    pts = np.vstack([before, arc, after])
    mask = np.ones(len(pts), dtype=bool)
    mask[20:70] = False  # the arc: out of contact
    mask[5:8] = False  # a dropped spike on the straight before it
    kept = keep_corners(pts, mask, 0.0002)
    assert kept[20:70].all()
    assert not kept[5:8].any()
    assert not keep_corners(pts, mask, 0.0005)[20:70].any()  # within a coarse tolerance: bridged


@settings(max_examples=60, deadline=None)
@given(
    radius_m=st.floats(0.02, 0.2),
    tool_radius_m=st.floats(0.0005, 0.005),
    end_m=st.floats(-0.01, 0.01),
    targets=st.integers(8, 200),
    drop_m=st.floats(0.0, 0.004),
)
def test_a_loops_ridge_is_the_scallop_between_its_end_and_its_start(
    radius_m, tool_radius_m, end_m, targets, drop_m
):
    """A closed program round a circle whose last target stops ``-end_m`` short of its first
    (or passes it by ``end_m``): no ridge when it passes, else r - sqrt(r^2 - (g/2)^2) for the
    chord g between them, the whole radius once the two cutters no longer overlap. The loop
    sinks ``drop_m`` along the tool axis on its way round: measured across the axis, the
    ridge is the same (a loop ending 1.6 mm lower where it began was NOT FIT for a ridge it
    does not leave)."""
    from robomach_core.postprocess import loop_ridge_m

    L = 2 * np.pi * radius_m
    s = np.linspace(0.0, L + end_m, targets)
    sink = -drop_m * s / L
    p = radius_m * np.column_stack([np.cos(s / radius_m), np.sin(s / radius_m), 0 * s])
    p[:, 2] = sink
    ridge = loop_ridge_m(p, tool_radius_m, axis=np.array([0.0, 0.0, -1.0]))
    if end_m >= 0:
        assert ridge == 0.0
        return
    g = 2 * radius_m * np.sin(-end_m / (2 * radius_m))
    half = g / 2
    want = (
        tool_radius_m
        if half >= tool_radius_m
        else tool_radius_m - np.sqrt(tool_radius_m**2 - half**2)
    )
    assert ridge == pytest.approx(want, rel=1e-9, abs=1e-12)


@settings(max_examples=200, deadline=None)
@given(
    radius=st.floats(0.01, 0.2),
    overrun=st.floats(0.0, 0.02),
    step=st.floats(2e-5, 2e-4),
    wiggle=st.floats(0.0, 2e-4),
    approach=st.floats(0.0, 0.001),  # in contact: the force builds within a millimetre
)
def test_a_closed_loop_ends_where_it_began(radius, overrun, step, wiggle, approach):
    """A closed loop's samples run past its start (the run knows it has passed only after);
    the program keeps them up to its nearest approach to its first kept sample, through the
    wall's wiggles, and an open route keeps all of them."""
    from robomach_core.postprocess.targets import closed_at_start

    length = 2 * np.pi * radius + overrun
    s = np.arange(0.0, length, step)
    r = radius + wiggle * np.sin(s / 3e-4)
    pts = np.stack([r * np.cos(s / radius), r * np.sin(s / radius), np.zeros_like(s)], axis=1)
    # the first samples in the force band come in across the wall, as the tool meets it
    lead = np.linspace(approach, 0.0, max(2, int(approach / step)), endpoint=False)
    pts = np.vstack([np.stack([radius + lead, np.zeros_like(lead), np.zeros_like(lead)], 1), pts])
    mask = np.ones(len(pts), dtype=bool)
    kept = np.nonzero(closed_at_start(pts, mask))[0]
    d = np.linalg.norm(pts - pts[0], axis=1)
    near_end = np.flatnonzero(np.arange(len(pts)) > len(pts) * 0.75)
    assert kept[-1] == near_end[np.argmin(d[near_end])]  # the nearest approach
    assert np.array_equal(kept, np.arange(kept[-1] + 1))  # nothing else dropped
