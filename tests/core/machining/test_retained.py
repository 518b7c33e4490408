"""What the workbench keeps of a machining result (issue 32, point 2): bucketed traces that
keep every sample's weight and the force and feed envelopes, finished walls that keep their
worst stations, over generated traces of any length."""

from __future__ import annotations

from dataclasses import fields

import numpy as np
from hypothesis import given, settings
from hypothesis import strategies as st

from robomach_core.machining.retained import (
    BucketTrace,
    bucket_trace,
    rebucket,
    retained_wall,
)
from robomach_core.machining.summary import FinishedWall, MachiningTrace

SIGNALS = [f.name for f in fields(MachiningTrace)]


def _trace(n: int, seed: int) -> MachiningTrace:
    rng = np.random.default_rng(seed)
    values = {k: np.cumsum(rng.normal(size=n)) for k in SIGNALS}
    values["time_s"] = np.arange(n) * 0.004
    values["force_N"] = np.abs(values["force_N"]) + 5 * (rng.random(n) < 0.001)  # spikes
    return MachiningTrace(**values)


@given(st.integers(1, 30_000), st.integers(1, 3000), st.integers(1, 500), st.integers(0, 2**32 - 1))
@settings(max_examples=60, deadline=None)
def test_buckets_keep_the_envelope_and_the_weight_of_every_sample(
    n: int, buckets: int, coarser: int, seed: int
) -> None:
    tr = _trace(n, seed)
    kept = bucket_trace(tr, buckets)
    assert len(kept) == min(n, buckets)
    for shown in (kept, rebucket(kept, coarser)):
        assert isinstance(shown, BucketTrace)
        assert shown.samples_total == n and np.all(shown.samples >= 1)
        assert shown.force_max_N.max() == tr.force_N.max()
        assert shown.force_min_N.min() == tr.force_N.min()
        assert shown.feed_max_m_s.max() == tr.feed_m_s.max()
        assert shown.feed_min_m_s.min() == tr.feed_m_s.min()
        assert np.all(shown.force_min_N <= shown.force_N + 1e-9)
        assert np.all(shown.force_N <= shown.force_max_N + 1e-9)
        for k in SIGNALS:  # the sample-weighted mean of the buckets is the signal's mean
            mean = np.sum(getattr(shown, k) * shown.samples) / n
            assert np.isclose(mean, np.mean(getattr(tr, k)), rtol=1e-9, atol=1e-9), k
        assert np.all(np.diff(shown.time_s) > 0)  # buckets stay in order along the run
    assert len(rebucket(kept, coarser)) == min(len(kept), coarser)


@given(st.integers(2, 20_000), st.integers(1, 2000), st.integers(0, 2**32 - 1))
@settings(max_examples=60, deadline=None)
def test_a_thinned_wall_keeps_its_ends_and_its_worst_stations(
    n: int, buckets: int, seed: int
) -> None:
    rng = np.random.default_rng(seed)
    s = np.cumsum(rng.random(n)) * 1e-4
    wall = FinishedWall(s, rng.random(n) * 1e-3, rng.normal(size=n) * 1e-4)
    kept = retained_wall(wall, buckets)
    assert len(kept.s_m) <= max(n if n <= 2 * buckets else 2 * buckets + 2, 2)
    assert kept.s_m[0] == s[0] and kept.s_m[-1] == s[-1]
    assert np.all(np.diff(kept.s_m) > 0)
    assert kept.error_m.min() == wall.error_m.min()
    assert kept.error_m.max() == wall.error_m.max()
    assert np.isin(kept.s_m, s).all()
