"""Continuous models sampled at the control period with their input held (zero-order hold)."""

from __future__ import annotations

import numpy as np
import pytest
import scipy.signal

from robomach_core.cell import CONTROL_PERIOD_S, zoh, zoh_tf


@pytest.mark.parametrize("trial", range(5))
def test_a_held_step_through_the_sampled_model_is_the_continuous_step_response(trial):
    """Exact for a zero-order hold: a step is held, so the sampled model's step response equals
    the continuous one at every sample time, for the state-space and the transfer-function
    forms, over second-order lags from 1 to 200 Hz and damping 0.05 to 2."""
    rng = np.random.default_rng()
    seed = int(rng.integers(2**32))
    rng = np.random.default_rng(seed)
    w = 2 * np.pi * rng.uniform(1.0, 200.0)
    zeta = rng.uniform(0.05, 2.0)
    num, den = [rng.uniform(0.0, 1.0) * w, w**2], [1.0, 2 * zeta * w, w**2]
    t = np.arange(200) * CONTROL_PERIOD_S
    _, want = scipy.signal.step((num, den), T=t)
    b, a = zoh_tf(num, den, CONTROL_PERIOD_S)
    got = scipy.signal.lfilter(b, a, np.ones(len(t)))
    np.testing.assert_allclose(got, want, atol=1e-9 * max(1.0, np.abs(want).max()), err_msg=seed)
    A, B, C, D = scipy.signal.tf2ss(num, den)
    phi, gamma = zoh(A, B, CONTROL_PERIOD_S)
    x, out = np.zeros(len(A)), []
    for _ in t:
        out.append((C @ x + D[:, 0])[0])
        x = phi @ x + gamma[:, 0]
    np.testing.assert_allclose(out, want, atol=1e-9 * max(1.0, np.abs(want).max()), err_msg=seed)
