"""The machining run's 4 ms loop compiled (numba): the private copy of ``_loop.cut_loop``.

PROBLEM   A machining run is 30 000-60 000 control periods, and offline compensation rehearses
          it four times; in Python (scalar floats, one controller call a period) a run took
          0.2-0.7 s and a compensated one 1-4 s, so an 18-run comparison took seconds and a
          sweep over a hundred castings many minutes.
STRATEGY  The loop of ``_loop.cut_loop`` (the reference: eq. (1) feed, the sensor's filter, the
          process force eqs. (3)-(6), the deflection, online compensation, force supervision)
          and each controller's step (``cmrr.controllers._fast``, itself tested against the
          public ``step``) as numba functions over plain arrays. A controller is packed once
          (``pack_controller``) into a kind, float parameters and a float state; the sensor
          noise is drawn from the same ``numpy.random.Generator`` (numba draws the same stream).
          The adaptive LQ re-solves its Riccati equation in Python (``_solve_lq``, cached): the
          kernel carries a table of designs on the Df grid, and when the estimate reaches a
          grid point not in the table it returns that point; the caller adds the design and
          runs the cut again from the start (same seed, same numbers).
          The fuzzy inference and the LQ's command are not copied: the kernel calls
          ``_fast._fuzzy_infer``, ``_fast.lq_command`` and ``_fast.lq_matching_integral``,
          which the reference loop's steppers call too. The two loops then run the same
          operations in the same order and agree to the last bit (tests ask it): a copy that
          summed the LQ's command in another order parted from the reference by an ulp, and
          the Df grid switch turned that ulp into a cut 6 samples longer (issue 29).
SOLUTION  ``cut_kernel`` and ``pack_controller``; ``run.cut_program`` calls them, and falls back
          to the reference loop for a controller setting the kernel does not cover (tests keep
          the two equal).
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass, field

import numba
import numpy as np

from ..cmrr.controllers._fast import (
    _fuzzy_infer,
    lq_command,
    lq_matching_integral,
    output_set_table,
)

_jit = numba.njit(cache=True, fastmath=False, nogil=True)
# The loop's parts, inlined into it by numba (a call with a dozen array arguments per sample
# doubled a PI sample's time).
_jit_inline = numba.njit(cache=True, fastmath=False, nogil=True, inline="always")

# Controller kinds of the kernel.
KIND_NONE = 0  # constant feed: the program's speed
KIND_FIXED_PI = 1
KIND_ADAPTIVE_PI = 2
KIND_FUZZY = 3  # fuzzy and two-stage
KIND_LQ = 4
# Events the kernel returns besides a finished cut.
EVENT_DONE = 0
EVENT_NEED_DESIGN = 1  # the LQ reached a Df grid point not in its table (index in ``value``)
EVENT_SAMPLE_LIMIT = 2
# The LQ step's answer when its table holds the design it needs.
NO_DESIGN_NEEDED = -(2**62)
# Stop reasons.
STOP_NONE = 0
STOP_PROTECTION = 1
STOP_SUPERVISION = 2
# Output columns of the kernel (the order of ``_loop.TRACE_NAMES``).
COLUMNS = 10
POWER_CAP_EXP = 300.0


@dataclass(eq=False)
class PackedController:
    """A controller as the kernel runs it.

    Attributes:
        kind: ``KIND_*``.
        fp: float parameters; ``fs`` the float state (copied for every run).
        stages, rules, set_idx, set_val, universe: the fuzzy controller's tables (output
            sets by ``_fast.sparse_sets``; empty otherwise).
        lq_*: the adaptive LQ's matrices and its table of designs on the Df grid
            (``lq_index0`` the grid index of row 0; rows not designed yet have ``lq_have`` 0).
        first_ratio: the speed ratio before the first command.
        solve: for the LQ, ``solve(grid_index) -> (gain, feedforward)``.
    """

    kind: int
    fp: np.ndarray
    fs: np.ndarray
    first_ratio: float
    stages: np.ndarray = field(default_factory=lambda: np.zeros(1))
    rules: np.ndarray = field(default_factory=lambda: np.zeros((1, 4), dtype=np.int64))
    set_idx: np.ndarray = field(default_factory=lambda: np.full((1, 2), -1, dtype=np.int64))
    set_val: np.ndarray = field(default_factory=lambda: np.zeros((1, 2)))
    universe: np.ndarray = field(default_factory=lambda: np.zeros(1))
    lq_mats: np.ndarray = field(default_factory=lambda: np.zeros((1, 1)))
    lq_vecs: np.ndarray = field(default_factory=lambda: np.zeros((1, 1)))
    lq_gains: np.ndarray = field(default_factory=lambda: np.zeros((1, 1)))
    lq_ff: np.ndarray = field(default_factory=lambda: np.zeros(1))
    lq_have: np.ndarray = field(default_factory=lambda: np.zeros(1, dtype=np.int64))
    lq_index0: int = 0
    solve: Callable[[int], tuple[np.ndarray, float]] | None = None

    def add_design(self, index: int) -> None:
        """Add the LQ design of grid ``index`` (growing the table) from ``solve``."""
        lo, n = self.lq_index0, len(self.lq_ff)
        if index < lo or index >= lo + n:
            new_lo = min(lo, index - 4)
            new_hi = max(lo + n, index + 5)
            gains = np.zeros((new_hi - new_lo, self.lq_gains.shape[1]))
            ff = np.zeros(new_hi - new_lo)
            have = np.zeros(new_hi - new_lo, dtype=np.int64)
            gains[lo - new_lo : lo - new_lo + n] = self.lq_gains
            ff[lo - new_lo : lo - new_lo + n] = self.lq_ff
            have[lo - new_lo : lo - new_lo + n] = self.lq_have
            self.lq_gains, self.lq_ff, self.lq_have, self.lq_index0 = gains, ff, have, new_lo
        assert self.solve is not None  # pack_controller gives every LQ its solve
        gain, feedforward = self.solve(index)
        row = index - self.lq_index0
        self.lq_gains[row] = gain
        self.lq_ff[row] = feedforward
        self.lq_have[row] = 1


def pack_controller(ctrl) -> PackedController | None:
    """The kernel's form of ``ctrl`` (None: constant feed), or ``NotImplemented`` when the
    kernel has no copy of this controller's setting (the caller runs the reference loop)."""
    from ..cmrr.controllers import (
        AdaptiveLqController,
        AdaptivePiController,
        FixedPiController,
        FuzzyController,
    )

    if ctrl is None:
        return PackedController(KIND_NONE, np.zeros(1), np.zeros(1), 1.0)
    if isinstance(ctrl, FixedPiController):
        return _pack_fixed_pi(ctrl)
    if isinstance(ctrl, AdaptivePiController):
        f = ctrl.design.measurement_filter
        if ctrl.settings.estimate_feed_exponent and (f is None or len(f.sos) == 1):
            return _pack_adaptive_pi(ctrl)
        return NotImplemented
    if isinstance(ctrl, FuzzyController):
        return _pack_fuzzy(ctrl)
    if isinstance(ctrl, AdaptiveLqController):
        f = ctrl.design.measurement_filter
        if ctrl.settings.resolve_tolerance > 0.0 and (f is None or len(f.sos) == 1):
            return _pack_lq(ctrl)
        return NotImplemented
    return NotImplemented


