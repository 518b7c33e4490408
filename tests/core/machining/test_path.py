"""The program's place along the stock's path (``machining.path.project_onto_path``)."""

from __future__ import annotations

import numpy as np
from hypothesis import given, settings
from hypothesis import strategies as st


@given(
    turns=st.floats(0.2, 2.0),
    radius_m=st.floats(0.02, 0.3),
    spacing_m=st.floats(5e-4, 8e-3),
    count=st.integers(3, 400),
    scatter_m=st.floats(0.0, 3e-3),
    seed=st.integers(0, 2**31 - 1),
)
@settings(max_examples=80, deadline=None)
def test_the_windowed_projection_is_the_projection_on_every_segment(
    turns, radius_m, spacing_m, count, scatter_m, seed
):
    """``project_onto_path`` measures each point against the segments near its expected arc
    length only: over arcs (up to two full turns, whose points sit over earlier segments too),
    programs denser or sparser than the path and points off it, the same numbers, to the bit,
    as measured against every segment."""
    from robomach_core.machining.path import _project_onto_every_segment, project_onto_path

    rng = np.random.default_rng(seed)
    angle = np.arange(0.0, 2.0 * np.pi * turns, spacing_m / radius_m)
    if len(angle) < 2:
        angle = np.array([0.0, spacing_m / radius_m])
    path = np.stack([radius_m * np.cos(angle), radius_m * np.sin(angle), 1e-3 * angle], axis=1)
    normals = -path * np.array([1.0, 1.0, 0.0]) / radius_m
    along = np.linspace(0.0, angle[-1], count)
    points = np.stack([radius_m * np.cos(along), radius_m * np.sin(along), 1e-3 * along], axis=1)
    points += rng.normal(0.0, scatter_m, points.shape)
    got = project_onto_path(points, path, normals)
    want = _project_onto_every_segment(points, path, normals, window_m=0.005)
    for name, a, b in zip(("s", "offset", "lateral"), got, want, strict=True):
        np.testing.assert_array_equal(a, b, err_msg=f"{name} (seed {seed})")
