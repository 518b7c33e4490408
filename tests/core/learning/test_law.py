"""The compiled law of path learning equals its Python reference (the same law run by the
interpreter, ``py_func``), and does what its docstring says on simple cases: it slides along
the wall at the reference force, holds the route's height over its reference surface, lifts
only off a floor (not off a wall's friction), and nothing in the height depends on time."""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from robomach_core.learning import thresholds as th
from robomach_core.learning.law import (
    EVER_TOUCHED,
    LEG_SIZE,
    LIFT,
    OUT_OF_CONTACT,
    P_FORCE,
    P_SPEED,
    PARAMETER_COUNT,
    REF_SIZE,
    contour_law,
    initial_state,
    route_height,
    turn_towards,
)
from robomach_core.learning.run import contour_law_parameters
from robomach_core.learning.settings import PathLearningSettings

AXIS = np.array([0.0, 0.0, -1.0])  # tool straight down, into the part
DT = 0.004


def _params(**override: float) -> np.ndarray:
    return contour_law_parameters(replace(PathLearningSettings(), **override))


def _unit(v) -> np.ndarray:
    v = np.asarray(v, dtype=float)
    return v / np.linalg.norm(v)


def _leg(xp=(1.0, 0.0, 0.0), length=0.05, offsets=(0.0, 0.0)) -> np.ndarray:
    leg = np.zeros(LEG_SIZE)
    leg[3:6] = _unit(xp)
    leg[6] = length
    leg[7:16] = np.eye(3).ravel()
    leg[20:22] = offsets
    leg[25:28] = leg[3:6]  # the height's chord: the leg's own (no walk)
    leg[28] = length
    return leg


def _plane(h0=0.0, grad=(0.0, 0.0, 0.0), k=1.0) -> np.ndarray:
    ref = np.zeros(REF_SIZE)
    ref[0], ref[1:4], ref[7] = h0, grad, k
    return ref


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
    offsets=st.tuples(st.floats(-0.015, 0.015), st.floats(-0.015, 0.015)),
    length=st.floats(0.0015, 0.05),
    grad=st.tuples(st.floats(-0.4, 0.4), st.floats(-0.4, 0.4)),
    k=st.sampled_from([1.0, -1.0, -1.1]),
)
def test_the_compiled_law_equals_its_reference(
    force, w_angle, side, p, touched, out_m, lift, offsets, length, grad, k
):
    w = np.array([np.cos(w_angle), np.sin(w_angle), 0.0])
    state = initial_state()
    state[EVER_TOUCHED] = float(touched)
    state[LIFT] = lift
    state[OUT_OF_CONTACT] = out_m
    leg = _leg((1, 0.2, 0), length=length, offsets=offsets)
    ref = _plane(0.001, (grad[0], grad[1], 0.0), k)
    args = (force, w, AXIS, side, leg, ref, p, state, _params())
    got = contour_law(*args)
    want = contour_law.py_func(*args)
    for a, b in zip(got, want, strict=True):
        np.testing.assert_allclose(a, b, rtol=1e-12, atol=1e-15)
    assert route_height(leg, ref, p, AXIS) == pytest.approx(
        route_height.py_func(leg, ref, p, AXIS), abs=1e-15
    )


@settings(max_examples=200, deadline=None)
@given(
    rise=st.floats(-0.015, 0.015),
    length=st.floats(0.0015, 0.05),
    grad=st.floats(-0.4, 0.4),
    k=st.sampled_from([1.0, -1.0, -1.1]),
    speed_mm_s=st.sampled_from([0.5, 1.0, 2.0, 5.0, 10.0, 20.0]),
)
def test_the_advance_leaves_the_height_loop_room_to_follow_the_route(
    rise, length, grad, k, speed_mm_s
):
    """Along a leg whose height changes fast (a point taught far above a neighbour close by)
    the tool advances no faster than the height loop can follow: |v_t dh/ds| within
    CLIMB_SHARE x HEIGHT_SPEED_M_S; elsewhere at the learning speed."""
    w = np.array([0.0, -1.0, 0.0])
    state = initial_state()
    state[EVER_TOUCHED] = 1.0
    leg = _leg((1, 0, 0), length=length, offsets=(0.0, rise))
    ref = _plane(0.0, (grad, 0.0, 0.0), k)
    params = _params(speed_m_s=speed_mm_s * 1e-3)
    step, *_ = contour_law(np.array([0.0, 10.0, 0.0]), w, AXIS, 1.0, leg, ref, np.zeros(3), state,
                           params)  # fmt: skip
    v_t = step[0] / DT
    slope = abs(k * rise / length + grad)
    room = th.CLIMB_SHARE * th.HEIGHT_SPEED_M_S
    assert v_t * slope <= room * (1 + 1e-9)
    assert v_t == pytest.approx(min(speed_mm_s * 1e-3, room / max(slope, 1e-9)), rel=1e-9)