def _pack_fixed_pi(ctrl) -> PackedController:
    from ..cmrr.controllers.pi import POWER_CAP_EXP as CAP

    d = ctrl.design
    inv_beta = 1.0 / ctrl.feed_exponent
    kp, ki = ctrl.unit_gains
    kf = ctrl.design_force_gain_N
    ref = _power_py(d.reference_force_N / kf, inv_beta, CAP)
    fp = np.array([ref, kf, inv_beta, kp, ki, d.dt_s, d.min_speed_ratio])
    return PackedController(
        KIND_FIXED_PI, fp, np.array([ctrl.initial_state().integral]), ctrl.initial_speed_ratio
    )


def _power_py(x: float, p: float, cap: float) -> float:
    if x <= 0.0:
        return 0.0
    e = p * math.log(x)
    return math.exp(e) if e < cap else math.exp(cap)


def _pack_adaptive_pi(ctrl) -> PackedController:
    from ..cmrr.controllers.base import FEED_REF_M_S

    d, s = ctrl.design, ctrl.settings
    est = ctrl.estimator
    st = ctrl.initial_state()
    (t0, t1) = st.rls.theta.tolist()
    (p00, p01), (p10, p11) = st.rls.covariance.tolist()
    filt = d.measurement_filter
    if filt is not None:
        b0, b1, b2, _, a1, a2 = filt.sos[0].tolist()
        z0, z1 = st.feed_filter
    else:
        b0 = b1 = b2 = a1 = a2 = z0 = z1 = 0.0
    cap0, cap1 = (float(v) for v in est.max_variances)
    lo_b, hi_b = est.feed_exponent_bounds
    vr = d.command_speed_m_s
    fr = d.reference_force_N
    fp = np.array(
        [
            b0, b1, b2, a1, a2, 1.0 if filt is not None else 0.0,
            est.forgetting, cap0, cap1, lo_b, hi_b, vr, math.log(vr / 1e-3), fr,
            d.min_speed_ratio, d.dt_s, s.min_force_fraction * fr, s.min_feed_ratio * vr,
            s.loop_gain, s.pi_zero_rad_s, vr / FEED_REF_M_S,
        ]
    )  # fmt: skip
    fs = np.array([st.integral, t0, t1, p00, p01, p10, p11, z0, z1])
    return PackedController(KIND_ADAPTIVE_PI, fp, fs, ctrl.initial_speed_ratio)


