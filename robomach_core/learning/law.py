"""The control law of path learning, one 4 ms period of it: follow the wall by force.

PROBLEM   Path learning (``run``, chapter section 3.2) must follow the wall from rough guide
          points, every 4 ms, in a few microseconds of arithmetic: as Python on numpy 3-vectors
          the law cost more than the simulated cell it drives.
STRATEGY  Hybrid force/velocity contour following in the plane across the tool axis ``a``
          (the chapter's "constant contact force normal to the edge", with the direction of
          travel taken from the wall); docs/learning_model.md states the model:
            - the contact force across the axis, F_x = F - (F . a) a, gives the wall direction
              w = -F_x / |F_x|, low-passed (w <- normalise(w + beta (w_meas - w))); a force from
              more than 135 deg off w is the wall behind the tool (F_n = -|F_x|, w kept);
            - the tangent t = side * (w x a) is the direction of travel; along it the tool
              advances at the learning speed times ``speed_ratio`` (slower where the force
              climbs, chapter section 3.4 "slower at sharp corner");
            - across it, PI force control to the reference (eq. of the chapter's Yp loop):
                  v_w = Kp e + Ki integral(e),  e = F_ref - F_n,  F_n = |F_x|;
            - out of contact the tool searches along w at the search speed, advancing no faster
              (not at all before the first touch, a push of ``touched`` or more, not the
              sensor's noise, until it has searched ``first_across``), and
              after ``search_turn`` without the wall it searches across the leg again;
            - along the axis the tool holds the height the person taught, relative to the part:
                  h = H0 + G . (p - P0) + K (o_a + (o_b - o_a) f) - lift,
              the reference surface (H0, G at P0: the part's floor under the tool, K = -1/cos,
              or the guide points' plane, K = 1; ``route.HeightReference``) plus the leg's
              offsets interpolated by the progress f along it (the advance slowed where the
              route climbs faster than ``climb`` x the height loop's speed); the floor's own
              push (its part along the axis beyond the friction cone of a wall contact) sets
              the lift to put the tool ``clearance`` above where the floor pushed, and the
              lift fades over ``lift_decay`` of travel. Nothing depends on elapsed time or
              adds up noise: the same points give the same heights at any speed.
SOLUTION  ``contour_law`` (compiled with numba; its ``py_func`` is the same law in Python, the
          reference the tests compare it with) returns the period's motion and the law's new
          state; ``turn_towards`` turns the tool's orientation towards the leg's, rate-limited.
          ``controller_period`` is the controller's whole period around them (the measured
          wrench, the law, the recording's row, the turn) in one compiled call.
"""

from __future__ import annotations

import math

import numba
import numpy as np

from .._kernels import contact_wrench_tcp_base, exp3, log3, mul3, rotate

_jit = numba.njit(cache=True, fastmath=False, nogil=True)

# The law's state vector: its entries by name.
INTEGRAL, LIFT, H_GOAL_LAST, FOUND_WALL, EVER_TOUCHED, OUT_OF_CONTACT = range(6)
STATE_SIZE = 6
# The law's parameters (``run.contour_law_parameters``): their places in its vector.
(
    P_FORCE, P_KP, P_KI, P_VMAX, P_SEARCH, P_SPEED, P_BETA, P_DT, P_CONE, P_FLOOR_N,
    P_CLEARANCE, P_LIFT_DECAY, P_HEIGHT_TIME, P_HEIGHT_SPEED, P_BEHIND, P_CONTACT, P_FIRST,
    P_TURN, P_SLOW_FROM, P_SLOWEST_AT, P_SLOWEST, P_CLIMB, P_TOUCHED,
) = range(23)  # fmt: skip
PARAMETER_COUNT = 23


