"""Recursive least squares with exponential forgetting, eq. (16) of the MRR paper.

Used twice: by the self-tuning PI to identify ln F = ln Kf + beta ln f, and (scalar) by the
adaptive LQ to identify the Lund material-removal parameter Df.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from ..errors import CmrrSettingsError
from .base import FEED_REF_M_S


@dataclass(frozen=True, eq=False)
class RlsState:
    """Estimate ``theta`` shape (n,) and its covariance ``covariance`` shape (n, n)."""

    theta: np.ndarray
    covariance: np.ndarray


def rls_update(
    state: RlsState,
    x: np.ndarray,
    y: float,
    forgetting: float,
    max_variances: np.ndarray | None = None,
) -> RlsState:
    """One step of eq. (16).

        K(t) = P(t-1) x / (lambda + x' P(t-1) x)
        theta(t) = theta(t-1) + K(t) (y - theta(t-1)' x)
        P(t) = [I - K(t) x'] P(t-1) / lambda

    Without excitation the division by lambda makes P grow without bound (estimator wind-up).
    ``max_variances`` shape (n,) caps the diagonal of P: a row and column whose variance would
    pass its cap are scaled down together (P stays positive semi-definite). A small cap also
    sets how fast a parameter may move, e.g. a process exponent that should drift slowly.
    """
    if len(state.theta) == 2:
        return _rls_update_2(state, x, y, forgetting, max_variances)
    p = state.covariance
    px = p @ x
    gain = px / (forgetting + float(x @ px))
    theta = state.theta + gain * (y - float(state.theta @ x))
    p_new = (p - np.outer(gain, px)) / forgetting
    p_new = 0.5 * (p_new + p_new.T)
    if max_variances is not None:
        diag = np.diagonal(p_new)
        if np.any(diag > max_variances):
            scale = np.sqrt(np.minimum(1.0, max_variances / np.maximum(diag, 1e-300)))
            p_new = p_new * np.outer(scale, scale)
    return RlsState(theta, p_new)


def _rls_update_2(
    state: RlsState, x: np.ndarray, y: float, forgetting: float, max_variances: np.ndarray | None
) -> RlsState:
    """``rls_update`` for two parameters in scalar arithmetic: the same formulas, ~5x faster
    than 2x2 numpy in the 4 ms loop of a machining run (numpy's per-call overhead dominates)."""
    (p00, p01), (p10, p11) = state.covariance.tolist()
    x0, x1 = float(x[0]), float(x[1])
    t0, t1 = state.theta.tolist()
    px0 = p00 * x0 + p01 * x1
    px1 = p10 * x0 + p11 * x1
    denom = forgetting + (x0 * px0 + x1 * px1)
    g0, g1 = px0 / denom, px1 / denom
    err = y - (t0 * x0 + t1 * x1)
    n00 = (p00 - g0 * px0) / forgetting
    n01 = (p01 - g0 * px1) / forgetting
    n10 = (p10 - g1 * px0) / forgetting
    n11 = (p11 - g1 * px1) / forgetting
    n01 = n10 = 0.5 * (n01 + n10)
    if max_variances is not None:
        cap0, cap1 = float(max_variances[0]), float(max_variances[1])
        if n00 > cap0 or n11 > cap1:
            s0 = math.sqrt(min(1.0, cap0 / max(n00, 1e-300)))
            s1 = math.sqrt(min(1.0, cap1 / max(n11, 1e-300)))
            n00, n01, n10, n11 = n00 * s0 * s0, n01 * s0 * s1, n10 * s1 * s0, n11 * s1 * s1
    return RlsState(np.array([t0 + g0 * err, t1 + g1 * err]), np.array([[n00, n01], [n10, n11]]))


@dataclass(frozen=True)
class PowerLawEstimator:
    """RLS on ln F = ln F_r + beta ln(f / Vr), the paper's regression (16) re-centred at Vr.

    The paper regresses on x = (1, ln f). Centring the feed at the command speed Vr estimates
    the same two parameters (F_r = Kf Vr^beta) but leaves beta untouched while the feed sits at
    Vr (saturated at full speed): a depth change seen at constant feed then moves only the gain,
    which is the only thing the data can tell.

    Attributes:
        command_speed_m_s: Vr [m/s].
        forgetting: lambda, 0.95-0.99 in the paper.
        initial_force_gain_N: Kf at 1 mm/s before any data [N].
        initial_feed_exponent: beta before any data.
        initial_variances: P(0) diagonal for (ln F_r, beta).
        max_variances: caps of P's diagonal for (ln F_r, beta), against wind-up; the small cap
            on beta keeps it slow (the paper: K, alpha, beta change much more slowly than the
            depth), so a depth change is not mistaken for a change of beta.
        feed_exponent_bounds: beta is clipped to this range when used.
        estimate_feed_exponent: False fixes beta and identifies the gain only.
    """

    command_speed_m_s: float
    forgetting: float = 0.98
    initial_force_gain_N: float = 23.0
    initial_feed_exponent: float = 0.5
    initial_variances: tuple[float, float] = (1.0, 0.002)
    max_variances: tuple[float, float] = (1.0, 0.002)
    feed_exponent_bounds: tuple[float, float] = (0.2, 1.2)
    estimate_feed_exponent: bool = True

    def __post_init__(self) -> None:
        if not 0.5 < self.forgetting <= 1.0:
            raise CmrrSettingsError(f"forgetting factor must be in (0.5, 1], got {self.forgetting}")
        lo, hi = self.feed_exponent_bounds
        if not 0.0 < lo < hi:
            raise CmrrSettingsError("feed exponent bounds must satisfy 0 < low < high")
        if not self.initial_force_gain_N > 0.0 or min(self.initial_variances) <= 0.0:
            raise CmrrSettingsError("initial gain and variances must be positive")
        if min(self.max_variances) <= 0.0:
            raise CmrrSettingsError("variance caps must be positive")

    def initial_state(self) -> RlsState:
        """theta(0) = (ln F_r, beta) from the initial Kf and beta."""
        beta = self.initial_feed_exponent
        log_fr = math.log(self.initial_force_gain_N) + beta * math.log(
            self.command_speed_m_s / FEED_REF_M_S
        )
        if self.estimate_feed_exponent:
            return RlsState(np.array([log_fr, beta]), np.diag(self.initial_variances))
        return RlsState(np.array([log_fr]), np.array([[self.initial_variances[0]]]))

    def update(self, state: RlsState, force_N: float, feed_m_s: float) -> RlsState:
        """Fold in one sample (force > 0 and feed > 0 required; callers gate weak samples)."""
        z = math.log(feed_m_s / self.command_speed_m_s)
        y = math.log(force_N)
        if self.estimate_feed_exponent:
            caps = np.asarray(self.max_variances)
            return rls_update(state, np.array([1.0, z]), y, self.forgetting, caps)
        caps = np.asarray(self.max_variances[:1])
        y_gain = y - self.initial_feed_exponent * z
        return rls_update(state, np.array([1.0]), y_gain, self.forgetting, caps)

    def estimate(self, state: RlsState) -> tuple[float, float]:
        """(Kf [N at 1 mm/s], beta), beta clipped to its bounds."""
        if self.estimate_feed_exponent:
            lo, hi = self.feed_exponent_bounds
            beta = min(max(float(state.theta[1]), lo), hi)
        else:
            beta = self.initial_feed_exponent
        log_kf = float(state.theta[0]) - beta * math.log(self.command_speed_m_s / FEED_REF_M_S)
        return math.exp(log_kf), beta
