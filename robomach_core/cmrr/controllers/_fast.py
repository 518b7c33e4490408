"""Private fast copies of the controllers' ``step`` for the machining loop (x100 real time).

PROBLEM   The public controllers are immutable values whose ``step(state, measurement)``
          returns a new state and a ``ControlOutput``: clear, replayable, and 40-140 us a step
          for the fuzzy and LQ controllers (numpy on 5- and 6-element arrays, dataclasses),
          which holds a 4 ms machining loop to x30-x100 real time.
STRATEGY  ``fast_stepper(controller)`` returns a ``step(force_N, feed_m_s) -> (ratio, stop)``
          with the state held inside: the Mamdani inference and the LQ step's arithmetic in
          numba kernels (the LQ's Riccati re-design stays in Python and is cached); a
          controller without a fast copy is wrapped as it is. The public ``step`` stays the
          reference: tests drive both with the same signals and compare every output.
SOLUTION  ``fast_stepper``.
"""

from __future__ import annotations

import functools
import math
from collections.abc import Callable

import numba
import numpy as np

from .adaptive_lq import AdaptiveLqController
from .base import Measurement
from .fuzzy import (
    ERROR_TERMS,
    OUTPUT_SETS,
    OUTPUT_TERMS,
    OUTPUT_UNIVERSE,
    RATIO_TERMS,
    STOP,
    TREND_TERMS,
    FuzzyController,
    _next_stage,
)
from .pi import POWER_CAP_EXP, AdaptivePiController, FixedPiController, pi_gains

_jit = numba.njit(cache=True, fastmath=False, nogil=True)
Stepper = Callable[[float, float], tuple[float, bool]]


def fast_stepper(controller) -> Stepper:
    """A stateful ``step(force_N, feed_m_s) -> (speed_ratio, stop)`` equal to the controller's
    public ``step`` from its initial state."""
    if isinstance(controller, FuzzyController):
        return _FuzzyStepper(controller).step
    if isinstance(controller, AdaptiveLqController):
        return _LqStepper(controller).step
    if isinstance(controller, FixedPiController):
        return _fixed_pi_stepper(controller)
    if isinstance(controller, AdaptivePiController) and controller.settings.estimate_feed_exponent:
        f = controller.design.measurement_filter
        if f is None or len(f.sos) == 1:
            return _adaptive_pi_stepper(controller)
    state = [controller.initial_state()]

    def step(force_N: float, feed_m_s: float) -> tuple[float, bool]:
        state[0], out = controller.step(state[0], Measurement(force_N, feed_m_s))
        return out.speed_ratio, out.stop

    return step


def _fixed_pi_stepper(ctrl: FixedPiController) -> Stepper:
    """``FixedPiController.step`` (eqs. 10-13) as a closure over plain floats."""
    d = ctrl.design
    inv_beta = 1.0 / ctrl.feed_exponent
    kp, ki = ctrl.unit_gains
    kf = ctrl.design_force_gain_N
    cap = math.exp(POWER_CAP_EXP)
    dt, low = d.dt_s, d.min_speed_ratio

    def power(x: float) -> float:
        if x <= 0.0:
            return 0.0
        e = inv_beta * math.log(x)
        return math.exp(e) if e < POWER_CAP_EXP else cap

    ref = power(d.reference_force_N / kf)
    integral = [ctrl.initial_state().integral]

    def step(force_N: float, feed_m_s: float) -> tuple[float, bool]:
        error = ref - power((force_N if force_N > 0.0 else 0.0) / kf)
        u_free = kp * error + integral[0]
        u = 1.0 if u_free >= 1.0 else (low if u_free <= low else u_free)
        if not ((u_free >= 1.0 and error > 0.0) or (u_free <= low and error < 0.0)):
            integral[0] = min(max(integral[0] + ki * error * dt, low), 1.0)
        return u, False

    return step


