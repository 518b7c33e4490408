"""The machining run's 4 ms loop over the stations of a planned cut: the Python reference and
its compiled copy (``_kernel``), behind one call (``run_loop``).

The loop (``run`` module docstring has the model): the path interpolator never runs the TCP
backwards; the depth met is the allowance minus where the tool's edge is (the program's offset,
the deflection by the TRUE compliance, minus the online correction); the F/T sensor adds noise
and the controller's filter smooths it; the controller sets the speed ratio one period later;
the process force lags towards eq. (5); the cell's force supervision trips at its threshold;
the robot's feed follows the command through eq. (1).
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass
from typing import Any

import numpy as np

from ..errors import InvalidInputError
from . import _kernel
from .errors import CancelledError, MachiningSettingsError, SampleLimitError

# Columns of a loop's trace, in order.
TRACE_NAMES: tuple[str, ...] = (
    "time_s",
    "path_m",
    "feed_m_s",
    "commanded_feed_m_s",
    "speed_ratio",
    "depth_m",
    "force_N",
    "measured_force_N",
    "deflection_m",
    "tool_normal_m",
)
# Samples between two checks of the cancel flag (reference loop).
CANCEL_CHECK_EVERY = 64
# Sensor noise is drawn this many samples at a time (reference loop; the same stream).
NOISE_BLOCK = 65_536
STOP_REASONS = {
    _kernel.STOP_NONE: None,
    _kernel.STOP_PROTECTION: "protection rule",
    _kernel.STOP_SUPERVISION: "force supervision",
}


@dataclass(frozen=True, eq=False)
class LoopInputs:
    """What the loop needs, at the stations every ``ds`` along the path (each (n_st,)).

    Attributes:
        allowance: the stock before the cut [m]; ``v_prog`` the planned programmed speed
            [m/s]; ``c_true`` / ``c_hat`` the true / identified normal compliance n^T C u
            [m/N] (``c_hat`` zero without online compensation); ``offset`` the program's
            offset from the stock's path along the normal [m].
        constant_feed: the constant feed's cap [m/s] (inf for a CMRR controller).
        gain_K: the process gain K of the stock's material; ``alpha_d``, ``beta_f`` eq. (5);
            ``lag`` exp(-dt / tau_m) of eq. (3).
        sigma: the sensor noise [N]; ``filt`` the sensor filter's second-order section
            (b0, b1, b2, 1, a1, a2) and ``filt_z`` its initial state.
        feed_a, feed_b, feed_c: eq. (1) discretized with the path position as last state.
        alpha_c: the online compensation filter's coefficient; ``online`` whether it acts.
        supervision_N: the force supervision's trip; ``stop_tail_s`` the time run after a stop.
        n_max: the most samples the run may take; ``capacity`` the first guess of its length.
    """

    allowance: np.ndarray
    v_prog: np.ndarray
    c_true: np.ndarray
    c_hat: np.ndarray
    offset: np.ndarray
    ds: float
    length: float
    dt: float
    constant_feed: float
    gain_K: float
    alpha_d: float
    beta_f: float
    lag: float
    sigma: float
    filt: np.ndarray
    filt_z: np.ndarray
    feed_a: np.ndarray
    feed_b: np.ndarray
    feed_c: np.ndarray
    online: bool
    alpha_c: float
    supervision_N: float
    stop_tail_s: float
    n_max: int
    capacity: int
    seed: int


@dataclass(frozen=True, eq=False)
class LoopResult:
    """The trace (``TRACE_NAMES`` -> (n,) array), the cycle time (None: not finished), the
    stop time and reason (None: no stop)."""

    columns: dict[str, np.ndarray]
    cycle_time_s: float | None
    stop_time_s: float | None
    stop_reason: str | None


def run_loop(
    inputs: LoopInputs,
    controller: Any,
    packed: Any,
    *,
    cancel: Callable[[], bool] | None = None,
    compiled: bool = True,
) -> LoopResult:
    """The cut's loop: compiled when ``packed`` (``_kernel.pack_controller`` of ``controller``)
    is a kernel form and ``compiled``, else the reference. Raises ``SampleLimitError`` when the
    feed stalls, ``MachiningSettingsError`` when the cut diverges."""
    if compiled and packed is not NotImplemented:
        return _compiled(inputs, packed, cancel)
    return cut_loop(inputs, controller, cancel=cancel)


def _stalled(n_max: int, dt: float) -> SampleLimitError:
    return SampleLimitError(
        f"the run did not finish within {n_max} samples ({n_max * dt:.0f} s); the feed stalled"
    )


def _compiled(inputs: LoopInputs, packed: Any, cancel: Callable[[], bool] | None) -> LoopResult:
    i = inputs
    while True:
        if cancel is not None and cancel():
            raise CancelledError("machining run cancelled")
        fs = packed.fs.copy()
        out, event, value, cycle, stop_t, reason = _kernel.cut_kernel(
            i.allowance, i.v_prog, i.c_true, i.c_hat, i.offset, i.ds, i.length, i.n_max,
            i.capacity, i.dt, i.gain_K, i.alpha_d, i.beta_f, i.lag, i.sigma,
            np.random.default_rng(i.seed), i.feed_a, i.feed_b, i.feed_c, i.filt, i.filt_z,
            i.constant_feed, i.online, i.alpha_c, i.supervision_N, i.stop_tail_s,
            packed.kind, packed.fp, fs, packed.first_ratio, packed.stages, packed.rules,
            packed.set_idx, packed.set_val, packed.universe, packed.lq_mats, packed.lq_vecs,
            packed.lq_gains, packed.lq_ff, packed.lq_have, packed.lq_index0,
        )  # fmt: skip
        if event == _kernel.EVENT_NEED_DESIGN:
            for index in range(value - 2, value + 3):
                packed.add_design(index)
            continue  # the same cut again from the start, with the design at hand
        if event == _kernel.EVENT_SAMPLE_LIMIT:
            raise _stalled(i.n_max, i.dt)
        if reason == -1:
            raise _diverged(float(out[1, -1]) if out.shape[1] else 0.0, float("inf"))
        columns = {name: out[k].copy() for k, name in enumerate(TRACE_NAMES)}
        return LoopResult(
            columns,
            None if cycle < 0.0 else float(cycle),
            None if stop_t < 0.0 else float(stop_t),
            STOP_REASONS[int(reason)],
        )


class _Diverged(MachiningSettingsError):
    """The cut diverged (the caller words the message with its settings)."""

    def __init__(self, s_m: float, force_N: float) -> None:
        super().__init__("diverged")
        self.s_m, self.force_N = s_m, force_N


def _diverged(s_m: float, force_N: float) -> _Diverged:
    return _Diverged(s_m, force_N)


def cut_loop(
    inputs: LoopInputs, controller: Any, *, cancel: Callable[[], bool] | None = None
) -> LoopResult:
    """The reference loop (scalar Python; the controller through ``_fast.fast_stepper``, itself
    tested against each controller's public ``step``). A cut whose arithmetic fails (an
    overflow, a division by zero, a NaN position) diverged where its last sample was, as the
    compiled loop reports it."""
    columns: list[list[float]] = [[] for _ in TRACE_NAMES]
    try:
        cycle_time, stop_time, stop_reason = _reference_samples(inputs, controller, cancel, columns)
    except (OverflowError, ZeroDivisionError, ValueError) as exc:
        if isinstance(exc, InvalidInputError):
            raise
        path, force = columns[TRACE_NAMES.index("path_m")], columns[TRACE_NAMES.index("force_N")]
        raise _diverged(path[-1] if path else 0.0, force[-1] if force else 0.0) from None
    return LoopResult(
        {name: np.asarray(c, dtype=float) for name, c in zip(TRACE_NAMES, columns, strict=True)},
        cycle_time,
        stop_time,
        stop_reason,
    )


def _reference_samples(
    inputs: LoopInputs,
    controller: Any,
    cancel: Callable[[], bool] | None,
    columns: list[list[float]],
) -> tuple[float | None, float | None, str | None]:
    """The reference loop's samples, appended to ``columns`` (``TRACE_NAMES``); returns (cycle
    time, stop time, stop reason)."""
    from ..cmrr.controllers._fast import fast_stepper

    i = inputs
    dt = i.dt
    inv_ds = 1.0 / i.ds
    last = len(i.allowance) - 1
    a_l, v_l = i.allowance.tolist(), i.v_prog.tolist()
    ct_l, ch_l, off_l = i.c_true.tolist(), i.c_hat.tolist(), i.offset.tolist()
    K, alpha_d, beta_f, lag, sigma = i.gain_K, i.alpha_d, i.beta_f, i.lag, i.sigma
    b0, b1, b2, _, a1, a2 = i.filt.tolist()
    z1, z2 = (float(v) for v in i.filt_z)
    fa, fb, fc = i.feed_a.tolist(), i.feed_b.tolist(), i.feed_c.tolist()
    constant_feed = i.constant_feed
    rng = np.random.default_rng(i.seed)
    noise: list[float] = []
    rt, rs, rf, rcf, rr, rd, rF, rm, rdef, rh = columns
    control = fast_stepper(controller) if controller is not None else None
    first_ratio = controller.initial_speed_ratio if controller is not None else 1.0
    pending = [first_ratio]  # one period of control delay
    force = w_f = s_held = 0.0
    x0 = x1 = x2 = pos = 0.0
    stop_time: float | None = None
    stop_reason: str | None = None
    cycle_time: float | None = None
    k = 0
    while True:
        if k >= i.n_max:
            raise _stalled(i.n_max, dt)
        if cancel is not None and k % CANCEL_CHECK_EVERY == 0 and cancel():
            raise CancelledError("machining run cancelled")
        t = k * dt
        s = pos
        if s < s_held:
            s = s_held
        else:
            s_held = s
        j = int(s * inv_ds)
        if j > last:
            j = last
        feed = fc[0] * x0 + fc[1] * x1 + fc[2] * x2 + fc[3] * pos
        if feed < 0.0:
            feed = 0.0
        deflection = ct_l[j] * force
        h = off_l[j] + deflection - ch_l[j] * w_f
        depth = a_l[j] - h
        if depth < 0.0:
            depth = 0.0
        if k % NOISE_BLOCK == 0:
            noise = rng.standard_normal(NOISE_BLOCK).tolist()
        raw = force + sigma * noise[k % NOISE_BLOCK]
        measured = b0 * raw + z1
        z1 = b1 * raw - a1 * measured + z2
        z2 = b2 * raw - a2 * measured
        if control is not None:
            next_ratio, stop = control(measured, feed)
            if stop and stop_time is None:
                stop_time, stop_reason = t, "protection rule"
            pending.append(0.0 if stop_time is not None else next_ratio)
            ratio = pending.pop(0)
            command = ratio * v_l[j]
        else:
            command = constant_feed if constant_feed < v_l[j] else v_l[j]
            ratio = command / v_l[j]
        if stop_time is not None:
            ratio = command = 0.0
        rt.append(t)
        rs.append(s)
        rf.append(feed)
        rcf.append(command)
        rr.append(ratio)
        rd.append(depth)
        rF.append(force)
        rm.append(raw)
        rdef.append(deflection)
        rh.append(h)
        k += 1
        if s >= i.length:
            cycle_time = t
            break
        if stop_time is not None and t - stop_time >= i.stop_tail_s:
            break
        # Process force, eq. (3): exact first-order lag towards eq. (5) at this depth, feed.
        if depth > 0.0 and feed > 0.0:
            target = K * (depth * 1e3) ** alpha_d * (feed * 1e3) ** beta_f
        else:
            target = 0.0
        force = lag * force + (1.0 - lag) * target
        if not math.isfinite(force):
            raise _diverged(s, force)
        if force > i.supervision_N:
            force = i.supervision_N
            if stop_time is None:
                stop_time, stop_reason = t, "force supervision"
        if i.online:
            w_f += i.alpha_c * (raw - w_f)
        n0 = fa[0][0] * x0 + fa[0][1] * x1 + fa[0][2] * x2 + fa[0][3] * pos
        n1 = fa[1][0] * x0 + fa[1][1] * x1 + fa[1][2] * x2 + fa[1][3] * pos
        n2 = fa[2][0] * x0 + fa[2][1] * x1 + fa[2][2] * x2 + fa[2][3] * pos
        n3 = fa[3][0] * x0 + fa[3][1] * x1 + fa[3][2] * x2 + fa[3][3] * pos
        x0 = n0 + fb[0] * command
        x1 = n1 + fb[1] * command
        x2 = n2 + fb[2] * command
        pos = n3 + fb[3] * command
    return cycle_time, stop_time, stop_reason
