"""``Contour.distance`` measures only the pieces that can be nearest, and agrees exactly with
measuring every piece (the score of every learned path depends on it)."""

from __future__ import annotations

import numpy as np
from hypothesis import given, settings
from hypothesis import strategies as st

from robomach_core.part import Contour, water_pump_wall
from robomach_core.part.contour import DISTANCE_RUN

WALL = water_pump_wall()


def every_piece(contour: Contour, points: np.ndarray) -> np.ndarray:
    d = np.full(len(points), np.inf)
    for piece in contour.pieces:
        d = np.minimum(d, piece.distance(points))
    return d


@settings(max_examples=40, deadline=None)
@given(
    offset_mm=st.floats(-2.0, 2.5),
    spacing_mm=st.sampled_from([0.02, 0.1, 1.0]),
    noise_mm=st.floats(0.0, 3.0),
    start=st.integers(0, 5000),
    count=st.integers(1, 3 * DISTANCE_RUN),
    seed=st.integers(0, 2**16),
)
def test_distance_along_a_path_equals_the_distance_to_every_piece(
    offset_mm, spacing_mm, noise_mm, start, count, seed
):
    path = WALL.offset(offset_mm * 1e-3).sample(spacing_mm * 1e-3)
    pts = np.roll(path, -start, axis=0)[:count]
    pts = pts + np.random.default_rng(seed).normal(0.0, noise_mm * 1e-3, pts.shape)
    np.testing.assert_allclose(WALL.distance(pts), every_piece(WALL, pts), rtol=0, atol=1e-15)


@settings(max_examples=20, deadline=None)
@given(scale_m=st.floats(0.001, 10.0), count=st.integers(0, 2000), seed=st.integers(0, 2**16))
def test_distance_of_scattered_points_equals_the_distance_to_every_piece(scale_m, count, seed):
    pts = np.random.default_rng(seed).uniform(-scale_m, scale_m, (count, 2))
    np.testing.assert_allclose(WALL.distance(pts), every_piece(WALL, pts), rtol=0, atol=1e-15)
