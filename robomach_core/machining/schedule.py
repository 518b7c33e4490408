"""A staged controller's stages planned offline: the feed schedule an offline-compensated
program carries (chapter sec. 4.3.4 and 5.4; issue 29).

PROBLEM   Offline compensation plans each target's correction from the force the cut will
          meet there. Under a staged controller (fuzzy, two-stage) that force steps with the
          stage, and a stage switch lands where the sensor's noise puts it, a sample to a
          millimetre from one cut to the next: no plan made before the cut can know where the
          cell's own cut will switch, and the correction planned for one stage's force is
          wrong by up to half a stage step wherever the cut ran the other (two-stage on the
          pump: the wall error cut 61 %, the chapter asks >= 75 %).
STRATEGY  Take the switching out of the cell's cut. The staged controller still decides the
          feed, offline: it cuts the nominal wall (the tool held on it, the full allowance:
          the cut a working compensation meets) ``SCHEDULE_DRAWS`` times, each on a
          sensor-noise draw of its own, and each station keeps the lowest stage any of those
          cuts ran there (where they disagree, the lower feed: its force is lower, so the
          schedule never takes the force above what the controller's own cuts met). The
          program carries that schedule as its programmed speeds (a target where the stage
          changes; each move at its stage x the learned speed, rounded down to 0.01 mm/s), and
          the cell runs those speeds as written: no feed control online, the force limit
          supervised by the cell as for every cut (its overload trip at twice the limit). The
          schedule's cut is deterministic (no measured force drives it), so the offline
          compensation is planned for exactly the force that cut meets
          (``offline.offline_compensated_run`` with these speeds), as for the constant feed.
LIMIT     The schedule is planned for the stock it was cut on. With no feed control, a
          casting whose burrs lie elsewhere meets them at the planned speeds: the pump's
          schedules over 16 drawn stocks peaked at up to 285 N, p95 272 N (switching online:
          145 N), so a sweep over castings (``--variations``) does not choose them. A guard
          dropping to the lowest stage while the force is over the limit left 216-233 N (the
          feed and the force lag the trigger) and was not kept; one that reacts where the
          force leaves the planned force by a margin (per station, carried per target) is the
          next step.
SOLUTION  ``stage_ratio_met`` (the stage each draw ran at each station), ``scheduled_program``
          (the program with the schedule as its speeds); ``run.run_machining`` composes them
          when ``MachiningSettings.stages`` is "planned" (the default "online" keeps the
          switching in the cell: its feed control meets any casting).
          The row's summary says ``feed: "program"`` and ``schedule_draws``; the exporters
          write the speeds and no FC SpeedChange or feed loop for it (``project``).
"""

from __future__ import annotations

from dataclasses import replace

import numpy as np

from ..postprocess import Targets
from ..transforms import arc_length_m
from .program import SPEED_QUANTUM_M_S, quantized_down

# The controllers whose output is a stage (a few fixed speed ratios), so their feed can be
# planned offline as a schedule.
STAGED_CONTROLLERS: tuple[str, ...] = ("fuzzy", "two-stage")
# Cuts of the nominal wall, each on a noise draw of its own, whose lowest stage per station is
# the schedule: two, the fewest where draws can disagree. Issue 29, UR10 pump demo and 8 fresh
# stocks: 1, 2, 3, 4 and 6 draws cut the wall error alike (fuzzy 95.9-97.6 %, two-stage
# 95.1-97.3 %) with the same peaks; each draw more lengthens the cycle (fuzzy on the pump
# 144.1, 144.4, 144.4, 144.6, 144.8 s; two-stage 194.9, 195.6, 195.8, 195.8, 196.1 s).
SCHEDULE_DRAWS = 2