def _pack_fuzzy(ctrl) -> PackedController:
    from ..cmrr.controllers._fast import _rule_table
    from ..cmrr.controllers.fuzzy import OUTPUT_UNIVERSE

    f, d = ctrl.fuzzy, ctrl.design
    s0 = ctrl.initial_state()
    e_span, de_span = ctrl.spans
    fp = np.array(
        [
            d.reference_force_N, e_span, de_span, math.exp(-d.dt_s / f.trend_filter_s), d.dt_s,
            f.stop_strength, f.stop_hold_s, f.max_rate_per_s, f.hysteresis,
            d.nominal_feed_exponent, f.switch_settle_s, f.stage_up_margin,
        ]
    )  # fmt: skip
    fs = np.array(
        [
            s0.internal_ratio, float(s0.stage), s0.trend_N_s, s0.previous_error_N,
            s0.protection_time_s, 1.0 if s0.stopped else 0.0, s0.since_switch_s,
        ]
    )  # fmt: skip
    set_idx, set_val = output_set_table()
    return PackedController(
        KIND_FUZZY, fp, fs, ctrl.initial_speed_ratio,
        stages=np.array(f.stages, dtype=float), rules=_rule_table(), set_idx=set_idx,
        set_val=set_val, universe=np.ascontiguousarray(OUTPUT_UNIVERSE, dtype=float),
    )  # fmt: skip


def _pack_lq(ctrl) -> PackedController:
    s, d = ctrl.settings, ctrl.design
    st = ctrl.initial_state()
    phi, gamma, c = (np.asarray(a, dtype=float) for a in ctrl.robot)
    n = phi.shape[0]
    delay = len(st.commands_mm_s)
    sphi, sgam = (np.asarray(a, dtype=float) for a in ctrl.svf)
    filt = d.measurement_filter
    sos = np.asarray(filt.sos[0], dtype=float) if filt is not None else np.zeros(6)
    zf = list(st.feed_filter) if filt is not None else [0.0, 0.0]
    # Matrices: phi (n x n) | svf phi (2 x 2), padded into one (max(n, 2), n + 2) array.
    rows = max(n, 2)
    mats = np.zeros((rows, n + 2))
    mats[:n, :n] = phi
    mats[:2, n : n + 2] = sphi
    # Vectors: gamma, c, kalman, svf gamma (padded to n), sos (6).
    vecs = np.zeros((5, max(n, 6)))
    vecs[0, :n] = gamma
    vecs[1, :n] = c
    vecs[2, :n] = np.asarray(ctrl.kalman_gain, dtype=float)
    vecs[3, :2] = sgam
    vecs[4, :6] = sos
    tol = s.resolve_tolerance
    step = math.log1p(tol)
    fp = np.array(
        [
            d.reference_force_N, ctrl.kf, ctrl.vr_mm_s, 1.0 if s.adapt else 0.0,
            s.forgetting_factor, ctrl.df0, step, math.sqrt(1.0 + tol), d.min_speed_ratio,
            s.startup_speed_ratio, d.dt_s, s.min_startup_s, s.activation_rel_std,
            1.0 if filt is not None else 0.0, float(n), float(delay),
        ]
    )  # fmt: skip
    # State: x_hat (n), delayed (delay), svf_f (2), svf_v (2), zf (2), theta, p, r2, integral,
    # time, active, grid index.
    fs = np.concatenate(
        [
            np.asarray(st.x_hat, dtype=float), np.asarray(st.commands_mm_s, dtype=float),
            np.asarray(st.svf_force), np.asarray(st.svf_feed), np.asarray(zf, dtype=float),
            [st.theta, st.covariance, st.residual_var, st.integral_N_s, st.time_s,
             1.0 if st.active else 0.0, 0.0],
        ]
    )  # fmt: skip
    m = len(st.design.gain)
    df0 = ctrl.df0

    def solve(index: int) -> tuple[np.ndarray, float]:
        lq = ctrl.solve(df0 if index == 0 else df0 * math.exp(step * index))
        return np.asarray(lq.gain, dtype=float), float(lq.feedforward)

    packed = PackedController(
        KIND_LQ, fp, fs, ctrl.initial_speed_ratio, lq_mats=mats, lq_vecs=vecs,
        lq_gains=np.zeros((1, m)), lq_ff=np.zeros(1), lq_have=np.zeros(1, dtype=np.int64),
        lq_index0=0, solve=solve,
    )  # fmt: skip
    packed.lq_gains[0] = np.asarray(st.design.gain, dtype=float)
    packed.lq_ff[0] = float(st.design.feedforward)
    packed.lq_have[0] = 1
    return packed