def test_pressed_at_the_reference_it_slides_along_the_wall():
    """The wall at -y pushes the tool with 10 N along +y: the law keeps w = -y, moves along the
    tangent (the wall on the right of travel, with the tool axis down), and not across it."""
    w = np.array([0.0, -1.0, 0.0])
    state = initial_state()
    state[EVER_TOUCHED] = 1.0
    step, w_new, _, f_n, touching = contour_law(
        np.array([0.0, 10.0, 0.0]), w, AXIS, 1.0, _leg(), _plane(), np.zeros(3), state, _params()
    )
    assert touching and f_n == pytest.approx(10.0)
    np.testing.assert_allclose(w_new, w, atol=1e-12)
    assert step[0] == pytest.approx(0.005 * DT)  # full learning speed along +x
    assert abs(step[1]) < 1e-7  # in balance across the wall


@given(st.floats(0.01, 0.99), st.floats(0.0, 1.0), st.floats(0.5, 20.0))
@settings(max_examples=60, deadline=None)
def test_the_sensors_noise_is_not_the_first_touch(share, later, speed_mm_s):
    """Before the first touch the tool goes straight across to the wall, nothing skipped: a
    force across the axis under ``WALL_FORCE_CLEAR_N`` (the sensor's noise, 0.3 N rms, can pass
    the contact flag's 1 N) does not count as it. Counted, the tool advanced along a wall it had
    not met and an open route's program began 3.5 mm past its first point (issue 28)."""
    w = np.array([0.0, -1.0, 0.0])
    params = _params(speed_m_s=speed_mm_s * 1e-3)
    noise = th.CONTACT_FLAG_N + share * (th.WALL_FORCE_CLEAR_N - th.CONTACT_FLAG_N)
    state = initial_state()
    _, _, state, _, touching = contour_law(
        np.array([0.0, noise, 0.0]), w, AXIS, 1.0, _leg(), _plane(), np.zeros(3), state, params
    )
    assert touching  # the contact flag, as recorded
    step, *_ = contour_law(
        np.array([0.0, later * th.CONTACT_FLAG_N, 0.0]), w, AXIS, 1.0, _leg(), _plane(),
        np.zeros(3), state, params,
    )  # fmt: skip
    assert step[0] == 0.0  # no advance along the wall: still the first search


def test_a_force_from_behind_pushes_the_tool_towards_its_wall_and_keeps_w():
    w = np.array([0.0, -1.0, 0.0])
    state = initial_state()
    state[EVER_TOUCHED] = 1.0
    step, w_new, _, f_n, _ = contour_law(
        np.array([0.0, -8.0, 0.0]), w, AXIS, 1.0, _leg(), _plane(), np.zeros(3), state, _params()
    )
    assert f_n == pytest.approx(-8.0)
    np.testing.assert_allclose(w_new, w)
    assert step[1] < 0.0  # towards its own wall (-y), away from the one behind


@settings(max_examples=100, deadline=None)
@given(
    offsets=st.tuples(st.floats(-0.005, 0.005), st.floats(-0.005, 0.005)),
    f=st.floats(0.0, 1.0),
    grad=st.tuples(st.floats(-0.4, 0.4), st.floats(-0.4, 0.4)),
    k=st.sampled_from([1.0, -1.05]),
)
def test_the_route_height_is_the_surface_plus_the_interpolated_offsets(offsets, f, grad, k):
    leg = _leg(offsets=offsets)
    ref = _plane(0.002, (grad[0], grad[1], 0.0), k)
    p = np.array([f * 0.05, 0.003, 0.0])
    offset = offsets[0] + (offsets[1] - offsets[0]) * f
    want = 0.002 + grad[0] * p[0] + grad[1] * p[1] + k * offset
    assert route_height(leg, ref, p, AXIS) == pytest.approx(want, abs=1e-12)


def _hold_height(force: np.ndarray, periods: int, speed_mm_s: float) -> tuple[float, float]:
    """Run the law ``periods`` times with the same contact force, moving the reference by its
    steps; the reference's height (along the axis) at the end, and the lift."""
    params = _params(speed_m_s=speed_mm_s * 1e-3)
    state = initial_state()
    state[EVER_TOUCHED] = 1.0
    w, p = np.array([0.0, -1.0, 0.0]), np.zeros(3)
    for _ in range(periods):
        step, w, state, _, _ = contour_law(
            force, w, AXIS, 1.0, _leg(length=1.0), _plane(), p, state, params
        )
        p = p + step
    return float(p @ AXIS), float(state[LIFT])


