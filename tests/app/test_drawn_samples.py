"""The workbench draws at most MAX_DRAWN_SAMPLES of a recording, spread along all of it."""

from __future__ import annotations

import numpy as np

from app.gui.panels.postprocess import MAX_DRAWN_SAMPLES, drawn


def test_a_dense_recording_is_drawn_thinned_along_its_whole_length():
    pts = np.c_[np.arange(311_501.0), np.zeros(311_501), np.zeros(311_501)]
    out = drawn(pts)
    assert 0.9 * MAX_DRAWN_SAMPLES < len(out) <= MAX_DRAWN_SAMPLES
    assert out[0, 0] == 0.0 and out[-1, 0] > 311_501 - 311_501 / MAX_DRAWN_SAMPLES - 1
    small = pts[:1000]
    assert np.array_equal(drawn(small), small)
