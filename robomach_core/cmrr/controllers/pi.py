"""PI feed control on the linearized force, fixed-gain and self-tuning (MRR paper sec. III-B, C).

PROBLEM: F = Kf f^beta (eq. (8)) is nonlinear in the feed and Kf = K d^alpha changes with the
depth of cut. STRATEGY: control F' = F^(1/beta) = k f with k = Kf^(1/beta) (eqs. (9)-(10)),
which is exactly linear in f; a PI Gc = Kp + Ki/s (eq. (11)) with its zero at -66.5 cancels the
slow robot pole of eq. (1), and Kp = Ki/66.5, Ki = alpha (eq. (12)). The open-loop gain is
alpha Vr k (eq. (14)); at 28.84 the dominant closed-loop pair has damping ~0.7.
SOLUTION: the fixed-gain PI picks alpha once for a design k; the self-tuning PI re-computes
Ki = 28.84 / (Vr k_hat), Kp = 0.432 / (Vr k_hat) (eq. (15)) every sample from an RLS estimate
(eq. (16)) of Kf and beta. Both saturate the speed ratio to [delta, 1] (eq. (13)) and stop
integrating while saturated in the direction of the error (anti-windup).

Units: F in N and f in mm/s inside the gains, as in the paper, so k and alpha match its numbers.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from functools import cached_property
from typing import Literal

from ..errors import CmrrSettingsError
from .base import FEED_REF_M_S, ControlDesign, ControlOutput, Measurement, saturate
from .rls import PowerLawEstimator, RlsState

# Eq. (14): the open-loop gain that gives the dominant pole pair a damping of ~0.7.
DESIGN_LOOP_GAIN = 28.84
# Eq. (12): the PI zero cancels the robot's slow pole at -66.5 rad/s.
PI_ZERO_RAD_S = 66.5


def pi_gains(
    loop_gain: float, command_speed_m_s: float, k: float, zero_rad_s: float
) -> tuple[float, float]:
    """Eqs. (14)-(15): (Kp, Ki) such that alpha Vr k = loop_gain with Kp = Ki / zero.

    ``k`` is the linearized process gain Kf^(1/beta) with f in mm/s; at the paper's numbers
    (loop gain 28.84, zero 66.5) this is Ki = 28.84 / (Vr k), Kp = 0.434 / (Vr k).
    """
    ki = loop_gain / ((command_speed_m_s / FEED_REF_M_S) * k)
    return ki / zero_rad_s, ki


# x^p is capped at e^POWER_CAP_EXP: with a small beta, F^(1/beta) would overflow a float.
POWER_CAP_EXP = 300.0


def safe_power(x: float, p: float) -> float:
    """x^p for x >= 0 and p > 0, capped at e^300 instead of overflowing."""
    if x <= 0.0:
        return 0.0
    e = p * math.log(x)
    return math.exp(e) if e < POWER_CAP_EXP else math.exp(POWER_CAP_EXP)


def _check_pi(loop_gain: float, zero_rad_s: float, initial_speed_ratio: float) -> None:
    if not loop_gain > 0.0:
        raise CmrrSettingsError(f"loop gain must be positive, got {loop_gain}")
    if not zero_rad_s > 0.0:
        raise CmrrSettingsError(f"PI zero must be positive (left-half-plane), got {zero_rad_s}")
    if not 0.0 < initial_speed_ratio <= 1.0:
        raise CmrrSettingsError("initial speed ratio must be in (0, 1]")


@dataclass(frozen=True)
class PiState:
    """Integral part of the PI, in speed-ratio units."""

    integral: float


def _pi_step(
    integral: float,
    error: float,
    kp: float,
    ki: float,
    dt_s: float,
    low: float,
) -> tuple[float, float]:
    """Positional PI with saturation (13) and conditional integration; returns (u, integral)."""
    u_free = kp * error + integral
    u = saturate(u_free, low)
    winding_up = (u_free >= 1.0 and error > 0.0) or (u_free <= low and error < 0.0)
    if not winding_up:
        integral = min(max(integral + ki * error * dt_s, low), 1.0)
    return u, integral


@dataclass(frozen=True)
class FixedPiSettings:
    """Fixed-gain PI on F' = F^(1/beta), eqs. (9)-(14).

    Attributes:
        loop_gain: alpha Vr k at the design process gain (28.84: damping ~0.7 there).
        pi_zero_rad_s: the PI zero (66.5 rad/s cancels the slow robot pole).
        design_force_gain_N: Kf [N at 1 mm/s] the gains are tuned for; None takes the
            scenario's nominal value (the lab fit at 1 mm depth for milling).
        feed_exponent: beta used in the linearization; None takes the scenario's nominal value.
        initial_speed_ratio: speed ratio at the start of the cut.
    """

    kind: Literal["fixed-pi"] = field(default="fixed-pi", init=False)
    loop_gain: float = DESIGN_LOOP_GAIN
    pi_zero_rad_s: float = PI_ZERO_RAD_S
    design_force_gain_N: float | None = None
    feed_exponent: float | None = None
    initial_speed_ratio: float = 1.0

    def __post_init__(self) -> None:
        _check_pi(self.loop_gain, self.pi_zero_rad_s, self.initial_speed_ratio)
        if self.design_force_gain_N is not None and not self.design_force_gain_N > 0.0:
            raise CmrrSettingsError("design force gain must be positive")
        if self.feed_exponent is not None and not 0.0 < self.feed_exponent <= 2.0:
            raise CmrrSettingsError("feed exponent must be in (0, 2]")


@dataclass(frozen=True)
class FixedPiController:
    """u = sat(Kp e' + Ki int e'), e' = Fr^(1/beta) - F^(1/beta), gains fixed at design (12)."""

    settings: FixedPiSettings
    design: ControlDesign
    name: str = "fixed-pi"
    estimate_names: tuple[str, ...] = ()

    @cached_property
    def feed_exponent(self) -> float:
        return self.settings.feed_exponent or self.design.nominal_feed_exponent

    @cached_property
    def design_force_gain_N(self) -> float:
        return self.settings.design_force_gain_N or self.design.nominal_force_gain_N

    @cached_property
    def gains(self) -> tuple[float, float]:
        """(Kp, Ki) of eq. (12) for the design k."""
        k = safe_power(self.design_force_gain_N, 1.0 / self.feed_exponent)
        return pi_gains(
            self.settings.loop_gain, self.design.command_speed_m_s, k, self.settings.pi_zero_rad_s
        )

    @cached_property
    def unit_gains(self) -> tuple[float, float]:
        """(Kp k, Ki k): the gains acting on the error in units of (F / Kf)^(1/beta), which
        stays a float where F^(1/beta) itself would overflow (a small beta)."""
        return pi_gains(
            self.settings.loop_gain, self.design.command_speed_m_s, 1.0, self.settings.pi_zero_rad_s
        )

    @property
    def initial_speed_ratio(self) -> float:
        return self.settings.initial_speed_ratio

    def initial_state(self) -> PiState:
        return PiState(self.settings.initial_speed_ratio)

    def step(self, state: PiState, measurement: Measurement) -> tuple[PiState, ControlOutput]:
        inv_beta = 1.0 / self.feed_exponent
        kp, ki = self.unit_gains
        kf = self.design_force_gain_N
        # e' / k = (Fr / Kf)^(1/beta) - (F / Kf)^(1/beta): eq. (10)'s error over k = Kf^(1/beta).
        error = safe_power(self.design.reference_force_N / kf, inv_beta) - safe_power(
            max(measurement.force_N, 0.0) / kf, inv_beta
        )
        u, integral = _pi_step(
            state.integral, error, kp, ki, self.design.dt_s, self.design.min_speed_ratio
        )
        return PiState(integral), ControlOutput(u)

    def describe(self) -> dict[str, float | str]:
        kp, ki = self.gains
        return {
            "kp": kp,
            "ki": ki,
            "loop_gain_at_design": self.settings.loop_gain,
            "design_force_gain_N": self.design_force_gain_N,
            "feed_exponent": self.feed_exponent,
            "pi_zero_rad_s": self.settings.pi_zero_rad_s,
        }


