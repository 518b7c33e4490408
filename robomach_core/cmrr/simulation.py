"""The study runner: one controller on one scenario, sample by sample at the control rate.

Each sample: read the depth at the tool's position; the process force lags towards its steady
value (eq. (3) or Lund eq. (9)); the sensor adds noise and filters; the controller turns the
measurement into a speed ratio; after the control delay the robot (eq. (1)) gets
speed_ratio x Vr as its commanded feed and moves the tool along the path.

``run_study`` takes a progress callback and a cancel flag so the workbench or the REST API can
run it in a worker thread and show or stop it.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass, field
from typing import Any, Protocol

import numpy as np

from .controllers import ControllerSettings, make_controller, settings_for
from .controllers.base import Measurement
from .errors import CancelledError
from .metrics import summarize
from .process import LundForceModel, PowerLawForceModel, process_step
from .scenarios import Scenario, build_scenario

# Simulated time after a protection stop before the study ends [s].
STOP_TAIL_S = 0.3
# Samples between two checks of the cancel flag.
CANCEL_CHECK_EVERY = 64


class CancelFlag(Protocol):
    """Anything with ``is_set()``, e.g. ``threading.Event``."""

    def is_set(self) -> bool: ...


ProgressCallback = Callable[[float], None]


@dataclass(frozen=True, eq=False)
class StudyTrace:
    """Sampled signals of one study, SI units, each shape (n,).

    ``speed_ratio`` is the ratio applied to the robot at that sample (after the control
    delay), so ``commanded_feed_m_s = speed_ratio * Vr``; ``measured_force_N`` is the filtered
    feedback the controller saw; ``engaged`` is False in a start-up phase or after a stop.
    ``estimates`` and ``truths`` map estimate names to arrays (truths from the true process).
    """

    time_s: np.ndarray
    position_m: np.ndarray
    depth_m: np.ndarray
    commanded_feed_m_s: np.ndarray
    actual_feed_m_s: np.ndarray
    speed_ratio: np.ndarray
    force_N: np.ndarray
    measured_force_N: np.ndarray
    spindle_current_A: np.ndarray
    reference_N: np.ndarray
    engaged: np.ndarray
    estimates: dict[str, np.ndarray] = field(default_factory=dict)
    truths: dict[str, np.ndarray] = field(default_factory=dict)

    def __len__(self) -> int:
        return int(self.time_s.size)


@dataclass(frozen=True, eq=False)
class StudyResult:
    """A finished study: the scenario, the controller, the trace and the summary dict."""

    scenario: Scenario
    controller_name: str
    settings: ControllerSettings
    trace: StudyTrace
    summary: dict[str, Any]


def run_study(
    scenario: Scenario | str,
    controller: ControllerSettings | str,
    *,
    seed: int = 0,
    progress: ProgressCallback | None = None,
    cancel: CancelFlag | Callable[[], bool] | None = None,
) -> StudyResult:
    """Simulate one cut of ``scenario`` under ``controller`` and summarize it.

    Args:
        scenario: a ``Scenario`` or a scenario name (its defaults).
        controller: controller settings, or a controller name (its defaults).
        seed: seed of the sensor and spindle-current noise.
        progress: called with the fraction of the path done, in [0, 1], about every 1 %.
        cancel: a flag (``is_set()``) or a callable; when true the study raises
            ``CancelledError``.

    Returns:
        The ``StudyResult``; ``summary`` holds the figures listed in ``metrics.summarize``.
    """
    if isinstance(scenario, str):
        scenario = build_scenario(scenario)
    settings = settings_for(controller) if isinstance(controller, str) else controller
    design = scenario.control_design()
    ctrl = make_controller(settings, design)
    cancelled = cancel_predicate(cancel)

    dt = scenario.dt_s
    vr = scenario.command_speed_m_s
    length = scenario.path_length_m
    n_max = int(math.ceil(scenario.time_limit_s / dt)) + 1
    robot = scenario.feed_dynamics.discretize(dt)
    sensor_filter = design.measurement_filter
    assert sensor_filter is not None
    noise = np.random.default_rng(seed).standard_normal((n_max, 2))
    sensor, spindle, process = scenario.sensor, scenario.spindle, scenario.process
    use_current = scenario.feedback == "spindle_current"
    depth_at = scenario.depth_profile

    rec, engaged_rec, est_rec = _trace_buffers(n_max, ctrl.estimate_names)

    x = robot.initial_state()
    held = 0.0
    force = 0.0
    filt_state = sensor_filter.initial_state()
    ctrl_state = ctrl.initial_state()
    pending = [ctrl.initial_speed_ratio] * scenario.control_delay_steps
    stop_time: float | None = None
    cycle_time: float | None = None
    last_progress = -1.0
    n = 0
    for k in range(n_max):
        if cancelled is not None and k % CANCEL_CHECK_EVERY == 0 and cancelled():
            raise CancelledError(f"CMRR study {scenario.name}/{ctrl.name} cancelled")
        t = k * dt
        # The path interpolator never runs the tool backwards: eq. (1) is non-minimum phase and
        # dips before it rises; the dip below rest is held at rest (as in the machining run).
        position = max(float(x[-1]), held)
        held = position
        depth = float(depth_at(position))  # a scalar at a scalar position
        feed = max(robot.feed(x), 0.0)
        current = spindle.current_A(force, noise[k, 1])
        raw = (
            spindle.force_from_current(current)
            if use_current
            else force + sensor.bias_N + sensor.noise_std_N * noise[k, 0]
        )
        filt_state, measured = sensor_filter.step(filt_state, raw)
        ctrl_state, out = ctrl.step(ctrl_state, Measurement(measured, feed))
        if out.stop and stop_time is None:
            stop_time = t
        pending.append(0.0 if stop_time is not None else out.speed_ratio)
        ratio = pending.pop(0)
        if stop_time is not None:
            ratio = 0.0

        rec["time_s"][k] = t
        rec["position_m"][k] = position
        rec["depth_m"][k] = depth
        rec["actual_feed_m_s"][k] = feed
        rec["speed_ratio"][k] = ratio
        rec["force_N"][k] = force
        rec["measured_force_N"][k] = measured
        rec["spindle_current_A"][k] = current
        engaged_rec[k] = out.engaged and stop_time is None
        for name, value in out.estimates.items():
            est_rec[name][k] = value
        n = k + 1

        if position >= length:
            cycle_time = t
            break
        if stop_time is not None and t - stop_time >= STOP_TAIL_S:
            break
        force = process_step(process, force, depth, feed, dt)
        x = robot.step(x, ratio * vr)
        if progress is not None:
            frac = min(position / length, 1.0)
            if frac - last_progress >= 0.01:
                last_progress = frac
                progress(frac)
    if progress is not None:
        progress(1.0)

    trace = _finished_trace(scenario, ctrl.estimate_names, rec, engaged_rec, est_rec, n)
    summary = summarize(
        scenario,
        ctrl.name,
        trace,
        cycle_time_s=cycle_time,
        stop_time_s=stop_time,
        controller_params=ctrl.describe(),
    )
    return StudyResult(scenario, ctrl.name, settings, trace, summary)


def _trace_buffers(
    n_max: int, estimate_names: tuple[str, ...]
) -> tuple[dict[str, np.ndarray], np.ndarray, dict[str, np.ndarray]]:
    """Room for ``n_max`` samples of the trace: the scalar signals by ``StudyTrace`` field name,
    the engaged flags and the controller's estimates (NaN where it gives none)."""
    rec = {
        k: np.empty(n_max)
        for k in (
            "time_s position_m depth_m actual_feed_m_s speed_ratio force_N "
            "measured_force_N spindle_current_A"
        ).split()
    }
    engaged_rec = np.zeros(n_max, dtype=bool)
    est_rec = {name: np.full(n_max, np.nan) for name in estimate_names}
    return rec, engaged_rec, est_rec


