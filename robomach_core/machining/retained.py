"""What a machining result keeps once it is computed: what its views show, not every period.

PROBLEM   A run's trace holds 13 signals at every 4 ms control period (26,000 samples, 2.7 MB,
          for the block's short cut; a comparison has 18 runs: 54 MB), and a workbench that
          kept each comparison's runs grew by that much per comparison (issue 32: 86 MB each
          on a longer path, 544 MB to 6.1 GB in 68 comparisons). The views (the force and feed
          plots with their min/max envelope, the finished-wall error along the path, the
          figure of a few runs, the table) show at most a couple of thousand points.
STRATEGY  Each run's trace becomes ``BucketTrace``: ``RETAINED_POINTS`` buckets of consecutive
          samples, each signal the bucket's mean, with the bucket's sample count and the
          min/max envelope of force and feed, so that a plot at any coarser resolution is
          rebuilt exactly (``rebucket``: weighted means, min of mins, max of maxes). The
          finished wall keeps, per bucket of stations, the stations of its least and greatest
          error (the overcut and the material left are never averaged away). The table, the
          summaries, the corrected programs and the stock are kept as they are.
SOLUTION  ``retained_result(result) -> MachiningResult``; ``rebucket(trace, max_points)``.
"""

from __future__ import annotations

from dataclasses import dataclass, fields, replace
from typing import Any

import numpy as np

from .summary import FinishedWall, MachiningTrace

# Buckets a retained trace keeps (the workbench plots 1500; the API serves at most this many).
RETAINED_POINTS = 2000
# Buckets of finished-wall stations (each keeps two stations: its least and greatest error).
RETAINED_WALL_BUCKETS = 1000


@dataclass(frozen=True, eq=False)
class BucketTrace(MachiningTrace):
    """A trace reduced to buckets of consecutive samples: each signal of ``MachiningTrace`` is
    the bucket's mean, shape (k,).

    Attributes:
        samples: (k,) samples each bucket stands for.
        force_min_N, force_max_N: (k,) the envelope of the process force in each bucket.
        feed_min_m_s, feed_max_m_s: (k,) the envelope of the feed.
    """

    samples: np.ndarray
    force_min_N: np.ndarray
    force_max_N: np.ndarray
    feed_min_m_s: np.ndarray
    feed_max_m_s: np.ndarray

    @property
    def samples_total(self) -> int:
        """Samples of the run the buckets stand for."""
        return int(self.samples.sum())


_SIGNALS = tuple(f.name for f in fields(MachiningTrace))


def _bounds(n: int, buckets: int) -> np.ndarray:
    """Start indices of ``min(buckets, n)`` near-equal runs of ``n`` items (n >= 1)."""
    return np.unique(np.linspace(0, n, min(buckets, n) + 1).astype(int))[:-1]


def bucket_trace(trace: MachiningTrace, buckets: int = RETAINED_POINTS) -> BucketTrace:
    """``trace`` as at most ``buckets`` buckets (module docstring); a ``BucketTrace`` is
    re-bucketed."""
    if isinstance(trace, BucketTrace):
        return rebucket(trace, buckets)
    n = len(trace)
    if n == 0:
        empty = np.zeros(0)
        return BucketTrace(**dict.fromkeys(_SIGNALS, empty), samples=np.zeros(0, dtype=np.int64),
                           force_min_N=empty, force_max_N=empty, feed_min_m_s=empty,
                           feed_max_m_s=empty)  # fmt: skip
    starts = _bounds(n, buckets)
    counts = np.diff(np.append(starts, n))
    means = {
        k: np.add.reduceat(np.asarray(getattr(trace, k), dtype=float), starts) / counts
        for k in _SIGNALS
    }
    return BucketTrace(
        **means,
        samples=counts.astype(np.int64),
        force_min_N=np.minimum.reduceat(trace.force_N, starts),
        force_max_N=np.maximum.reduceat(trace.force_N, starts),
        feed_min_m_s=np.minimum.reduceat(trace.feed_m_s, starts),
        feed_max_m_s=np.maximum.reduceat(trace.feed_m_s, starts),
    )


def rebucket(trace: BucketTrace, max_points: int) -> BucketTrace:
    """Coarser buckets of a ``BucketTrace``: sample-weighted means, the envelopes' extremes."""
    k = len(trace)
    if k <= max_points:
        return trace
    starts = _bounds(k, max_points)
    w = trace.samples.astype(float)
    weight = np.add.reduceat(w, starts)
    means = {k_: np.add.reduceat(getattr(trace, k_) * w, starts) / weight for k_ in _SIGNALS}
    return BucketTrace(
        **means,
        samples=np.add.reduceat(trace.samples, starts),
        force_min_N=np.minimum.reduceat(trace.force_min_N, starts),
        force_max_N=np.maximum.reduceat(trace.force_max_N, starts),
        feed_min_m_s=np.minimum.reduceat(trace.feed_min_m_s, starts),
        feed_max_m_s=np.maximum.reduceat(trace.feed_max_m_s, starts),
    )


def retained_wall(wall: FinishedWall, buckets: int = RETAINED_WALL_BUCKETS) -> FinishedWall:
    """The stations of ``wall`` with the least and greatest error of each bucket (the first
    and last stations too), in order."""
    n = len(wall.s_m)
    if n <= 2 * buckets:
        return wall
    starts = _bounds(n, buckets)
    ends = np.append(starts[1:], n)
    error = np.asarray(wall.error_m)
    keep = {0, n - 1}
    for a, b in zip(starts, ends, strict=True):
        segment = error[a:b]
        keep.add(a + int(np.argmin(segment)))
        keep.add(a + int(np.argmax(segment)))
    idx = np.array(sorted(keep))
    return FinishedWall(wall.s_m[idx], wall.allowance_m[idx], wall.finished_m[idx])


def retained_run(run: Any) -> Any:
    """A ``MachiningRun`` with its trace bucketed and its finished wall thinned."""
    return replace(run, trace=bucket_trace(run.trace), wall=retained_wall(run.wall))


def retained_result(result: Any) -> Any:
    """A ``project.MachiningResult`` keeping what the workbench shows of it (module docstring):
    the rows, table, choice, programs and stock as they are, each run's trace and wall
    reduced."""
    if not result.runs:
        return result
    return replace(result, runs=tuple(retained_run(r) for r in result.runs))