def stage_ratio_met(path_m: np.ndarray, ratio: np.ndarray, s_st: np.ndarray) -> np.ndarray:
    """(n_st,) the least speed ratio a cut ran at each station (the loop runs station
    j = floor(s / ds) at ratio x its programmed speed); a station no sample fell in takes the
    lesser of its neighbours'.

    Args:
        path_m, ratio: (n,) the cut's trace: the path position and the speed ratio applied.
        s_st: (n_st,) the stations, every ds from 0.
    """
    from ._kernel import lowest_reach

    s = np.asarray(s_st, dtype=float)
    ds = float(s[1] - s[0])
    station = np.clip(np.floor(np.asarray(path_m) / ds).astype(np.int64), 0, len(s) - 1)
    least = lowest_reach(station, np.ascontiguousarray(ratio, dtype=float), len(s))
    seen = np.isfinite(least)
    if not seen.any():
        return np.ones(len(s))
    idx = np.arange(len(s))
    before = np.maximum.accumulate(np.where(seen, idx, -1))
    after = np.minimum.accumulate(np.where(seen, idx, len(s))[::-1])[::-1]
    lo = least[np.clip(before, 0, len(s) - 1)]
    hi = least[np.clip(after, 0, len(s) - 1)]
    lo = np.where(before >= 0, lo, hi)
    hi = np.where(after < len(s), hi, lo)
    return np.where(seen, least, np.minimum(lo, hi))


def draw_stages(draw, s_st: np.ndarray) -> np.ndarray:
    """(n_st,) the stage a cut of the nominal wall (a ``run.Rehearsal``) ran at each station
    (``stage_ratio_met``); a cut the controller's protection rule stopped counts up to where it
    stopped (inf beyond: it says nothing of the rest of the path)."""
    ratio = np.asarray(draw.trace.speed_ratio, dtype=float)
    path = np.asarray(draw.trace.path_m, dtype=float)
    if draw.summary["completed"]:
        return stage_ratio_met(path, ratio, s_st)
    moving = ratio > 0.0  # after the stop the ratio is 0
    if not moving.any():
        return np.full(len(s_st), np.inf)
    out = stage_ratio_met(path[moving], ratio[moving], s_st)
    out[np.asarray(s_st) > path[moving][-1]] = np.inf
    return out


def scheduled_program(targets: Targets, s_st: np.ndarray, ratio: np.ndarray) -> Targets:
    """The program with the stage schedule ``ratio`` (n_st,) at the stations ``s_st`` as its
    speeds: a target added where the stage changes (halfway between the last station of the
    old stage and the first of the new, so no rounding of an arc length moves a station to
    the other move), each move at the least ratio over the stations it runs (the loop runs
    station j at the speed of the move whose end is the first at or after it) times its
    learned speed, rounded down to the speed quantum."""
    from .offline import targets_at

    s_t = arc_length_m(targets.position_m)
    s = np.asarray(s_st, dtype=float)
    r = np.asarray(ratio, dtype=float)
    ds = float(s[1] - s[0])
    change = s[np.flatnonzero(np.diff(r) != 0.0)] + 0.5 * ds
    grid = np.union1d(s_t, change[(change > s_t[0]) & (change < s_t[-1])])
    grid = grid[np.concatenate([[True], np.diff(grid) > 1e-9])]
    out = targets_at(targets, grid)
    g = arc_length_m(out.position_m)
    lo = np.clip(np.searchsorted(s, g[:-1], side="right"), 0, len(s) - 1)
    lo[0] = 0  # the first station, at the first target, runs the first move
    hi = np.maximum(np.searchsorted(s, g[1:], side="right"), lo + 1)
    hi[-1] = len(s)  # the stations past the last target run the last move
    move_ratio = np.array([r[a:b].min() for a, b in zip(lo, hi, strict=True)])
    v = np.asarray(out.speed_m_s, dtype=float)
    speeds = np.empty(len(out))
    speeds[1:] = quantized_down(move_ratio * v[1:])
    speeds[0] = speeds[1]
    return replace(out, speed_m_s=np.maximum(speeds, SPEED_QUANTUM_M_S))


def switches(ratio: np.ndarray) -> int:
    """How many times the schedule changes stage along the path."""
    return int(np.count_nonzero(np.diff(np.asarray(ratio, dtype=float)) != 0.0))