# --- the controllers' steps ------------------------------------------------------------------


@_jit
def _power(x: float, p: float) -> float:
    if x <= 0.0:
        return 0.0
    e = p * math.log(x)
    return math.exp(e) if e < POWER_CAP_EXP else math.exp(POWER_CAP_EXP)


@_jit
def _fixed_pi_step(fp: np.ndarray, fs: np.ndarray, force: float) -> float:
    """``_fast._fixed_pi_stepper``'s step."""
    ref, kf, inv_beta, kp, ki, dt, low = fp[0], fp[1], fp[2], fp[3], fp[4], fp[5], fp[6]
    error = ref - _power((force if force > 0.0 else 0.0) / kf, inv_beta)
    u_free = kp * error + fs[0]
    u = 1.0 if u_free >= 1.0 else (low if u_free <= low else u_free)
    if not ((u_free >= 1.0 and error > 0.0) or (u_free <= low and error < 0.0)):
        fs[0] = min(max(fs[0] + ki * error * dt, low), 1.0)
    return u


@_jit
def _adaptive_pi_step(fp: np.ndarray, fs: np.ndarray, force_N: float, feed_m_s: float) -> float:
    """``_fast._adaptive_pi_stepper``'s step (eqs. 15-16)."""
    feed = feed_m_s
    if fp[5] > 0.5:
        out = fp[0] * feed + fs[7]
        fs[7] = fp[1] * feed - fp[3] * out + fs[8]
        fs[8] = fp[2] * feed - fp[4] * out
        feed = out
    force = force_N if force_N > 0.0 else 0.0
    integral, t0, t1, p00, p01, p10, p11 = fs[0], fs[1], fs[2], fs[3], fs[4], fs[5], fs[6]
    lam, cap0, cap1, lo_b, hi_b = fp[6], fp[7], fp[8], fp[9], fp[10]
    vr, log_vr_ref, fr, low, dt = fp[11], fp[12], fp[13], fp[14], fp[15]
    if force > fp[16] and feed > fp[17]:
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
        n01 = 0.5 * (n01 + n10)
        n10 = n01
        if n00 > cap0 or n11 > cap1:
            s0 = math.sqrt(min(1.0, cap0 / max(n00, 1e-300)))
            s1 = math.sqrt(min(1.0, cap1 / max(n11, 1e-300)))
            n00, n01, n10, n11 = n00 * s0 * s0, n01 * s0 * s1, n10 * s1 * s0, n11 * s1 * s1
        t0, t1 = t0 + g0 * err, t1 + g1 * err
        p00, p01, p10, p11 = n00, n01, n10, n11
    beta = min(max(t1, lo_b), hi_b)
    kf_hat = math.exp(t0 - beta * log_vr_ref)
    inv_beta = 1.0 / beta
    k_hat = kf_hat**inv_beta
    ki = fp[18] / (fp[20] * k_hat)
    kp = ki / fp[19]
    error = fr**inv_beta - force**inv_beta
    if not math.isfinite(error):
        error = 0.0
    u_free = kp * error + integral
    u = 1.0 if u_free >= 1.0 else (low if u_free <= low else u_free)
    if not ((u_free >= 1.0 and error > 0.0) or (u_free <= low and error < 0.0)):
        integral = min(max(integral + ki * error * dt, low), 1.0)
    fs[0], fs[1], fs[2], fs[3], fs[4], fs[5], fs[6] = integral, t0, t1, p00, p01, p10, p11
    return u


@_jit
def _switch_level(stages: np.ndarray, stage: int, direction: int, hysteresis: float) -> float:
    other = stage + direction
    mid = 0.5 * (stages[stage] + stages[other])
    return mid + direction * hysteresis * abs(stages[other] - stages[stage])


