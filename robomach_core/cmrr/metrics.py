"""Figures of merit of a study: stability, force error, peak force, cycle time vs a baseline.

"Stable" is judged from the speed ratio, the controller's output: a loop that has lost
stability limit-cycles between the saturation limits (eq. (13)) for as long as the cause lasts,
while a stable loop may ring after a depth step but the ringing dies out. A reversal counts
when the ratio turns after moving more than ``REVERSAL_FRACTION`` of its range; reversals less
than ``OSCILLATION_GAP_S`` apart form a burst; a burst of at least ``OSCILLATION_REVERSALS``
reversals lasting ``OSCILLATION_MIN_S`` or longer is a sustained oscillation: not stable.
The normal down-and-up at a burr is two reversals and never a sustained burst; an
oscillation slower than 2 Hz is not detected (none of the simulated loops has one).
"""

from __future__ import annotations

from typing import TYPE_CHECKING, Any

import numpy as np

if TYPE_CHECKING:
    from .scenarios import Scenario
    from .simulation import StudyTrace

# A reversal is a turn after a move larger than this fraction of (1 - delta).
REVERSAL_FRACTION = 0.25
# Reversals closer than this belong to one burst [s]: an oscillation faster than 2 Hz (the
# PI loop goes unstable at ~12-18 Hz; a burr passage is 0.1 s or longer between its two turns).
OSCILLATION_GAP_S = 0.25
# A burst this long [s] with this many reversals (three cycles) is a sustained oscillation.
OSCILLATION_MIN_S = 1.0
OSCILLATION_REVERSALS = 6


def reversal_times(signal: np.ndarray, time_s: np.ndarray, threshold: float) -> np.ndarray:
    """Times [s] at which ``signal`` turns after a monotone run larger than ``threshold``."""
    out: list[float] = []
    if signal.size == 0:
        return np.array(out)
    direction = 0  # +1 rising, -1 falling, 0 not yet moved by more than the threshold
    hi = lo = float(signal[0])
    hi_t = lo_t = float(time_s[0])
    for value, t in zip(signal.tolist(), time_s.tolist(), strict=True):
        if value > hi:
            hi, hi_t = value, t
        if value < lo:
            lo, lo_t = value, t
        if direction >= 0 and hi - value > threshold:
            if direction > 0:
                out.append(hi_t)
            direction, hi, hi_t, lo, lo_t = -1, value, t, value, t
        elif direction <= 0 and value - lo > threshold:
            if direction < 0:
                out.append(lo_t)
            direction, hi, hi_t, lo, lo_t = 1, value, t, value, t
    return np.array(out)


def oscillation_bursts(times: np.ndarray, gap_s: float = OSCILLATION_GAP_S) -> list[tuple]:
    """Group reversal times into bursts: (start [s], end [s], reversals) each."""
    bursts: list[tuple[float, float, int]] = []
    for t in times.tolist():
        if bursts and t - bursts[-1][1] <= gap_s:
            start, _, count = bursts[-1]
            bursts[-1] = (start, t, count + 1)
        else:
            bursts.append((t, t, 1))
    return bursts


def longest_oscillation_s(times: np.ndarray) -> float:
    """Duration [s] of the longest burst with enough reversals to count as oscillating."""
    spans = [b - a for a, b, n in oscillation_bursts(times) if n >= OSCILLATION_REVERSALS]
    return max(spans, default=0.0)


def is_stable(times: np.ndarray) -> bool:
    """No sustained oscillation among these reversal times."""
    return longest_oscillation_s(times) < OSCILLATION_MIN_S


def _rms(x: np.ndarray) -> float | None:
    return float(np.sqrt(np.mean(x**2))) if x.size else None


