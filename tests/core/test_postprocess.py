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
    deviation_heights,
    force_threshold_mask,
    reduce_deviation_height,
    speeds_by_curvature,
)

walks = arrays(
    np.float64, st.tuples(st.integers(2, 300), st.just(3)), elements=st.floats(-1e-3, 1e-3)
).map(lambda steps: np.cumsum(steps, axis=0))


@given(walks, st.floats(1e-5, 5e-3))
@settings(max_examples=150, deadline=None)
def test_reduction_keeps_endpoints_and_bounds_every_dropped_sample(points, tolerance):
    kept = reduce_deviation_height(points, tolerance)
    assert kept[0] == 0 and kept[-1] == len(points) - 1
    assert np.all(np.diff(kept) > 0)
    for a, b in zip(kept[:-1], kept[1:], strict=True):
        if b - a > 1:
            assert deviation_heights(points, a, b).max() <= tolerance + 1e-12


@given(walks, st.floats(1e-5, 5e-3))
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


@pytest.mark.parametrize(
    "kwargs",
    [{"tolerance_m": 0.0}, {"tolerance_m": -1e-4}, {"force_min_N": 15.0, "force_max_N": 5.0}],
)
def test_bad_settings_are_refused(kwargs):
    with pytest.raises(InvalidInputError):
        PostprocessSettings(**kwargs)