@_jit
def _fuzzy_step(
    fp: np.ndarray, fs: np.ndarray, stages: np.ndarray, rules: np.ndarray, set_idx: np.ndarray,
    set_val: np.ndarray, universe: np.ndarray, scratch: np.ndarray, force_N: float,
) -> tuple[float, bool]:  # fmt: skip
    """``_fast._FuzzyStepper.step`` with ``fuzzy._next_stage``."""
    if fs[5] > 0.5:
        return 0.0, True
    fr, e_span, de_span, a, dt = fp[0], fp[1], fp[2], fp[3], fp[4]
    stop_strength, stop_hold, max_rate, hysteresis, beta = fp[5], fp[6], fp[7], fp[8], fp[9]
    stage = int(fs[1])
    error = force_N - fr
    raw_trend = (error - fs[3]) / dt
    trend = a * fs[2] + (1.0 - a) * raw_trend
    fs[6] += dt
    if fs[6] < fp[10]:
        trend = 0.0  # the controller's own switch, settling
    n = stages.shape[0]
    change, strength = _fuzzy_infer(
        error / e_span, trend / de_span, stages[stage], stages[0], stages[n - 1], rules,
        set_idx, set_val, universe, scratch,
    )  # fmt: skip
    firing = strength >= stop_strength
    protection = fs[4] + dt if firing else 0.0
    fs[2], fs[3], fs[4] = trend, error, protection
    if firing and protection >= stop_hold:
        fs[5] = 1.0
        return 0.0, True
    internal = fs[0] + change * max_rate * dt
    internal = min(max(internal, stages[0]), stages[n - 1])
    force_now = force_N if force_N > 0.0 else 0.0
    while stage + 1 < n and internal > _switch_level(stages, stage, 1, hysteresis):
        predicted = force_now * (stages[stage + 1] / stages[stage]) ** beta
        if predicted >= fr * (1.0 - fp[11]):
            internal = _switch_level(stages, stage, 1, hysteresis)
            break
        stage += 1
    while stage > 0 and internal < _switch_level(stages, stage, -1, hysteresis):
        stage -= 1
    if stage != int(fs[1]):
        fs[6] = 0.0
    fs[0], fs[1] = internal, float(stage)
    return stages[stage], False


