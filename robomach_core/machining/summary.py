"""What a machining run leaves: its trace, the finished wall the ball cutter swept, and the
run's figures (cycle, peak force, wall error, removed volume, real-time factor), units in the
keys."""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any

import numpy as np

from ..cmrr.process import PowerLawForceModel
from .settings import MachiningSettings

MM = 1e-3


@dataclass(frozen=True, eq=False)
class MachiningTrace:
    """Per-sample signals, SI units, each shape (n,).

    ``force_N`` is the true process force; ``measured_force_N`` the raw sensor reading (noise
    added); ``deflection_m`` the arm's bending along the wall normal (positive: off the wall);
    ``tool_normal_m`` where the tool's edge is along the normal relative to the nominal wall
    (deflection, minus the compensation's shift); ``wall_error_m`` the finished wall at the
    tool's station (positive: material left, negative: overcut).
    """

    time_s: np.ndarray
    path_m: np.ndarray
    feed_m_s: np.ndarray
    commanded_feed_m_s: np.ndarray
    speed_ratio: np.ndarray
    depth_m: np.ndarray
    force_N: np.ndarray
    measured_force_N: np.ndarray
    reference_N: np.ndarray
    limit_N: np.ndarray
    deflection_m: np.ndarray
    tool_normal_m: np.ndarray
    wall_error_m: np.ndarray

    def __len__(self) -> int:
        return int(self.time_s.size)


@dataclass(frozen=True, eq=False)
class FinishedWall:
    """The wall after the cut at stations along the path, each shape (k,).

    Attributes:
        s_m: Arc length of the stations.
        allowance_m: The stock before the cut.
        finished_m: The wall after it, relative to the nominal wall along n.
    """

    s_m: np.ndarray
    allowance_m: np.ndarray
    finished_m: np.ndarray

    @property
    def error_m(self) -> np.ndarray:
        """Finished minus nominal [m]: positive material left, negative overcut."""
        return self.finished_m


def steady_force_N(
    process: PowerLawForceModel, depth_m: np.ndarray, feed_m_s: np.ndarray
) -> np.ndarray:
    """Eq. (5) on arrays: K (d/1 mm)^alpha (f/1 mm/s)^beta, zero without depth or feed."""
    d = np.maximum(np.asarray(depth_m, dtype=float), 0.0) / MM
    f = np.maximum(np.asarray(feed_m_s, dtype=float), 0.0) / MM
    with np.errstate(over="ignore", invalid="ignore"):
        out = process.gain_N * d**process.depth_exponent * f**process.feed_exponent
    return np.where((d > 0.0) & (f > 0.0), out, 0.0)


def finished_wall(
    s_st: np.ndarray,
    allowance_m: np.ndarray,
    path_m: np.ndarray,
    tool_normal_m: np.ndarray,
    tool_radius_m: float,
) -> FinishedWall:
    """The wall the ball cutter leaves: at each station the lowest reach of the ball over the
    tool positions within one radius along the path, h + r - sqrt(r^2 - ds^2), clipped by the
    stock (where the tool never reached the stock surface the stock remains)."""
    ds = float(s_st[1] - s_st[0])
    n_st = len(s_st)
    from ._kernel import ball_envelope, lowest_reach

    idx = np.clip(np.rint(path_m / ds).astype(np.int64), 0, n_st - 1)
    reach = lowest_reach(idx, np.ascontiguousarray(tool_normal_m, dtype=float), n_st)
    envelope = ball_envelope(reach, ball_rise_m(tool_radius_m, ds))
    return FinishedWall(s_st, allowance_m, np.minimum(allowance_m, envelope))


def ball_rise_m(radius_m: float, ds_m: float) -> np.ndarray:
    """(k,) how far the ball's surface rises ``shift`` = 1 ... k stations (every ``ds_m``)
    from its lowest point, r - sqrt(r^2 - (shift ds)^2), over the ball's radius."""
    r = radius_m
    return np.array(
        [
            r - math.sqrt(max(r * r - (shift * ds_m) ** 2, 0.0))
            for shift in range(1, int(r / ds_m) + 1)
        ],
        dtype=float,
    )


def ball_envelope_reference(reach: np.ndarray, rise: np.ndarray) -> np.ndarray:
    """``_kernel.ball_envelope`` in numpy (its reference, tests compare them)."""
    envelope = reach.copy()
    for shift in range(1, len(rise) + 1):
        envelope[shift:] = np.minimum(envelope[shift:], reach[:-shift] + rise[shift - 1])
        envelope[:-shift] = np.minimum(envelope[:-shift], reach[shift:] + rise[shift - 1])
    return envelope


def summarize(
    settings: MachiningSettings,
    trace: MachiningTrace,
    wall: FinishedWall,
    *,
    v_prog: np.ndarray,
    cycle_time_s: float | None,
    stop_time_s: float | None,
    constant_feed_m_s: float | None,
    wall_time_s: float,
    max_depth_m: float,
) -> dict[str, Any]:
    """The figures of a run, units in the keys.

    ``force_rms_error_N`` is taken where the reference is binding: where the steady force at
    the programmed speed and the depth met would exceed Fr (CMRR must act there); elsewhere
    the force is below Fr at full programmed speed by design.
    """
    fr = settings.reference_N
    process = settings.process
    full_speed = steady_force_N(process, trace.depth_m, v_prog)
    binding = full_speed >= fr
    sel = binding if np.any(binding) else trace.depth_m > 0.0
    err = trace.force_N[sel] - fr
    e = wall.error_m
    i_max = int(np.argmax(np.abs(e)))
    removed = float(np.trapezoid(wall.allowance_m - wall.finished_m, wall.s_m))
    volume_mm3 = removed * settings.axial_engagement_m / MM**3
    sim_time = float(trace.time_s[-1]) if len(trace) else 0.0
    return {
        "controller": settings.controller,
        "compensation": settings.compensation,
        "completed": cycle_time_s is not None,
        "cycle_time_s": cycle_time_s,
        "stop_time_s": stop_time_s,
        "samples": len(trace),
        "path_length_mm": float(wall.s_m[-1]) / MM,
        "force_peak_N": float(np.max(trace.force_N)),
        "force_limit_N": settings.force_limit_N,
        "force_reference_N": fr,
        "force_rms_error_N": float(np.sqrt(np.mean(err**2))) if err.size else 0.0,
        "force_over_limit_fraction": float(np.mean(trace.force_N > settings.force_limit_N)),
        "wall_error_max_mm": float(abs(e[i_max])) / MM,
        "wall_error_max_at_path_mm": float(wall.s_m[i_max]) / MM,
        "wall_error_rms_mm": float(np.sqrt(np.mean(e**2))) / MM,
        "material_left_max_mm": max(0.0, float(e.max())) / MM,
        "overcut_max_mm": max(0.0, float(-e.min())) / MM,
        "deflection_max_mm": float(np.max(trace.deflection_m)) / MM,
        "depth_max_mm": max_depth_m / MM,
        "feed_mean_mm_s": float(np.mean(trace.feed_m_s)) / MM,
        "constant_feed_mm_s": None if constant_feed_m_s is None else constant_feed_m_s / MM,
        "removed_volume_mm3": volume_mm3,
        "mrr_mean_mm3_s": volume_mm3 / cycle_time_s if cycle_time_s else None,
        "sim_time_s": sim_time,
        "wall_time_s": wall_time_s,
        "realtime_factor": sim_time / wall_time_s if wall_time_s > 0 else None,
    }
