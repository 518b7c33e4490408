"""Robot feed dynamics: commanded to actual end-effector speed, eq. (1) of the MRR paper.

The identified model of the position-controlled IRB 6400 is

    f(s) / fc(s) = (63 s^2 - 45800 s + 4330000) / (s^3 + 575 s^2 + 98670 s + 4313000),

stable and non-minimum phase (zeros at +112 and +615 rad/s), poles at -66.5 and -254 +- 14.5j.
The simulator discretizes it exactly (zero-order hold on the command) with the path position as
an extra integrator state, so the position along the path is exact between samples too.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..cell import zoh
from .errors import CmrrSettingsError

# Eq. (1), MRR paper: numerator and denominator in descending powers of s.
ROBOT_FEED_NUM: tuple[float, ...] = (63.0, -45800.0, 4330000.0)
ROBOT_FEED_DEN: tuple[float, ...] = (1.0, 575.0, 98670.0, 4313000.0)


@dataclass(frozen=True)
class FeedDynamics:
    """Transfer function from commanded to actual feed speed (dimensionless, speed to speed)."""

    num: tuple[float, ...] = ROBOT_FEED_NUM
    den: tuple[float, ...] = ROBOT_FEED_DEN

    def __post_init__(self) -> None:
        if len(self.den) < 2 or self.den[0] == 0.0 or len(self.num) >= len(self.den):
            raise CmrrSettingsError("feed dynamics must be a strictly proper transfer function")
        if np.any(np.roots(self.den).real >= 0.0):
            raise CmrrSettingsError("feed dynamics must be stable (all poles in the left half)")

    @property
    def dc_gain(self) -> float:
        """Static gain f/fc (1.0039 for eq. (1))."""
        return float(self.num[-1] / self.den[-1])

    def poles(self) -> np.ndarray:
        """Poles [rad/s], shape (n,)."""
        return np.roots(self.den)

    def zeros(self) -> np.ndarray:
        """Zeros [rad/s]; positive real parts make eq. (1) non-minimum phase."""
        return np.roots(self.num)

    def state_space(self) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Continuous (A, B, C) in controllable canonical form; D is zero (strictly proper)."""
        import scipy.signal  # here, not at start-up: 0.7 s of every process's start

        a, b, c, _ = scipy.signal.tf2ss(self.num, self.den)
        return a, b[:, 0], c[0]

    def discretize(self, dt_s: float) -> DiscreteFeedModel:
        """Exact zero-order-hold model with the path position appended as the last state."""
        if not dt_s > 0.0:
            raise CmrrSettingsError(f"sample time must be positive, got {dt_s}")
        a, b, c = self.state_space()
        n = a.shape[0]
        # Augmented state [x; s] with s' = C x.
        a_aug = np.zeros((n + 1, n + 1))
        a_aug[:n, :n] = a
        a_aug[n, :n] = c
        phi, gamma = zoh(a_aug, np.append(b, 0.0), dt_s)
        return DiscreteFeedModel(a=phi, b=gamma, c=np.append(c, 0.0), dt_s=dt_s)


@dataclass(frozen=True, eq=False)
class DiscreteFeedModel:
    """x[k+1] = a x[k] + b fc[k]; actual feed c x[k] [m/s]; position x[-1] [m]."""

    a: np.ndarray
    b: np.ndarray
    c: np.ndarray
    dt_s: float

    def initial_state(self, feed_m_s: float = 0.0, position_m: float = 0.0) -> np.ndarray:
        """State at rest (or in steady motion at ``feed_m_s``) at ``position_m``. Shape (n+1,)."""
        n = self.a.shape[0] - 1
        x = np.zeros(n + 1)
        if feed_m_s != 0.0:
            # Steady state of the feed states for a constant command giving this feed.
            a = self.a[:n, :n]
            b = self.b[:n]
            xs = np.linalg.solve(np.eye(n) - a, b)
            x[:n] = xs * feed_m_s / float(self.c[:n] @ xs)
        x[n] = position_m
        return x

    def feed(self, x: np.ndarray) -> float:
        """Actual end-effector feed speed [m/s]."""
        return float(self.c @ x)

    def step(self, x: np.ndarray, commanded_feed_m_s: float) -> np.ndarray:
        """Next state after holding the commanded feed for one sample."""
        return self.a @ x + self.b * commanded_feed_m_s