# A leg of the route, one row of ``legs``: start a (3), unit direction xp (3), length, the
# orientation at a (9, row-major), the rotation vector omega to the orientation at its end
# (3, in a's axes: slerp R_a exp(f omega)), the index of its first guide point, the height
# offsets over the reference surface at its two ends (``route.HeightReference``), and the
# chord the height's progress is measured along (start (3), unit direction (3), length: the
# walk's points beside the two guide points, ``route.Leg.height_chord``).
LEG_A, LEG_XP, LEG_LENGTH, LEG_RA, LEG_OMEGA, LEG_FIRST, LEG_OFFSETS = 0, 3, 6, 7, 16, 19, 20
LEG_HA, LEG_HXP, LEG_HLENGTH = 22, 25, 28
LEG_SIZE = 29
# The height reference under the tool (``route.HeightReference.at``): the surface's height
# along the axis H0 at P0 (3), its gradient G (3) across the axis, and the offsets' factor K.
REF_H0, REF_G, REF_P0, REF_K = 0, 1, 4, 7
REF_SIZE = 8
# The recording's columns, one row per period (``controller_period``): time, motor-side joints
# (6), measured TCP position (3) and rotation (9, row-major), sensor reading (6), compensated
# wrench in the tool frame (6), force normal to the edge, contact flag, wall direction (3), leg.
REC_TIME, REC_JOINTS, REC_POSITION, REC_ROTATION, REC_SENSOR, REC_TOOL = 0, 1, 7, 10, 19, 25
REC_NORMAL, REC_CONTACT, REC_YP, REC_SEGMENT = 31, 32, 33, 36
REC_WIDTH = 37


def initial_state() -> np.ndarray:
    """The law's state before the run: no integral, no lift, no wall found yet."""
    state = np.zeros(STATE_SIZE)
    state[H_GOAL_LAST] = np.nan
    return state


@_jit
def speed_ratio(f_n: float, f_ref: float, slow_from: float, slowest_at: float, slowest: float):
    """Share of the learning speed to advance at: 1 up to ``slow_from`` x F_ref, falling
    linearly to ``slowest`` at ``slowest_at`` x F_ref (the tool must back off a wall that
    turns towards it faster than it advances)."""
    over = (f_n / f_ref - slow_from) / (slowest_at - slow_from)
    return min(1.0, max(slowest, 1.0 - (1.0 - slowest) * over))


@_jit
def route_height(leg: np.ndarray, ref: np.ndarray, p: np.ndarray, axis: np.ndarray) -> float:
    """The height the route holds at ``p`` along ``axis`` [m] (module docstring), before lift:
    the reference surface there plus the leg's offsets interpolated by the progress on it."""
    s = 0.0
    dh = 0.0
    for i in range(3):
        s += (p[i] - leg[LEG_HA + i]) * leg[LEG_HXP + i]
        dh += ref[REF_G + i] * (p[i] - ref[REF_P0 + i])
    f = min(max(s / leg[LEG_HLENGTH], 0.0), 1.0)
    o_a, o_b = leg[LEG_OFFSETS], leg[LEG_OFFSETS + 1]
    return ref[REF_H0] + dh + ref[REF_K] * (o_a + (o_b - o_a) * f)