@_jit
def _lq_step(
    fp: np.ndarray, fs: np.ndarray, mats: np.ndarray, vecs: np.ndarray, gains: np.ndarray,
    ffs: np.ndarray, have: np.ndarray, index0: int, force: float, feed_m_s: float,
) -> tuple[float, int]:  # fmt: skip
    """``_fast._LqStepper.step``; returns (ratio, grid index still to design or
    ``NO_DESIGN_NEEDED``)."""
    fr, kf, vr, adapt, lam = fp[0], fp[1], fp[2], fp[3] > 0.5, fp[4]
    df0, step, half, low, startup, dt = fp[5], fp[6], fp[7], fp[8], fp[9], fp[10]
    min_startup, activation = fp[11], fp[12]
    has_filter = fp[13] > 0.5
    n = int(fp[14])
    delay = int(fp[15])
    o = n + delay  # state offsets
    i_theta = o + 6
    x_hat, delayed = fs[:n], fs[n:o]
    feed = feed_m_s / 1e-3
    # Kalman measurement update.
    y_hat = 0.0
    for i in range(n):
        y_hat += vecs[1, i] * fs[i]
    innovation = feed - y_hat
    for i in range(n):
        fs[i] += vecs[2, i] * innovation
    feed_f = feed
    if has_filter:
        b0, b1, b2, a1, a2 = vecs[4, 0], vecs[4, 1], vecs[4, 2], vecs[4, 4], vecs[4, 5]
        out = b0 * feed + fs[o + 4]
        fs[o + 4] = b1 * feed - a1 * out + fs[o + 5]
        fs[o + 5] = b2 * feed - a2 * out
        feed_f = out
    s00, s01, s10, s11 = mats[0, n], mats[0, n + 1], mats[1, n], mats[1, n + 1]
    g0, g1 = vecs[3, 0], vecs[3, 1]
    f0 = s00 * fs[o] + s01 * fs[o + 1] + g0 * force
    f1 = s10 * fs[o] + s11 * fs[o + 1] + g1 * force
    v0 = s00 * fs[o + 2] + s01 * fs[o + 3] + g0 * feed_f
    v1 = s10 * fs[o + 2] + s11 * fs[o + 3] + g1 * feed_f
    fs[o], fs[o + 1], fs[o + 2], fs[o + 3] = f0, f1, v0, v1
    y = f0 / fr
    x = (v0 - f1 / kf) / vr
    theta, p, r2 = fs[i_theta], fs[i_theta + 1], fs[i_theta + 2]
    if adapt and x > 0.03 and y > 0.03:
        residual = y - theta * x
        gain_rls = p * x / (lam + x * p * x)
        theta = theta + gain_rls * residual
        p = min((p - gain_rls * x * p) / lam, 1.0e3)
        r2 = lam * r2 + (1.0 - lam) * residual * residual
        fs[i_theta], fs[i_theta + 1], fs[i_theta + 2] = theta, p, r2
    df_hat = theta * fr / vr
    integral = fs[i_theta + 3]
    fs[i_theta + 4] += dt
    time_s = fs[i_theta + 4]
    active = fs[i_theta + 5] > 0.5
    index = int(fs[i_theta + 6])
    row = index - index0
    key = df0 * math.exp(step * index) if index != 0 else df0
    cell_lo = key / half * (1.0 + 1e-9)
    cell_hi = key * half * (1.0 - 1e-9)
    if adapt and not (cell_lo < df_hat < cell_hi):
        if df_hat > 0.0 and math.isfinite(df_hat):
            new = int(np.round(math.log(df_hat / df0) / step))
            grid = df0 * math.exp(step * new) if new != 0 else df0
            if grid != key:
                new_row = new - index0
                if new_row < 0 or new_row >= have.shape[0] or have[new_row] == 0:
                    return 0.0, new
                if active:
                    before = lq_command(gains[row], ffs[row], x_hat, delayed, force, integral, fr)
                    integral = lq_matching_integral(
                        gains[new_row], ffs[new_row], x_hat, delayed, force, fr, before, integral
                    )
                index, row = new, new_row
                fs[i_theta + 6] = float(index)
    if not active and time_s >= min_startup:
        rel_std = math.sqrt(max(r2 * p, 0.0)) / max(abs(theta), 1e-9)
        if not adapt or rel_std < activation:
            active = True
            current = startup * vr if delay == 0 else fs[n + delay - 1]
            integral = lq_matching_integral(
                gains[row], ffs[row], x_hat, delayed, force, fr, current, integral
            )
    gain = gains[row]
    if active:
        u = lq_command(gain, ffs[row], x_hat, delayed, force, integral, fr) / vr
        ratio = 1.0 if u >= 1.0 else (low if u <= low else u)
        error = fr - force
        pushing = (ratio >= 1.0 and error > 0.0) or (ratio <= low and error < 0.0)
        if not pushing:
            integral += dt * error
    else:
        ratio = startup
    command = ratio * vr
    acting = fs[n] if delay > 0 else command
    nxt = np.empty(n)
    for i in range(n):
        acc = vecs[0, i] * acting
        for j in range(n):
            acc += mats[i, j] * fs[j]
        nxt[i] = acc
    for i in range(n):
        fs[i] = nxt[i]
    if delay > 0:
        for i in range(delay - 1):
            fs[n + i] = fs[n + i + 1]
        fs[n + delay - 1] = command
    fs[i_theta + 3] = integral
    fs[i_theta + 5] = 1.0 if active else 0.0
    return ratio, NO_DESIGN_NEEDED


# --- the loop ----------------------------------------------------------------------------------


@_jit_inline
def _record(
    out: np.ndarray, k: int, t: float, s: float, feed: float, command: float, ratio: float,
    depth: float, force: float, raw: float, deflection: float, h: float,
) -> None:  # fmt: skip
    """Sample ``k`` of the trace, in the columns of ``_loop.TRACE_NAMES``."""
    out[0, k] = t
    out[1, k] = s
    out[2, k] = feed
    out[3, k] = command
    out[4, k] = ratio
    out[5, k] = depth
    out[6, k] = force
    out[7, k] = raw
    out[8, k] = deflection
    out[9, k] = h


@_jit_inline
def _process_force(
    force_N: float, depth_m: float, feed_m_s: float, gain_K: float, alpha_d: float,
    beta_f: float, lag: float,
) -> float:  # fmt: skip
    """The process force one period on, eq. (3): the exact first-order lag (``lag`` =
    exp(-dt / tau_m)) towards eq. (5), F = K d^alpha f^beta (d, f in mm, mm/s), at this depth
    and feed."""
    if depth_m > 0.0 and feed_m_s > 0.0:
        target = gain_K * (depth_m * 1e3) ** alpha_d * (feed_m_s * 1e3) ** beta_f
    else:
        target = 0.0
    return lag * force_N + (1.0 - lag) * target