def _adaptive_pi_stepper(ctrl: AdaptivePiController) -> Stepper:
    """``AdaptivePiController.step`` (eqs. 15-16 with ``rls._rls_update_2``) over plain floats."""
    d, s = ctrl.design, ctrl.settings
    est = ctrl.estimator
    st = ctrl.initial_state()
    (t0, t1) = st.rls.theta.tolist()
    (p00, p01), (p10, p11) = st.rls.covariance.tolist()
    x = [st.integral, t0, t1, p00, p01, p10, p11]
    filt = d.measurement_filter
    if filt is not None:
        b0, b1, b2, _, a1, a2 = filt.sos[0].tolist()
        z = list(st.feed_filter)
    lam = est.forgetting
    cap0, cap1 = (float(v) for v in est.max_variances)
    lo_b, hi_b = est.feed_exponent_bounds
    vr = d.command_speed_m_s
    log_vr_ref = math.log(vr / 1e-3)
    fr, low, dt = d.reference_force_N, d.min_speed_ratio, d.dt_s
    f_gate, v_gate = s.min_force_fraction * fr, s.min_feed_ratio * vr

    def step(force_N: float, feed_m_s: float) -> tuple[float, bool]:
        feed = feed_m_s
        if filt is not None:
            out = b0 * feed + z[0]
            z[0] = b1 * feed - a1 * out + z[1]
            z[1] = b2 * feed - a2 * out
            feed = out
        force = force_N if force_N > 0.0 else 0.0
        integral, t0, t1, p00, p01, p10, p11 = x
        if force > f_gate and feed > v_gate:
            x1 = math.log(feed / vr)
            y = math.log(force)
            px0 = p00 + p01 * x1
            px1 = p10 + p11 * x1
            denom = lam + (px0 + x1 * px1)
            g0, g1 = px0 / denom, px1 / denom
            err = y - (t0 + t1 * x1)
            n00 = (p00 - g0 * px0) / lam
            n01 = (p01 - g0 * px1) / lam
            n10 = (p10 - g1 * px0) / lam
            n11 = (p11 - g1 * px1) / lam
            n01 = n10 = 0.5 * (n01 + n10)
            if n00 > cap0 or n11 > cap1:
                s0 = math.sqrt(min(1.0, cap0 / max(n00, 1e-300)))
                s1 = math.sqrt(min(1.0, cap1 / max(n11, 1e-300)))
                n00, n01, n10, n11 = n00 * s0 * s0, n01 * s0 * s1, n10 * s1 * s0, n11 * s1 * s1
            t0, t1 = t0 + g0 * err, t1 + g1 * err
            p00, p01, p10, p11 = n00, n01, n10, n11
        beta = min(max(t1, lo_b), hi_b)
        kf_hat = math.exp(t0 - beta * log_vr_ref)
        inv_beta = 1.0 / beta
        kp, ki = pi_gains(s.loop_gain, vr, kf_hat**inv_beta, s.pi_zero_rad_s)
        error = fr**inv_beta - force**inv_beta
        if not math.isfinite(error):
            error = 0.0
        u_free = kp * error + integral
        u = 1.0 if u_free >= 1.0 else (low if u_free <= low else u_free)
        if not ((u_free >= 1.0 and error > 0.0) or (u_free <= low and error < 0.0)):
            integral = min(max(integral + ki * error * dt, low), 1.0)
        x[:] = integral, t0, t1, p00, p01, p10, p11
        return u, False

    return step


# --- fuzzy -----------------------------------------------------------------------------------


def _rule_table() -> np.ndarray:
    from .fuzzy import RULE_BASE

    rows = []
    for e, de, u, o in RULE_BASE:
        rows.append(
            (
                -1 if e is None else ERROR_TERMS.index(e),
                -1 if de is None else TREND_TERMS.index(de),
                -1 if u is None else RATIO_TERMS.index(u),
                -1 if o == STOP else OUTPUT_TERMS.index(o),
            )
        )
    return np.array(rows, dtype=np.int64)


@_jit
def _memberships(x: float, lo: float, hi: float, count: int, out: np.ndarray) -> None:
    """``fuzzy.triangular_memberships`` of ``count`` evenly spaced centres in [lo, hi] into
    ``out``."""
    width = (hi - lo) / (count - 1)
    xc = min(max(x, lo), hi)
    for i in range(count):
        g = 1.0 - abs(xc - (lo + i * width)) / width
        out[i] = g if g > 0.0 else 0.0