@_jit
def contour_law(
    force: np.ndarray,
    w: np.ndarray,
    axis: np.ndarray,
    side: float,
    leg: np.ndarray,
    ref: np.ndarray,
    p_ref: np.ndarray,
    state: np.ndarray,
    params: np.ndarray,
) -> tuple[np.ndarray, np.ndarray, np.ndarray, float, bool]:
    """One period of the law (module docstring).

    Args:
        force: (3,) measured contact force on the tool, base frame [N].
        w: (3,) the wall direction in use (unit, across ``axis``).
        axis: (3,) the height axis, into the part (unit).
        side: +1 wall on the right of travel, -1 on the left.
        leg: (LEG_SIZE,) the current leg (``LEG_A`` ...).
        ref: (REF_SIZE,) the height reference under the tool (``REF_H0`` ...).
        p_ref: (3,) the reference TCP position [m].
        state: (STATE_SIZE,) the law's state (``initial_state``); not modified.
        params: (PARAMETER_COUNT,) the law's parameters (``P_FORCE`` ...).

    Returns:
        (step (3,) [m] this period, new w, new state, F_n [N], touching).
    """
    f_ref, kp, ki, vmax = params[P_FORCE], params[P_KP], params[P_KI], params[P_VMAX]
    search, speed, beta, dt = params[P_SEARCH], params[P_SPEED], params[P_BETA], params[P_DT]
    out = state.copy()
    w_new = w.copy()
    ax, ay, az = axis[0], axis[1], axis[2]
    leg_xp = leg[LEG_XP : LEG_XP + 3]
    f_axis = force[0] * ax + force[1] * ay + force[2] * az  # < 0: pushed back up the axis
    px = force[0] - f_axis * ax
    py = force[1] - f_axis * ay
    pz = force[2] - f_axis * az
    f_across = math.sqrt(px * px + py * py + pz * pz)
    touching = f_across > params[P_CONTACT]
    f_n = f_across
    if touching:
        mx, my, mz = -px / f_across, -py / f_across, -pz / f_across
        if mx * w[0] + my * w[1] + mz * w[2] < params[P_BEHIND]:
            f_n = -f_across  # the wall behind the tool: move away from it, keep w
        else:
            wx = w[0] + beta * (mx - w[0])
            wy = w[1] + beta * (my - w[1])
            wz = w[2] + beta * (mz - w[2])
            norm = math.sqrt(wx * wx + wy * wy + wz * wz)
            w_new[0], w_new[1], w_new[2] = wx / norm, wy / norm, wz / norm
            out[FOUND_WALL] = 1.0
            if f_across >= params[P_TOUCHED]:  # a push, not the sensor's noise
                out[EVER_TOUCHED] = 1.0
            out[OUT_OF_CONTACT] = 0.0
    if not touching and out[FOUND_WALL] > 0.0 and out[OUT_OF_CONTACT] > params[P_TURN]:
        # the wall has been lost for a while: search across the leg again
        cx = (ay * leg_xp[2] - az * leg_xp[1]) * side
        cy = (az * leg_xp[0] - ax * leg_xp[2]) * side
        cz = (ax * leg_xp[1] - ay * leg_xp[0]) * side
        dot = cx * ax + cy * ay + cz * az
        cx, cy, cz = cx - dot * ax, cy - dot * ay, cz - dot * az
        norm = math.sqrt(cx * cx + cy * cy + cz * cz)
        w_new[0], w_new[1], w_new[2] = cx / norm, cy / norm, cz / norm
        out[FOUND_WALL] = 0.0
    # the tangent t = side * (w x a)
    tx = (w_new[1] * az - w_new[2] * ay) * side
    ty = (w_new[2] * ax - w_new[0] * az) * side
    tz = (w_new[0] * ay - w_new[1] * ax) * side
    e = f_ref - f_n
    limit = vmax if touching else search
    integral = min(max(out[INTEGRAL] + ki * e * dt, -limit), limit)
    out[INTEGRAL] = integral
    v_w = min(max(kp * e + integral, -vmax), limit)
    if touching:
        v_t = speed * speed_ratio(
            f_n, f_ref, params[P_SLOW_FROM], params[P_SLOWEST_AT], params[P_SLOWEST]
        )
    elif out[EVER_TOUCHED] > 0.0 or out[OUT_OF_CONTACT] > params[P_FIRST]:
        v_t = min(speed, search)
    else:
        v_t = 0.0  # the first search: straight across to the wall, nothing skipped
    # no faster than the height loop can follow the route's climb along the leg (a point
    # taught 12 mm above its neighbour 2 mm away): dh/ds = K (o_b - o_a) / L + G . xp, along
    # the height's chord
    slope = ref[REF_K] * (leg[LEG_OFFSETS + 1] - leg[LEG_OFFSETS]) / leg[LEG_HLENGTH]
    for i in range(3):
        slope += ref[REF_G + i] * leg[LEG_HXP + i]
    v_t = min(v_t, params[P_CLIMB] * params[P_HEIGHT_SPEED] / max(abs(slope), 1e-9))
    if not touching:
        out[OUT_OF_CONTACT] += math.sqrt(v_t * v_t + v_w * v_w) * dt
    # the height: the route's, lifted where the floor pushed (beyond a wall's friction cone)
    h_route = route_height(leg, ref, p_ref, axis)
    h_now = p_ref[0] * ax + p_ref[1] * ay + p_ref[2] * az
    if -f_axis > params[P_CONE] * f_across + params[P_FLOOR_N]:
        out[LIFT] = max(out[LIFT], h_route - h_now + params[P_CLEARANCE])
    else:
        out[LIFT] *= math.exp(-v_t * dt / params[P_LIFT_DECAY])
    h_goal = h_route - out[LIFT]
    h_rate = 0.0 if math.isnan(out[H_GOAL_LAST]) else (h_goal - out[H_GOAL_LAST]) / dt
    out[H_GOAL_LAST] = h_goal
    v_h = h_rate + (h_goal - h_now) / params[P_HEIGHT_TIME]
    v_h = min(max(v_h, -params[P_HEIGHT_SPEED]), params[P_HEIGHT_SPEED])
    step = np.empty(3)
    step[0] = (tx * v_t + w_new[0] * v_w + ax * v_h) * dt
    step[1] = (ty * v_t + w_new[1] * v_w + ay * v_h) * dt
    step[2] = (tz * v_t + w_new[2] * v_w + az * v_h) * dt
    return step, w_new, out, f_n, touching


