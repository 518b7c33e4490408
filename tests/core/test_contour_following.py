"""The compiled contour-following law equals its Python reference (the same law run by the
interpreter, ``py_func``), and does what its docstring says on simple cases."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from robomach_core.learning.law import (
    EVER_TOUCHED,
    LIFT,
    PARAMETERS,
    contour_law,
    initial_state,
    law_parameters,
    turn_towards,
)
from robomach_core.learning.run import PathLearningSettings, contour_law_parameters

AXIS = np.array([0.0, 0.0, -1.0])  # tool straight down, into the part


def _params(**override: float) -> np.ndarray:
    """The law's parameters for the default settings (``path_learning``'s own)."""
    from dataclasses import replace

    return contour_law_parameters(replace(PathLearningSettings(), **override))


def _unit(v) -> np.ndarray:
    v = np.asarray(v, dtype=float)
    return v / np.linalg.norm(v)


vec = st.lists(st.floats(-30.0, 30.0), min_size=3, max_size=3).map(np.array)


@settings(max_examples=300, deadline=None)
@given(
    force=vec,
    w_angle=st.floats(-np.pi, np.pi),
    side=st.sampled_from([-1.0, 1.0]),
    p=vec.map(lambda v: v * 1e-3),
    touched=st.booleans(),
    out_m=st.floats(0.0, 0.02),
    lift=st.floats(0.0, 0.003),
)
def test_the_compiled_law_equals_its_reference(force, w_angle, side, p, touched, out_m, lift):
    w = np.array([np.cos(w_angle), np.sin(w_angle), 0.0])
    state = initial_state()
    state[EVER_TOUCHED] = float(touched)
    state[LIFT] = lift
    state[6] = out_m
    args = (force, w, AXIS, side, np.zeros(3), _unit([1, 0.2, 0]), 0.05, p, state, _params())
    got = contour_law(*args)
    want = contour_law.py_func(*args)
    for a, b in zip(got, want, strict=True):
        np.testing.assert_allclose(a, b, rtol=1e-12, atol=1e-15)


def test_pressed_at_the_reference_it_slides_along_the_wall():
    """The wall at -y pushes the tool with 10 N along +y: the law keeps w = -y, moves along the
    tangent (the wall on the right of travel: +x... with the tool axis down, right of +x is
    -y), and not across it."""
    w = np.array([0.0, -1.0, 0.0])
    state = initial_state()
    state[EVER_TOUCHED] = 1.0
    step, w_new, _, f_n, touching = contour_law(
        np.array([0.0, 10.0, 0.0]), w, AXIS, 1.0, np.zeros(3), _unit([1, 0, 0]), 0.05,
        np.zeros(3), state, _params(),
    )  # fmt: skip
    assert touching and f_n == pytest.approx(10.0)
    np.testing.assert_allclose(w_new, w, atol=1e-12)
    assert step[0] == pytest.approx(0.005 * 0.004)  # full learning speed along +x
    assert abs(step[1]) < 1e-7  # in balance across the wall


def test_a_force_from_behind_pushes_the_tool_towards_its_wall_and_keeps_w():
    w = np.array([0.0, -1.0, 0.0])
    state = initial_state()
    state[EVER_TOUCHED] = 1.0
    step, w_new, _, f_n, _ = contour_law(
        np.array([0.0, -8.0, 0.0]), w, AXIS, 1.0, np.zeros(3), _unit([1, 0, 0]), 0.05,
        np.zeros(3), state, _params(),
    )  # fmt: skip
    assert f_n == pytest.approx(-8.0)
    np.testing.assert_allclose(w_new, w)
    assert step[1] < 0.0  # towards its own wall (-y), away from the one behind


def test_the_floor_lifts_the_run_and_then_the_clearance():
    state = initial_state()
    args = (np.zeros(3), _unit([0, -1, 0]), AXIS, 1.0, np.zeros(3), _unit([1, 0, 0]), 0.05)
    _, _, state, _, _ = contour_law(
        np.array([0.0, 0.0, 5.0]), *args[1:], np.zeros(3), state, _params()
    )
    assert state[LIFT] == pytest.approx(0.002 * 0.004)
    _, _, state, _, _ = contour_law(np.zeros(3), *args[1:], np.zeros(3), state, _params())
    assert state[LIFT] == pytest.approx(0.002 * 0.004 + 0.0005)


def test_parameters_are_all_named():
    with pytest.raises(TypeError, match="missing"):
        law_parameters(force_N=10.0)
    assert len(_params()) == len(PARAMETERS)


def test_the_turn_is_rate_limited_and_reaches_the_leg_orientation():
    from scipy.spatial.transform import Rotation

    Ra = np.eye(3)
    omega = np.array([0.0, 0.0, 0.8])  # 46 deg over the leg
    args = (Ra, omega, np.zeros(3), _unit([1, 0, 0]), 0.1)
    turn = turn_towards(np.eye(3), *args, np.array([0.1, 0.0, 0.0]), 0.002)
    assert np.linalg.norm(turn) == pytest.approx(0.002)
    R_end = Rotation.from_rotvec(omega).as_matrix()
    np.testing.assert_allclose(
        turn_towards(R_end, *args, np.array([0.1, 0, 0]), 0.002), 0.0, atol=1e-12
    )
    np.testing.assert_allclose(
        turn_towards(np.eye(3), *args, np.array([0.05, 0, 0]), 1.0), omega / 2, atol=1e-12
    )