@dataclass(frozen=True)
class AdaptivePiSettings:
    """Self-tuning PI, eqs. (15)-(16): RLS estimate of (Kf, beta), gains re-set every sample.

    Attributes:
        loop_gain: the open-loop gain the tuning rule holds (28.84).
        pi_zero_rad_s: PI zero (66.5 rad/s).
        forgetting_factor: lambda of eq. (16), 0.95-0.99.
        initial_force_gain_N: Kf before any data; None takes the scenario's nominal value.
        initial_feed_exponent: beta before any data; None takes the scenario's nominal value.
        estimate_feed_exponent: False fixes beta and identifies Kf only.
        feed_exponent_bounds: the range beta_hat is clipped to.
        min_force_fraction: samples with F below this fraction of Fr are not used by the RLS.
        min_feed_ratio: samples with feed below this fraction of Vr are not used by the RLS.
        initial_speed_ratio: speed ratio at the start of the cut.
    """

    kind: Literal["adaptive-pi"] = field(default="adaptive-pi", init=False)
    loop_gain: float = DESIGN_LOOP_GAIN
    pi_zero_rad_s: float = PI_ZERO_RAD_S
    forgetting_factor: float = 0.95
    initial_force_gain_N: float | None = None
    initial_feed_exponent: float | None = None
    estimate_feed_exponent: bool = True
    feed_exponent_bounds: tuple[float, float] = (0.2, 1.2)
    min_force_fraction: float = 0.1
    min_feed_ratio: float = 0.05
    initial_speed_ratio: float = 1.0

    def __post_init__(self) -> None:
        _check_pi(self.loop_gain, self.pi_zero_rad_s, self.initial_speed_ratio)
        if not 0.5 < self.forgetting_factor <= 1.0:
            raise CmrrSettingsError("forgetting factor must be in (0.5, 1]")
        if not 0.0 <= self.min_force_fraction < 1.0 or not 0.0 < self.min_feed_ratio < 1.0:
            raise CmrrSettingsError("RLS gating fractions must be in [0, 1)")
        object.__setattr__(self, "feed_exponent_bounds", tuple(self.feed_exponent_bounds))