@_jit
def turn_towards(
    R_ref: np.ndarray,
    R_leg_start: np.ndarray,
    omega: np.ndarray,
    leg_a: np.ndarray,
    leg_xp: np.ndarray,
    leg_length: float,
    p: np.ndarray,
    max_turn: float,
) -> np.ndarray:
    """The rotation vector (in the frame of ``R_ref``) that turns the tool towards the leg's
    orientation at ``p`` (R_a exp(f omega), f the progress along the leg, slerp between its
    guide points), at most ``max_turn`` [rad]: no jump where one leg hands over to the next."""
    s = (
        (p[0] - leg_a[0]) * leg_xp[0]
        + (p[1] - leg_a[1]) * leg_xp[1]
        + (p[2] - leg_a[2]) * leg_xp[2]
    )
    f = min(max(s / leg_length, 0.0), 1.0)
    turn = log3(mul3(R_ref, mul3(R_leg_start, exp3(omega * f)), True))
    angle = math.sqrt(turn[0] * turn[0] + turn[1] * turn[1] + turn[2] * turn[2])
    if angle > max_turn:
        turn = turn * (max_turn / angle)
    return turn


@_jit
def controller_period(
    reading: np.ndarray,
    T_meas: np.ndarray,
    q_motor: np.ndarray,
    time_s: float,
    tool_data: np.ndarray,
    R_tcp_flange: np.ndarray,
    leg: np.ndarray,
    ref: np.ndarray,
    axis: np.ndarray,
    side: float,
    T_ref: np.ndarray,
    w: np.ndarray,
    state: np.ndarray,
    params: np.ndarray,
    max_turn: float,
    step: np.ndarray,
    turn: np.ndarray,
    record: np.ndarray,
    n: int,
) -> tuple[float, bool, bool, float, float, float, float]:
    """One controller period of path learning: what the controller measures, the law, the
    recording's row ``n`` and the turn; ``w``, ``state`` (the law's), ``step`` and ``turn``
    are updated in place.

    The contact wrench is the reading compensated with the controller's tool data
    (``_kernels.contact_wrench_tcp_base``; ``tool_data``: weight m g (3), centre of mass (3),
    TCP (3) in the sensor frame, bias (6)); ``contour_law`` moves the reference ``T_ref``'s
    position by ``step``; ``turn_towards`` turns its orientation towards the ``leg``'s at the
    new position, at most ``max_turn`` [rad].

    Returns:
        (|F| [N], touching, ever touched, the law's distance out of contact [m], the
        reference's distance from the leg's line [m], the step's advance along the wall [m],
        the reference's progress along the leg [m]).
    """
    R_meas = T_meas[:3, :3]
    wrench = contact_wrench_tcp_base(
        reading, mul3(R_meas, R_tcp_flange), tool_data[:3], tool_data[3:6], tool_data[6:9],
        tool_data[9:15],
    )  # fmt: skip
    f_abs = math.sqrt(wrench[0] * wrench[0] + wrench[1] * wrench[1] + wrench[2] * wrench[2])
    a, xp, length = leg[LEG_A : LEG_A + 3], leg[LEG_XP : LEG_XP + 3], leg[LEG_LENGTH]
    p_ref = T_ref[:3, 3].copy()
    step_new, w_new, state_new, f_n, touching = contour_law(
        wrench[:3], w, axis, side, leg, ref, p_ref, state, params
    )
    w[:] = w_new
    state[:] = state_new
    step[:] = step_new
    contact = 1.0 if f_abs > params[P_CONTACT] else 0.0
    record_row(record[n], time_s, q_motor, T_meas, reading, wrench, f_n, contact, w, leg[LEG_FIRST])
    rel = p_ref - a
    along = rel @ xp
    off_route = math.sqrt(max(rel @ rel - along * along, 0.0))
    turn[:] = turn_towards(
        T_ref[:3, :3], leg[LEG_RA : LEG_RA + 9].reshape((3, 3)), leg[LEG_OMEGA : LEG_OMEGA + 3],
        a, xp, length, p_ref + step_new, max_turn,
    )  # fmt: skip
    # the advance along the wall (the tangent side * (w x a)): not the force loop's motion
    # across it nor the height's, which at slow feeds add up to more than the advance itself
    tx = (w[1] * axis[2] - w[2] * axis[1]) * side
    ty = (w[2] * axis[0] - w[0] * axis[2]) * side
    tz = (w[0] * axis[1] - w[1] * axis[0]) * side
    advance = abs(step_new[0] * tx + step_new[1] * ty + step_new[2] * tz)
    ever = state_new[EVER_TOUCHED] > 0.0
    return f_abs, touching, ever, state_new[OUT_OF_CONTACT], off_route, advance, along


@_jit
def record_row(
    row: np.ndarray,
    time_s: float,
    q_motor: np.ndarray,
    T_meas: np.ndarray,
    reading: np.ndarray,
    wrench: np.ndarray,
    f_n: float,
    contact: float,
    w: np.ndarray,
    leg_first: float,
) -> None:
    """Writes one period into the recording's ``row`` (``REC_TIME`` ...): ``wrench`` is the
    compensated contact wrench at the TCP in base axes, recorded in the tool's axes."""
    row[REC_TIME] = time_s
    row[REC_JOINTS : REC_JOINTS + 6] = q_motor
    for i in range(3):
        row[REC_POSITION + i] = T_meas[i, 3]
        for j in range(3):
            row[REC_ROTATION + 3 * i + j] = T_meas[i, j]
    row[REC_SENSOR : REC_SENSOR + 6] = reading
    row[REC_TOOL : REC_TOOL + 3] = rotate(T_meas, wrench, 0, True)
    row[REC_TOOL + 3 : REC_TOOL + 6] = rotate(T_meas, wrench, 3, True)
    row[REC_NORMAL] = f_n
    row[REC_CONTACT] = contact
    row[REC_YP : REC_YP + 3] = w
    row[REC_SEGMENT] = leg_first