@pytest.mark.parametrize("speed_mm_s", [0.5, 20.0])
@pytest.mark.parametrize("force_N", [10.0, 20.0])
def test_a_walls_friction_along_the_axis_never_lifts_the_tool(force_N, speed_mm_s):
    """Pressed against a wall at 10-20 N with Coulomb friction (0.3) along the axis, or a wall
    20 deg off the axis: the force along the axis stays inside the cone a wall gives, so the
    height holds, at a slow feed as at a fast one (the landed law lifted 0.5 mm per push of
    2 N along the axis, and at 0.5 mm/s climbed out of the groove)."""
    for along in (0.3 * force_N, np.tan(np.radians(20)) * force_N):
        force = np.array([0.0, force_N, along])  # the wall at -y; +z is up, against the axis
        h, lift = _hold_height(force, 2000, speed_mm_s)
        assert lift == 0.0 and h == pytest.approx(0.0, abs=1e-9)


def test_the_floor_lifts_the_tool_clear_of_where_it_pushed_and_the_lift_fades_with_travel():
    params = _params()
    state = initial_state()
    state[EVER_TOUCHED] = 1.0
    w, leg, ref = np.array([0.0, -1.0, 0.0]), _leg(length=1.0), _plane()
    p = np.array([0.0, 0.0, -0.0003])  # 0.3 mm below the route: the floor is higher than known
    floor = np.array([0.0, 10.0, 12.0])  # the floor pushes up 12 N while the wall holds 10 N
    _, _, state, _, _ = contour_law(floor, w, AXIS, 1.0, leg, ref, p, state, params)
    # the goal goes the clearance above where the floor pushed: 0.5 mm over 0.3 mm below
    assert state[LIFT] == pytest.approx(0.0005 - 0.0003)
    lift = state[LIFT]
    travelled = 0.0
    free = np.array([0.0, 10.0, 0.0])
    while travelled < th.LIFT_DECAY_M:
        step, w, state, _, _ = contour_law(free, w, AXIS, 1.0, leg, ref, p, state, params)
        travelled += abs(step[0])
    assert state[LIFT] == pytest.approx(lift * np.exp(-travelled / th.LIFT_DECAY_M), rel=1e-3)


def test_every_parameter_has_its_place():
    params = _params(force_N=17.0, speed_m_s=0.002)
    assert params.shape == (PARAMETER_COUNT,) and np.all(np.isfinite(params))
    assert params[P_FORCE] == 17.0 and params[P_SPEED] == 0.002


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


def test_the_documented_thresholds_are_the_codes():
    """docs/learning_model.md's table is the thresholds module's, value for value."""
    from pathlib import Path

    doc = (Path(__file__).resolve().parents[3] / "docs" / "learning_model.md").read_text()
    table = doc.split("<!-- thresholds -->\n", 1)[1].split("<!-- /thresholds -->", 1)[0]
    assert table == th.table_markdown()
    # every threshold is a row: none written over several lines, where the table misses it
    names = [n for n in vars(th) if n.isupper() and not n.startswith("_")]
    assert sorted(names) == sorted(row.split("`")[1] for row in table.splitlines()[2:])


@settings(max_examples=50, deadline=None)
@given(
    start_mm=st.floats(0.0, 10.0),
    across_mm=st.floats(-3.0, 3.0),
    heading=st.floats(0.0, 2 * np.pi),
    end=st.sampled_from([0, -1]),
)
def test_an_open_routes_end_is_measured_across_the_wall_when_the_program_starts_late(
    start_mm, across_mm, heading, end
):
    """A program that starts ``start_mm`` after its first point's wall point (the force
    builds first) is measured across the line of its first move, up to OPEN_END_SHORT_M
    short; farther short, or beside the program rather than before it, the distance stands."""
    from robomach_core.learning.checks import _across_the_end

    t = np.array([np.cos(heading), np.sin(heading), 0.0])
    n = np.array([-t[1], t[0], 0.0])
    s = np.linspace(0.0, 0.05, 200)
    path = np.outer(s, t)  # starts at the origin along t; or, reversed, ends there along -t
    if end == -1:
        path = path[::-1]
    foot = -start_mm * 1e-3 * t + across_mm * 1e-3 * n
    idx = 0 if end == 0 else len(path) - 1
    gap = float(np.linalg.norm(foot - path[idx]))
    got = _across_the_end(path, idx, foot, gap)
    if start_mm * 1e-3 <= th.OPEN_END_SHORT_M:
        assert got == pytest.approx(abs(across_mm) * 1e-3, abs=1e-9)
    else:
        assert got == gap