@_jit_inline
def _feed_step(
    feed_a: np.ndarray, feed_b: np.ndarray, x0: float, x1: float, x2: float, pos: float,
    command: float,
) -> tuple[float, float, float, float]:  # fmt: skip
    """Eq. (1) discretized one period on under ``command``: the feed model's state, the path
    position last."""
    n0 = feed_a[0, 0] * x0 + feed_a[0, 1] * x1 + feed_a[0, 2] * x2 + feed_a[0, 3] * pos
    n1 = feed_a[1, 0] * x0 + feed_a[1, 1] * x1 + feed_a[1, 2] * x2 + feed_a[1, 3] * pos
    n2 = feed_a[2, 0] * x0 + feed_a[2, 1] * x1 + feed_a[2, 2] * x2 + feed_a[2, 3] * pos
    n3 = feed_a[3, 0] * x0 + feed_a[3, 1] * x1 + feed_a[3, 2] * x2 + feed_a[3, 3] * pos
    return (
        n0 + feed_b[0] * command,
        n1 + feed_b[1] * command,
        n2 + feed_b[2] * command,
        n3 + feed_b[3] * command,
    )


@_jit
def cut_kernel(
    allowance: np.ndarray, v_prog: np.ndarray, c_true: np.ndarray, c_hat: np.ndarray,
    offset: np.ndarray, ds: float, length: float, n_max: int, capacity: int, dt: float,
    gain_K: float, alpha_d: float, beta_f: float, lag: float, sigma: float, rng,
    feed_a: np.ndarray, feed_b: np.ndarray, feed_c: np.ndarray, filt: np.ndarray,
    filt_z: np.ndarray, constant_feed: float, online: bool, alpha_c: float,
    supervision_N: float, stop_tail_s: float,
    kind: int, fp: np.ndarray, fs: np.ndarray, first_ratio: float, stages: np.ndarray,
    rules: np.ndarray, set_idx: np.ndarray, set_val: np.ndarray, universe: np.ndarray,
    lq_mats: np.ndarray,
    lq_vecs: np.ndarray, lq_gains: np.ndarray, lq_ff: np.ndarray, lq_have: np.ndarray,
    lq_index0: int,
):  # fmt: skip
    """``_loop.cut_loop`` compiled. Returns (trace (COLUMNS, n), event, value, cycle time
    (-1: none), stop time (-1: none), stop reason)."""
    out = np.empty((COLUMNS, capacity))
    scratch = np.zeros(16)
    inv_ds = 1.0 / ds
    last = allowance.shape[0] - 1
    force = 0.0
    w_f = 0.0
    s_held = 0.0
    z1, z2 = filt_z[0], filt_z[1]
    b0, b1, b2, a1, a2 = filt[0], filt[1], filt[2], filt[4], filt[5]
    x0 = x1 = x2 = pos = 0.0
    pending = first_ratio
    stop_time = -1.0
    stop_reason = STOP_NONE
    cycle_time = -1.0
    k = 0
    while True:
        if k >= n_max:
            return out[:, :k], EVENT_SAMPLE_LIMIT, k, cycle_time, stop_time, stop_reason
        if k >= out.shape[1]:
            grown = np.empty((COLUMNS, min(2 * out.shape[1], n_max)))
            grown[:, :k] = out[:, :k]
            out = grown
        t = k * dt
        s = pos
        if s < s_held:
            s = s_held
        else:
            s_held = s
        j = int(s * inv_ds)
        if j > last:
            j = last
        feed = feed_c[0] * x0 + feed_c[1] * x1 + feed_c[2] * x2 + feed_c[3] * pos
        if feed < 0.0:
            feed = 0.0
        deflection = c_true[j] * force
        h = offset[j] + deflection - c_hat[j] * w_f
        depth = allowance[j] - h
        if depth < 0.0:
            depth = 0.0
        raw = force + sigma * rng.standard_normal()
        measured = b0 * raw + z1
        z1 = b1 * raw - a1 * measured + z2
        z2 = b2 * raw - a2 * measured
        if kind != KIND_NONE:
            stop = False
            if kind == KIND_FIXED_PI:
                next_ratio = _fixed_pi_step(fp, fs, measured)
            elif kind == KIND_ADAPTIVE_PI:
                next_ratio = _adaptive_pi_step(fp, fs, measured, feed)
            elif kind == KIND_FUZZY:
                next_ratio, stop = _fuzzy_step(
                    fp, fs, stages, rules, set_idx, set_val, universe, scratch, measured
                )
            else:
                next_ratio, need = _lq_step(
                    fp, fs, lq_mats, lq_vecs, lq_gains, lq_ff, lq_have, lq_index0, measured,
                    feed,
                )  # fmt: skip
                if need != NO_DESIGN_NEEDED:
                    return out[:, :k], EVENT_NEED_DESIGN, need, cycle_time, stop_time, stop_reason
            if stop and stop_time < 0.0:
                stop_time, stop_reason = t, STOP_PROTECTION
            ratio = pending
            pending = 0.0 if stop_time >= 0.0 else next_ratio
            command = ratio * v_prog[j]
        else:
            command = constant_feed if constant_feed < v_prog[j] else v_prog[j]
            ratio = command / v_prog[j]
        if stop_time >= 0.0:
            ratio = 0.0
            command = 0.0
        _record(out, k, t, s, feed, command, ratio, depth, force, raw, deflection, h)
        k += 1
        if s >= length:
            cycle_time = t
            break
        if stop_time >= 0.0 and t - stop_time >= stop_tail_s:
            break
        force = _process_force(force, depth, feed, gain_K, alpha_d, beta_f, lag)
        if not math.isfinite(force):
            return out[:, :k], EVENT_DONE, -1, cycle_time, stop_time, -1
        if force > supervision_N:
            force = supervision_N
            if stop_time < 0.0:
                stop_time, stop_reason = t, STOP_SUPERVISION
        if online:
            w_f += alpha_c * (raw - w_f)
        x0, x1, x2, pos = _feed_step(feed_a, feed_b, x0, x1, x2, pos, command)
    return out[:, :k], EVENT_DONE, 0, cycle_time, stop_time, stop_reason