def summarize(
    scenario: Scenario,
    controller: str,
    trace: StudyTrace,
    *,
    cycle_time_s: float | None,
    stop_time_s: float | None,
    controller_params: dict[str, Any],
) -> dict[str, Any]:
    """The study's summary (JSON-ready; mm, N, s at this boundary).

    Keys: controller, scenario, completed, stable, peak_force_N, force_rms_error_N (over the
    samples where the control law is engaged and the reference is reachable, i.e. the steady
    force at full command speed would exceed it), cycle_time_s, baseline_cycle_time_s (the
    path at the greatest constant feed whose steady force stays under the limit everywhere),
    cycle_time_gain, protection_stop, segments, and the settings that produced them.
    """
    delta = scenario.min_speed_ratio
    threshold = REVERSAL_FRACTION * (1.0 - delta)
    t = trace.time_s
    rev = reversal_times(trace.speed_ratio, t, threshold)
    reachable = scenario.reference_reachable(trace.depth_m)
    mask = trace.engaged & reachable
    error = trace.force_N - scenario.reference_force_N
    baseline_feed = scenario.safe_constant_feed_m_s()
    baseline_time = scenario.path_length_m / baseline_feed
    limit = scenario.force_limit_N
    summary: dict[str, Any] = {
        "controller": controller,
        "scenario": scenario.name,
        "description": scenario.description,
        "feedback": scenario.feedback,
        "reference_force_N": scenario.reference_force_N,
        "command_speed_mm_s": 1e3 * scenario.command_speed_m_s,
        "min_speed_ratio": delta,
        "force_limit_N": limit,
        "path_length_mm": 1e3 * scenario.path_length_m,
        "completed": cycle_time_s is not None,
        "stable": is_stable(rev),
        "longest_oscillation_s": longest_oscillation_s(rev),
        "speed_ratio_reversals": int(rev.size),
        "peak_force_N": float(np.max(trace.force_N)) if len(trace) else 0.0,
        "force_rms_error_N": _rms(error[mask]),
        "engaged_reachable_time_s": float(np.count_nonzero(mask) * scenario.dt_s),
        "force_over_limit_time_s": (
            float(np.count_nonzero(trace.force_N > limit) * scenario.dt_s)
            if limit is not None
            else None
        ),
        "cycle_time_s": cycle_time_s,
        "baseline_feed_mm_s": 1e3 * baseline_feed,
        "baseline_cycle_time_s": baseline_time,
        "cycle_time_gain": baseline_time / cycle_time_s if cycle_time_s else None,
        "mean_feed_mm_s": (1e3 * scenario.path_length_m / cycle_time_s if cycle_time_s else None),
        "protection_stop": stop_time_s is not None,
        "stop_time_s": stop_time_s,
        "controller_params": controller_params,
    }
    if scenario.conservative_feed_m_s is not None:
        summary["conservative_feed_mm_s"] = 1e3 * scenario.conservative_feed_m_s
        summary["conservative_cycle_time_s"] = (
            scenario.path_length_m / scenario.conservative_feed_m_s
        )
    summary["segments"] = [
        _segment_summary(seg, trace, error, mask, threshold) for seg in scenario.segments
    ]
    return summary


def _segment_summary(
    seg: Any, trace: StudyTrace, error: np.ndarray, mask: np.ndarray, threshold: float
) -> dict[str, Any]:
    """Figures of one stretch of the path; settled statistics over 50-90 % of it."""
    inside = (trace.position_m >= seg.start_m) & (trace.position_m < seg.end_m)
    out: dict[str, Any] = {
        "label": seg.label,
        "start_mm": 1e3 * seg.start_m,
        "end_mm": 1e3 * seg.end_m,
        "reached": bool(np.any(inside)),
    }
    if not np.any(inside):
        return out
    idx = np.flatnonzero(inside)
    # Settled: from the middle of the segment to 90 % of it (before the next transition).
    late = idx[idx.size // 2 : max(int(0.9 * idx.size), idx.size // 2 + 1)]
    rev = reversal_times(trace.speed_ratio[idx], trace.time_s[idx], threshold)
    out.update(
        {
            "depth_mm": 1e3 * float(np.mean(trace.depth_m[idx])),
            "duration_s": float(trace.time_s[idx[-1]] - trace.time_s[idx[0]]),
            "stable": is_stable(rev),
            "longest_oscillation_s": longest_oscillation_s(rev),
            "speed_ratio_reversals": int(rev.size),
            "peak_force_N": float(np.max(trace.force_N[idx])),
            "settled_force_mean_N": float(np.mean(trace.force_N[late])),
            "settled_force_std_N": float(np.std(trace.force_N[late])),
            "settled_speed_ratio_min": float(np.min(trace.speed_ratio[late])),
            "settled_speed_ratio_max": float(np.max(trace.speed_ratio[late])),
            "mean_feed_mm_s": 1e3 * float(np.mean(trace.actual_feed_m_s[idx])),
            "force_rms_error_N": _rms(error[idx][mask[idx]]),
        }
    )
    return out