@dataclass(frozen=True, eq=False)
class AdaptivePiState:
    """PI integral, RLS estimate, and the feed filtered like the force (consistent regressors)."""

    integral: float
    rls: RlsState
    feed_filter: tuple[float, ...]


@dataclass(frozen=True)
class AdaptivePiController:
    """Self-tuning PI: Ki = 28.84/(Vr k_hat), Kp = 0.432/(Vr k_hat), eq. (15), k_hat from (16)."""

    settings: AdaptivePiSettings
    design: ControlDesign
    name: str = "adaptive-pi"
    estimate_names: tuple[str, ...] = ("force_gain_N", "feed_exponent")

    @cached_property
    def estimator(self) -> PowerLawEstimator:
        s = self.settings
        return PowerLawEstimator(
            command_speed_m_s=self.design.command_speed_m_s,
            forgetting=s.forgetting_factor,
            initial_force_gain_N=s.initial_force_gain_N or self.design.nominal_force_gain_N,
            initial_feed_exponent=s.initial_feed_exponent or self.design.nominal_feed_exponent,
            feed_exponent_bounds=s.feed_exponent_bounds,
            estimate_feed_exponent=s.estimate_feed_exponent,
        )

    @property
    def initial_speed_ratio(self) -> float:
        return self.settings.initial_speed_ratio

    def initial_state(self) -> AdaptivePiState:
        filt = self.design.measurement_filter
        return AdaptivePiState(
            self.settings.initial_speed_ratio,
            self.estimator.initial_state(),
            filt.initial_state() if filt is not None else (),
        )

    def step(
        self, state: AdaptivePiState, measurement: Measurement
    ) -> tuple[AdaptivePiState, ControlOutput]:
        d, s = self.design, self.settings
        filt = d.measurement_filter
        feed_filter, feed = state.feed_filter, measurement.feed_m_s
        if filt is not None:
            feed_filter, feed = filt.step(state.feed_filter, feed)
        force = max(measurement.force_N, 0.0)
        estimator = self.estimator
        rls = state.rls
        if (
            force > s.min_force_fraction * d.reference_force_N
            and feed > s.min_feed_ratio * d.command_speed_m_s
        ):
            rls = estimator.update(rls, force, feed)
        kf_hat, beta_hat = estimator.estimate(rls)
        inv_beta = 1.0 / beta_hat
        k_hat = kf_hat**inv_beta
        kp, ki = pi_gains(s.loop_gain, d.command_speed_m_s, k_hat, s.pi_zero_rad_s)
        error = d.reference_force_N**inv_beta - force**inv_beta
        if not math.isfinite(error):
            error = 0.0
        u, integral = _pi_step(state.integral, error, kp, ki, d.dt_s, d.min_speed_ratio)
        return (
            AdaptivePiState(integral, rls, feed_filter),
            ControlOutput(u, estimates={"force_gain_N": kf_hat, "feed_exponent": beta_hat}),
        )

    def describe(self) -> dict[str, float | str]:
        kf0, beta0 = self.estimator.estimate(self.estimator.initial_state())
        return {
            "loop_gain": self.settings.loop_gain,
            "pi_zero_rad_s": self.settings.pi_zero_rad_s,
            "forgetting_factor": self.settings.forgetting_factor,
            "initial_force_gain_N": kf0,
            "initial_feed_exponent": beta0,
        }