# --- the stations around the loop ------------------------------------------------------------


@_jit
def speed_profile(v2: np.ndarray, step: float) -> np.ndarray:
    """``run.planned_speed_profile`` on squared speeds: v^2 <= v0^2 + step forward, then the
    same backward; returns the speeds."""
    out = v2.copy()
    n = out.shape[0]
    for i in range(1, n):
        if out[i] > out[i - 1] + step:
            out[i] = out[i - 1] + step
    for i in range(n - 2, -1, -1):
        if out[i] > out[i + 1] + step:
            out[i] = out[i + 1] + step
    return np.sqrt(out)


@_jit
def lowest_reach(station: np.ndarray, tool_normal: np.ndarray, n_st: int) -> np.ndarray:
    """(n_st,) the lowest tool position over the samples at each station (inf where none):
    ``np.minimum.at`` of ``summary.finished_wall``."""
    reach = np.full(n_st, np.inf)
    for k in range(station.shape[0]):
        i = station[k]
        if tool_normal[k] < reach[i]:
            reach[i] = tool_normal[k]
    return reach


@_jit
def ball_envelope(reach: np.ndarray, rise: np.ndarray) -> np.ndarray:
    """The lowest reach of the ball at each station, ``summary.ball_envelope_reference``
    compiled: each station's own reach, and its neighbours' ``shift`` stations away lifted
    by ``rise[shift - 1]``, the ball's profile there (the same minima in the same order)."""
    envelope = reach.copy()
    n = reach.shape[0]
    for shift in range(1, rise.shape[0] + 1):
        lift = rise[shift - 1]
        for i in range(shift, n):
            v = reach[i - shift] + lift
            if v < envelope[i]:
                envelope[i] = v
        for i in range(n - shift):
            v = reach[i + shift] + lift
            if v < envelope[i]:
                envelope[i] = v
    return envelope


@_jit
def split_by_deviation(s: np.ndarray, shift: np.ndarray, keep: np.ndarray, tol: float) -> None:
    """``offline.split_by_deviation_reference`` compiled: the deviation-height split of the
    planned shift between the kept stations, ``keep`` updated in place."""
    n = s.shape[0]
    stack_i = np.empty(n, dtype=np.int64)
    stack_j = np.empty(n, dtype=np.int64)
    top = 0
    last = -1
    for k in range(n):
        if keep[k]:
            if last >= 0:
                stack_i[top] = last
                stack_j[top] = k
                top += 1
            last = k
    while top > 0:
        top -= 1
        i, j = stack_i[top], stack_j[top]
        if j - i < 2:
            continue
        best, at = -1.0, -1
        for m in range(i + 1, j):
            t = (s[m] - s[i]) / (s[j] - s[i])
            dev = abs(shift[m] - (shift[i] + t * (shift[j] - shift[i])))
            if dev > best:
                best, at = dev, m
        if best > tol:
            keep[at] = True
            stack_i[top], stack_j[top] = i, at
            stack_i[top + 1], stack_j[top + 1] = at, j
            top += 2