def sparse_sets(sets: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(index (k, 2), value (k, 2)) of the (at most two) output sets not zero at each of the k
    universe points, from ``sets`` (n_sets, k); -1 and 0 pad. Triangular sets overlap only
    their neighbours: a point under three sets is refused."""
    nonzero = sets > 0.0
    if int(nonzero.sum(axis=0).max(initial=0)) > 2:
        raise ValueError("the fast inference expects at most two output sets over a point")
    idx = np.full((sets.shape[1], 2), -1, dtype=np.int64)
    val = np.zeros((sets.shape[1], 2))
    for j in range(sets.shape[1]):
        on = np.flatnonzero(nonzero[:, j])
        idx[j, : len(on)] = on
        val[j, : len(on)] = sets[on, j]
    return idx, val


@functools.cache
def output_set_table() -> tuple[np.ndarray, np.ndarray]:
    """``sparse_sets`` of ``fuzzy.OUTPUT_SETS``."""
    return sparse_sets(np.asarray(OUTPUT_SETS, dtype=float))


@_jit
def _fuzzy_infer(
    e: float, de: float, ratio: float, lo: float, hi: float, rules: np.ndarray,
    set_idx: np.ndarray, set_val: np.ndarray, universe: np.ndarray, scratch: np.ndarray,
) -> tuple[float, float]:  # fmt: skip
    """``FuzzyController.infer`` on the normalized error and trend: Mamdani inference (min
    for AND, max for aggregation), centroid over the output universe. The machining kernel
    calls this very function.

    The output sets are stored sparsely (``sparse_sets``): at each universe point only the
    two sets that may be non-zero there (the aggregate is a max, so the others never count:
    the same numbers as the dense sets). Both are read without a branch: the aggregate's
    point-by-point branches were mispredicted at ~40 % of a fuzzy machining sample (issue 29).
    ``scratch`` (>= 16) holds the memberships and the rules' strengths.
    """
    mu_e = scratch[0:5]
    mu_de = scratch[5:8]
    mu_u = scratch[8:11]
    strength = scratch[11:16]
    _memberships(e, -1.0, 1.0, 5, mu_e)
    _memberships(de, -1.0, 1.0, 3, mu_de)
    _memberships(ratio, lo, hi, 3, mu_u)
    for o in range(5):
        strength[o] = 0.0
    stop = 0.0
    for r in range(rules.shape[0]):
        w = 1.0
        if rules[r, 0] >= 0:
            w = min(w, mu_e[rules[r, 0]])
        if rules[r, 1] >= 0:
            w = min(w, mu_de[rules[r, 1]])
        if rules[r, 2] >= 0:
            w = min(w, mu_u[rules[r, 2]])
        o = rules[r, 3]
        if o < 0:
            stop = max(stop, w)
        else:
            strength[o] = max(strength[o], w)
    area = 0.0
    moment = 0.0
    for j in range(universe.shape[0]):
        o0, o1 = set_idx[j, 0], set_idx[j, 1]
        v0 = min(strength[o0], set_val[j, 0]) if o0 >= 0 else 0.0
        v1 = min(strength[o1], set_val[j, 1]) if o1 >= 0 else 0.0
        a = v0 if v0 >= v1 else v1
        area += a
        moment += a * universe[j]
    return (moment / area if area > 0.0 else 0.0), stop


class _FuzzyStepper:
    """``FuzzyController.step`` with the state in attributes and the inference compiled."""

    def __init__(self, ctrl: FuzzyController) -> None:
        s0 = ctrl.initial_state()
        self.ctrl = ctrl
        self.f = ctrl.fuzzy
        self.d = ctrl.design
        self.e_span, self.de_span = ctrl.spans
        self.rules = _rule_table()
        self.internal, self.stage = s0.internal_ratio, s0.stage
        self.trend, self.previous = s0.trend_N_s, s0.previous_error_N
        self.protection, self.stopped = s0.protection_time_s, s0.stopped
        self.since = s0.since_switch_s
        self.a = math.exp(-self.d.dt_s / self.f.trend_filter_s)
        self.set_idx, self.set_val = output_set_table()
        self.universe = np.ascontiguousarray(OUTPUT_UNIVERSE, dtype=float)
        self.scratch = np.zeros(16)

    def step(self, force_N: float, feed_m_s: float) -> tuple[float, bool]:
        f, d = self.f, self.d
        if self.stopped:
            return 0.0, True
        error = force_N - d.reference_force_N
        raw_trend = (error - self.previous) / d.dt_s
        trend = self.a * self.trend + (1.0 - self.a) * raw_trend
        self.since += d.dt_s
        if self.since < f.switch_settle_s:
            trend = 0.0
        stages = f.stages
        change, stop_strength = _fuzzy_infer(
            error / self.e_span, trend / self.de_span, stages[self.stage], stages[0],
            stages[-1], self.rules, self.set_idx, self.set_val, self.universe, self.scratch,
        )  # fmt: skip
        firing = stop_strength >= f.stop_strength
        protection = self.protection + d.dt_s if firing else 0.0
        self.trend, self.previous, self.protection = trend, error, protection
        if firing and protection >= f.stop_hold_s:
            self.stopped = True
            return 0.0, True
        internal = self.internal + change * f.max_rate_per_s * d.dt_s
        internal = min(max(internal, stages[0]), stages[-1])
        internal, stage = _next_stage(
            stages, self.stage, internal, max(force_N, 0.0), d, f.hysteresis, f.stage_up_margin
        )
        if stage != self.stage:
            self.since = 0.0
        self.internal, self.stage = internal, stage
        return stages[stage], False


# --- adaptive LQ -----------------------------------------------------------------------------


@_jit
def _lq_estimate(
    x_hat: np.ndarray, kalman: np.ndarray, c: np.ndarray, feed: float, force: float,
    sos: np.ndarray, zf: np.ndarray, sphi: np.ndarray, sgam: np.ndarray, svf_f: np.ndarray,
    svf_v: np.ndarray, scal: np.ndarray,
) -> None:  # fmt: skip
    """The LQ step up to the Df estimate, in place: Kalman measurement update, the feed's
    low-pass (``zf``, empty: none), the state-variable filters and the RLS.

    ``scal`` = [fr, kf, vr, adapt, lam, theta, p, r2] (theta, p, r2 updated in place).
    """
    y_hat = 0.0
    for i in range(x_hat.shape[0]):
        y_hat += c[i] * x_hat[i]
    innovation = feed - y_hat
    for i in range(x_hat.shape[0]):
        x_hat[i] += kalman[i] * innovation
    feed_f = feed
    if zf.shape[0] == 2:
        b0, b1, b2, a1, a2 = sos[0], sos[1], sos[2], sos[4], sos[5]
        out = b0 * feed + zf[0]
        zf[0] = b1 * feed - a1 * out + zf[1]
        zf[1] = b2 * feed - a2 * out
        feed_f = out
    f0 = sphi[0, 0] * svf_f[0] + sphi[0, 1] * svf_f[1] + sgam[0] * force
    f1 = sphi[1, 0] * svf_f[0] + sphi[1, 1] * svf_f[1] + sgam[1] * force
    v0 = sphi[0, 0] * svf_v[0] + sphi[0, 1] * svf_v[1] + sgam[0] * feed_f
    v1 = sphi[1, 0] * svf_v[0] + sphi[1, 1] * svf_v[1] + sgam[1] * feed_f
    svf_f[0], svf_f[1], svf_v[0], svf_v[1] = f0, f1, v0, v1
    fr, kf, vr, adapt, lam = scal[0], scal[1], scal[2], scal[3], scal[4]
    y = f0 / fr
    x = (v0 - f1 / kf) / vr
    if adapt > 0.5 and x > 0.03 and y > 0.03:
        theta, p, r2 = scal[5], scal[6], scal[7]
        residual = y - theta * x
        gain = p * x / (lam + x * p * x)
        theta = theta + gain * residual
        p = min((p - gain * x * p) / lam, 1.0e3)
        r2 = lam * r2 + (1.0 - lam) * residual * residual
        scal[5], scal[6], scal[7] = theta, p, r2


@_jit
def lq_command(
    gain: np.ndarray, feedforward: float, x_hat: np.ndarray, delayed: np.ndarray, force: float,
    integral: float, fr: float,
) -> float:  # fmt: skip
    """``adaptive_lq._lq_command``, eq. (13) with the integral state [mm/s]: -L [x_hat;
    delayed; F; xi] + lr Fr, summed in one fixed order (x_hat, the delayed commands, then F
    and xi). The machining kernel calls this very function: the reference loop and the
    compiled one then agree to the last bit, where two orders of the same sum parted by an
    ulp, and an ulp moved the LQ's Df grid switch by a sample at a knife edge (issue 29)."""
    n = x_hat.shape[0]
    feedback = 0.0
    for i in range(n):
        feedback += gain[i] * x_hat[i]
    for i in range(delayed.shape[0]):
        feedback += gain[n + i] * delayed[i]
    o = n + delayed.shape[0]
    feedback = feedback + gain[o] * force + gain[o + 1] * integral
    return -feedback + feedforward * fr


@_jit
def lq_matching_integral(
    gain: np.ndarray, feedforward: float, x_hat: np.ndarray, delayed: np.ndarray, force: float,
    fr: float, command: float, fallback: float,
) -> float:  # fmt: skip
    """``adaptive_lq._matching_integral``: the integral state for which the design (``gain``,
    ``feedforward``) commands ``command`` at this state (``fallback`` without an integral)."""
    li = gain[x_hat.shape[0] + delayed.shape[0] + 1]
    if abs(li) < 1e-12:
        return fallback
    without = lq_command(gain, feedforward, x_hat, delayed, force, 0.0, fr)
    return (without - command) / li


@_jit
def _lq_act(
    gain: np.ndarray, feedforward: float, x_hat: np.ndarray, delayed: np.ndarray, force: float,
    integral: float, fr: float, vr: float, low: float, active: bool, startup: float, dt: float,
    phi: np.ndarray, gamma: np.ndarray,
) -> tuple[float, float]:  # fmt: skip
    """The LQ step after the estimate, in place: eq. (13)'s command with the integral state,
    saturation (anti-windup), the delay line and the Kalman time update. Returns (ratio,
    integral)."""
    n = x_hat.shape[0]
    if active:
        u = lq_command(gain, feedforward, x_hat, delayed, force, integral, fr) / vr
        ratio = 1.0 if u >= 1.0 else (low if u <= low else u)
        error = fr - force
        pushing = (ratio >= 1.0 and error > 0.0) or (ratio <= low and error < 0.0)
        if not pushing:
            integral += dt * error
    else:
        ratio = startup
    command = ratio * vr
    acting = delayed[0] if delayed.shape[0] > 0 else command
    nxt = np.empty(n)
    for i in range(n):
        acc = gamma[i] * acting
        for j in range(n):
            acc += phi[i, j] * x_hat[j]
        nxt[i] = acc
    x_hat[:] = nxt
    if delayed.shape[0] > 0:
        for i in range(delayed.shape[0] - 1):
            delayed[i] = delayed[i + 1]
        delayed[-1] = command
    return ratio, integral


class _LqStepper:
    """``AdaptiveLqController.step`` with the state in arrays and the arithmetic compiled."""

    def __init__(self, ctrl: AdaptiveLqController) -> None:
        st = ctrl.initial_state()
        s, d = ctrl.settings, ctrl.design
        self.ctrl, self.s, self.d = ctrl, s, d
        self.phi, self.gamma, self.c = (np.ascontiguousarray(a) for a in ctrl.robot)
        self.kalman = np.ascontiguousarray(ctrl.kalman_gain)
        self.sphi, self.sgam = (np.ascontiguousarray(a) for a in ctrl.svf)
        filt = d.measurement_filter
        if filt is not None and len(filt.sos) != 1:
            raise ValueError("the fast LQ expects a one-section measurement filter")
        self.sos = np.ascontiguousarray(filt.sos[0]) if filt is not None else np.zeros(6)
        self.zf = np.array(st.feed_filter, dtype=float) if filt is not None else np.zeros(0)
        self.x_hat = np.array(st.x_hat, dtype=float)
        self.svf_f = np.array(st.svf_force, dtype=float)
        self.svf_v = np.array(st.svf_feed, dtype=float)
        self.scal = np.array(
            [d.reference_force_N, ctrl.kf, ctrl.vr_mm_s, 1.0 if s.adapt else 0.0,
             s.forgetting_factor, st.theta, st.covariance, st.residual_var]
        )  # fmt: skip
        self.delayed = np.array(st.commands_mm_s, dtype=float)
        self.integral, self.time_s, self.active = st.integral_N_s, st.time_s, st.active
        self.lq = st.design
        self.gain = np.ascontiguousarray(self.lq.gain)
        self.grid_key = self.lq.removal_N_s_mm
        self._set_cell()

    def _set_cell(self) -> None:
        """The Df_hat interval (open, with a 1e-9 margin to the rounding's ties) that the
        current design's grid point stands for."""
        tol = self.s.resolve_tolerance
        if tol <= 0.0:
            self.cell_lo = self.cell_hi = self.grid_key
            return
        half = math.sqrt(1.0 + tol)
        self.cell_lo = self.grid_key / half * (1.0 + 1e-9)
        self.cell_hi = self.grid_key * half * (1.0 - 1e-9)

    def step(self, force_N: float, feed_m_s: float) -> tuple[float, bool]:
        s, d, ctrl = self.s, self.d, self.ctrl
        fr = d.reference_force_N
        force = force_N
        _lq_estimate(
            self.x_hat, self.kalman, self.c, feed_m_s / 1e-3, force, self.sos, self.zf,
            self.sphi, self.sgam, self.svf_f, self.svf_v, self.scal,
        )  # fmt: skip
        theta, p, r2 = self.scal[5], self.scal[6], self.scal[7]
        df_hat = theta * fr / ctrl.vr_mm_s
        self.time_s += d.dt_s
        # The grid cell of the current design: inside it, ``_grid`` would return its centre.
        if s.adapt and not (self.cell_lo < df_hat < self.cell_hi):
            grid_df = ctrl._grid(df_hat)
            if grid_df is not None and grid_df != self.grid_key:
                old = self.lq
                lq = ctrl.solve(grid_df)
                if self.active:
                    before = lq_command(
                        self.gain, old.feedforward, self.x_hat, self.delayed, force,
                        self.integral, fr,
                    )  # fmt: skip
                    self.integral = lq_matching_integral(
                        np.ascontiguousarray(lq.gain), lq.feedforward, self.x_hat,
                        self.delayed, force, fr, before, self.integral,
                    )  # fmt: skip
                self.lq, self.gain, self.grid_key = lq, np.ascontiguousarray(lq.gain), grid_df
                self._set_cell()
        if not self.active and self.time_s >= s.min_startup_s:
            rel_std = math.sqrt(max(r2 * p, 0.0)) / max(abs(theta), 1e-9)
            if not s.adapt or rel_std < s.activation_rel_std:
                self.active = True
                last = float(self.delayed[-1]) if self.delayed.shape[0] else None
                current = s.startup_speed_ratio * ctrl.vr_mm_s if last is None else last
                self.integral = lq_matching_integral(
                    self.gain, self.lq.feedforward, self.x_hat, self.delayed, force, fr,
                    current, self.integral,
                )  # fmt: skip
        ratio, self.integral = _lq_act(
            self.gain, self.lq.feedforward, self.x_hat, self.delayed, force, self.integral, fr,
            ctrl.vr_mm_s, d.min_speed_ratio, self.active, s.startup_speed_ratio, d.dt_s,
            self.phi, self.gamma,
        )  # fmt: skip
        return ratio, False
