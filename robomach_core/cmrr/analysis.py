"""Linear analysis of the PI loop of the MRR paper: root locus points, damping, critical gain.

With the PI zero at -z and the linearized process F' = k f, the open loop is

    L(s) = g (s/z + 1) / s * G(s),    g = alpha Vr k  (eq. (14)),

with G(s) the robot feed dynamics of eq. (1). The closed-loop poles are the roots of
s den(s) + g (s/z + 1) num(s). At g = 28.84 the dominant pair has damping ~0.7 (the paper's
design point); the loop loses stability at g ~ 81 (the paper quotes 1.89 for "the open loop
gain" in a normalization it does not state). The simulated loop adds the force filter, the
sampling and a one-sample delay, which lower the critical gain further.
"""

from __future__ import annotations

import numpy as np
import scipy.optimize

from .controllers.pi import PI_ZERO_RAD_S
from .feed_dynamics import FeedDynamics


def closed_loop_poles(
    loop_gain: float,
    *,
    zero_rad_s: float = PI_ZERO_RAD_S,
    feed_dynamics: FeedDynamics | None = None,
) -> np.ndarray:
    """Closed-loop poles [rad/s] of the PI loop at open-loop gain g = alpha Vr k, shape (n+1,)."""
    fd = feed_dynamics or FeedDynamics()
    num = np.asarray(fd.num, dtype=float)
    den = np.asarray(fd.den, dtype=float)
    char = np.polyadd(
        np.polymul([1.0, 0.0], den), loop_gain * np.polymul([1.0 / zero_rad_s, 1.0], num)
    )
    return np.roots(char)


def dominant_pole_pair(poles: np.ndarray) -> np.ndarray:
    """The complex-conjugate pair nearest the imaginary axis, shape (2,); empty if none."""
    complex_poles = poles[np.abs(poles.imag) > 1e-9]
    if complex_poles.size == 0:
        return complex_poles
    upper = complex_poles[complex_poles.imag > 0]
    p = upper[np.argmax(upper.real)]
    return np.array([p, np.conj(p)])


def damping_ratio(pole: complex) -> float:
    """zeta = -Re(p) / |p|."""
    return float(-pole.real / abs(pole))


def critical_loop_gain(
    *,
    zero_rad_s: float = PI_ZERO_RAD_S,
    feed_dynamics: FeedDynamics | None = None,
    upper: float = 1.0e4,
) -> float:
    """Smallest open-loop gain g at which a closed-loop pole reaches the imaginary axis."""

    def margin(g: float) -> float:
        return float(
            np.max(closed_loop_poles(g, zero_rad_s=zero_rad_s, feed_dynamics=feed_dynamics).real)
        )

    lo = 1e-6
    if margin(upper) < 0.0:
        return float("inf")
    # Scan for the first sign change, then refine.
    grid = np.geomspace(lo, upper, 200)
    signs = [margin(g) for g in grid]
    for a, b, ma, mb in zip(grid, grid[1:], signs, signs[1:], strict=False):
        if ma < 0.0 <= mb:
            return float(scipy.optimize.brentq(margin, a, b))
    return float("inf")
