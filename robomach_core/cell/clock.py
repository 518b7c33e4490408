"""The controller's clock: the 4 ms period every loop runs at, and continuous models sampled at it.

The chapter's controller and recorder run at 250 Hz (shared/DESIGN.md: "Clock"): lead-through,
path learning, the machining run, CMRR, compensation and ILC all step at ``CONTROL_PERIOD_S``.
A continuous model x' = A x + B u whose input is held over each period (a zero-order hold)
samples exactly to x[k+1] = Phi x[k] + Gamma u[k] with Phi = e^{A dt} and
Gamma = integral_0^dt e^{A s} ds B: the top blocks of the exponential of [[A, B], [0, 0]] dt
(Van Loan, IEEE Trans. Automat. Control 23(3), 1978), which ``zoh`` computes; ``zoh_tf`` samples
a transfer function so, through ``scipy.signal.cont2discrete(..., method="zoh")``.
"""

from __future__ import annotations

import numpy as np
import scipy.linalg

CONTROL_PERIOD_S = 0.004


def zoh(a: np.ndarray, b: np.ndarray, dt_s: float) -> tuple[np.ndarray, np.ndarray]:
    """(Phi, Gamma) of x' = A x + B u held over ``dt_s``. Shapes (n, n) and (n,) or (n, m)."""
    a = np.atleast_2d(np.asarray(a, dtype=float))
    b = np.asarray(b, dtype=float)
    n = a.shape[0]
    columns = b.reshape(n, -1)
    m = columns.shape[1]
    big = np.zeros((n + m, n + m))
    big[:n, :n] = a
    big[:n, n:] = columns
    exp = scipy.linalg.expm(big * dt_s)
    return exp[:n, :n], exp[:n, n:].reshape(b.shape)


def zoh_tf(
    num: np.ndarray | list[float], den: np.ndarray | list[float], dt_s: float
) -> tuple[np.ndarray, np.ndarray]:
    """Discrete (b, a) of the transfer function num/den with its input held over ``dt_s``
    (``scipy.signal.cont2discrete``, method "zoh")."""
    import scipy.signal  # here, not at start-up: 0.7 s of every process's start

    b_d, a_d, _ = scipy.signal.cont2discrete((num, den), dt_s, method="zoh")
    return np.ravel(b_d), np.ravel(a_d)