def _finished_trace(
    scenario: Scenario,
    estimate_names: tuple[str, ...],
    rec: dict[str, np.ndarray],
    engaged_rec: np.ndarray,
    est_rec: dict[str, np.ndarray],
    n: int,
) -> StudyTrace:
    """The first ``n`` samples of the buffers as a ``StudyTrace``: the commanded feed is the
    applied speed ratio times Vr, and the true values of the estimates come from the scenario's
    process (``_truths``)."""
    return StudyTrace(
        commanded_feed_m_s=rec["speed_ratio"][:n] * scenario.command_speed_m_s,
        reference_N=np.full(n, scenario.reference_force_N),
        engaged=engaged_rec[:n],
        estimates={name: arr[:n] for name, arr in est_rec.items()},
        truths=_truths(scenario, rec["depth_m"][:n], estimate_names),
        **{k: v[:n] for k, v in rec.items()},
    )


def cancel_predicate(cancel: CancelFlag | Callable[[], bool] | None) -> Callable[[], bool] | None:
    """``cancel`` as a function that says whether to stop (None: never asked)."""
    if cancel is None:
        return None
    is_set = getattr(cancel, "is_set", None)
    if callable(is_set):
        return is_set
    if callable(cancel):
        return cancel
    raise TypeError("cancel must be a callable or have is_set()")


def _truths(scenario: Scenario, depth_m: np.ndarray, names: tuple[str, ...]) -> dict:
    """True values of the estimated quantities along the trace, for plots and checks."""
    process = scenario.process
    out: dict[str, np.ndarray] = {}
    for name in names:
        if name == "force_gain_N" and isinstance(process, PowerLawForceModel):
            out[name] = np.array([process.force_gain_N(float(d)) for d in depth_m])
        elif name == "feed_exponent" and isinstance(process, PowerLawForceModel):
            out[name] = np.full(depth_m.shape, process.feed_exponent)
        elif name == "removal_N_s_m" and isinstance(process, LundForceModel):
            out[name] = np.array([process.removal_parameter(float(d)) for d in depth_m])
    return out


def compare_controllers(
    scenario: Scenario | str,
    controllers: list[ControllerSettings | str],
    *,
    seed: int = 0,
    progress: ProgressCallback | None = None,
    cancel: CancelFlag | Callable[[], bool] | None = None,
) -> list[StudyResult]:
    """``run_study`` for each controller on the same scenario and noise; progress spans all."""
    if isinstance(scenario, str):
        scenario = build_scenario(scenario)
    results = []
    total = len(controllers)
    for i, controller in enumerate(controllers):

        def sub_progress(frac: float, i: int = i) -> None:
            if progress is not None:
                progress((i + frac) / total)

        results.append(
            run_study(scenario, controller, seed=seed, progress=sub_progress, cancel=cancel)
        )
    return results
