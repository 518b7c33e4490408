"""Cutting-process force models and the signals a controller sees (force sensor, spindle current).

Two force models share one interface (a steady force and a first-order lag towards it):

- ``PowerLawForceModel``: eqs. (3)-(6) of the MRR paper, F = Kc d^a f^b w^g / (tau_m s + 1),
  with the ABB lab fit F = 23 d^0.9 f^0.5 (d in mm, f in mm/s) as default.
- ``LundForceModel``: eq. (9) of the Lund paper, dF/dt = -Kf/Df F + Kf v, a linear first-order
  process with interaction stiffness Kf and material-removal parameter Df (steady F = Df v).

The signals: ``ForceSensorModel`` adds white noise and runs the low-pass filter the MRR paper
applied before feedback; ``SpindleCurrentModel`` is the alternative feedback (I = I0 + c F +
noise, converted back to force by the calibrated linear map, section IV of the MRR paper).
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Literal, Protocol

import numpy as np

from .errors import CmrrSettingsError

MM = 1e-3
# 63 % of one spindle revolution at 10 000 rpm (MRR paper, after eq. (3)).
DEFAULT_SPINDLE_RPM = 10_000.0
DEFAULT_TAU_M_S = 0.63 * 60.0 / DEFAULT_SPINDLE_RPM
# exp() of more than this overflows a float.
MAX_EXP = 700.0

FeedbackSignal = Literal["force", "spindle_current"]


class ForceModel(Protocol):
    """What the simulator needs from a process model."""

    def steady_force(self, depth_m: float, feed_m_s: float) -> float:
        """Force [N] the process settles to at this depth of cut and feed."""
        ...

    def lag_s(self, depth_m: float) -> float:
        """Time constant [s] of the first-order lag towards the steady force."""
        ...

    def feed_for_force(self, force_N: float, depth_m: float) -> float:
        """Steady feed [m/s] that gives ``force_N`` at this depth (inf if depth is zero)."""
        ...


@dataclass(frozen=True)
class PowerLawForceModel:
    """F = Kc (d/1 mm)^alpha (f/1 mm/s)^beta (w/1 mm)^gamma / (tau_m s + 1), eqs. (3), (5), (6).

    Defaults are the ABB lab fit of eq. (6), F = 23 d^0.9 f^0.5, valid for one tool and one
    aluminium block; ``gain_N`` is Kc w^gamma lumped (eq. (4)) unless ``width_m`` is given.
    """

    gain_N: float = 23.0
    depth_exponent: float = 0.9
    feed_exponent: float = 0.5
    width_exponent: float = 0.0
    width_m: float | None = None
    time_constant_s: float = DEFAULT_TAU_M_S

    def __post_init__(self) -> None:
        if not self.gain_N > 0.0:
            raise CmrrSettingsError(f"process gain must be positive, got {self.gain_N} N")
        if not 0.0 < self.feed_exponent <= 2.0:
            raise CmrrSettingsError(f"feed exponent must be in (0, 2], got {self.feed_exponent}")
        if not 0.0 <= self.depth_exponent <= 3.0:
            raise CmrrSettingsError(f"depth exponent must be in [0, 3], got {self.depth_exponent}")
        if self.time_constant_s < 0.0:
            raise CmrrSettingsError("process time constant must not be negative")

    def force_gain_N(self, depth_m: float) -> float:
        """Kf = K d^alpha of eq. (8): the force [N] at a feed of 1 mm/s."""
        width = 1.0 if self.width_m is None else (self.width_m / MM) ** self.width_exponent
        return self.gain_N * width * max(depth_m / MM, 0.0) ** self.depth_exponent

    def steady_force(self, depth_m: float, feed_m_s: float) -> float:
        """Eq. (5): F = Kf(d) f^beta [N]; zero for no depth or no forward feed."""
        if depth_m <= 0.0 or feed_m_s <= 0.0:
            return 0.0
        return self.force_gain_N(depth_m) * (feed_m_s / MM) ** self.feed_exponent

    def lag_s(self, depth_m: float) -> float:
        """tau_m of eq. (3), independent of depth."""
        return self.time_constant_s

    def feed_for_force(self, force_N: float, depth_m: float) -> float:
        """Inverse of eq. (5): f = (F / Kf)^(1/beta) [m/s]."""
        kf = self.force_gain_N(depth_m)
        if kf <= 0.0:
            return math.inf
        if force_N <= 0.0:
            return 0.0
        # In logs: a small beta makes the power overflow (or underflow) a float.
        exponent = math.log(force_N / kf) / self.feed_exponent
        if exponent > MAX_EXP:
            return math.inf
        return MM * math.exp(exponent) if exponent > -MAX_EXP else 0.0


@dataclass(frozen=True)
class LundForceModel:
    """dF/dt = -Kf/Df F + Kf v, eq. (9) of the Lund paper; Df grows with the depth of cut.

    Kf is the interaction stiffness (50 N/mm in the paper's simulation, 85 N/mm Cibatool, 143
    N/mm aluminium); Df [N s/m] is ``removal_N_s_m`` at ``depth_ref_m`` and proportional to the
    depth (the paper's Fig. 4: a deeper cut removes material more slowly for the same force).
    """

    stiffness_N_m: float = 50.0e3
    removal_N_s_m: float = 1.0e3
    depth_ref_m: float = 1.0 * MM

    def __post_init__(self) -> None:
        if not self.stiffness_N_m > 0.0 or not self.removal_N_s_m > 0.0:
            raise CmrrSettingsError("Lund model needs positive Kf and Df")
        if not self.depth_ref_m > 0.0:
            raise CmrrSettingsError("Lund model reference depth must be positive")

    def removal_parameter(self, depth_m: float) -> float:
        """Df [N s/m] at this depth of cut."""
        return self.removal_N_s_m * max(depth_m, 0.0) / self.depth_ref_m

    def steady_force(self, depth_m: float, feed_m_s: float) -> float:
        """Steady state of eq. (9): F = Df v [N]."""
        return self.removal_parameter(depth_m) * max(feed_m_s, 0.0)

    def lag_s(self, depth_m: float) -> float:
        """Df / Kf [s]."""
        return self.removal_parameter(depth_m) / self.stiffness_N_m

    def feed_for_force(self, force_N: float, depth_m: float) -> float:
        """v = F / Df [m/s]."""
        df = self.removal_parameter(depth_m)
        return math.inf if df <= 0.0 else max(force_N, 0.0) / df


def process_step(
    model: ForceModel, force_N: float, depth_m: float, feed_m_s: float, dt_s: float
) -> float:
    """Next process force [N]: exact first-order lag towards the steady force over one sample."""
    target = model.steady_force(depth_m, feed_m_s)
    tau = model.lag_s(depth_m)
    if tau <= 0.0:
        return target
    a = math.exp(-dt_s / tau)
    return a * force_N + (1.0 - a) * target


@dataclass(frozen=True, eq=False)
class LowPassFilter:
    """Discrete Butterworth low-pass as second-order sections; state is a tuple of floats."""

    cutoff_hz: float
    order: int
    dt_s: float
    sos: np.ndarray

    @classmethod
    def butterworth(cls, cutoff_hz: float, order: int, dt_s: float) -> LowPassFilter:
        """Design a Butterworth filter sampled at 1/dt_s (bilinear transform)."""
        nyquist = 0.5 / dt_s
        if not 0.0 < cutoff_hz < nyquist:
            raise CmrrSettingsError(
                f"filter cutoff must be in (0, {nyquist:g}) Hz at this sample rate, got {cutoff_hz}"
            )
        if order not in (1, 2, 3, 4):
            raise CmrrSettingsError(f"filter order must be 1 to 4, got {order}")
        import scipy.signal  # here, not at start-up: 0.7 s of every process's start

        sos = scipy.signal.butter(order, cutoff_hz, fs=1.0 / dt_s, output="sos")
        return cls(cutoff_hz=cutoff_hz, order=order, dt_s=dt_s, sos=np.asarray(sos))

    def initial_state(self, value: float = 0.0) -> tuple[float, ...]:
        """Filter state at rest with a constant input ``value`` (unit DC gain)."""
        import scipy.signal  # here, not at start-up: 0.7 s of every process's start

        zi = scipy.signal.sosfilt_zi(self.sos) * value
        return tuple(float(z) for z in zi.ravel())

    def step(self, state: tuple[float, ...], x: float) -> tuple[tuple[float, ...], float]:
        """One sample through the cascade (transposed direct form II)."""
        new: list[float] = []
        y = x
        for i, (b0, b1, b2, _, a1, a2) in enumerate(self.sos):
            z1, z2 = state[2 * i], state[2 * i + 1]
            out = b0 * y + z1
            new.append(b1 * y - a1 * out + z2)
            new.append(b2 * y - a2 * out)
            y = out
        return tuple(new), float(y)


@dataclass(frozen=True)
class ForceSensorModel:
    """F/T sensor along the feed direction: white noise, then the low-pass filter of the paper.

    The MRR paper filters the force before feedback but does not state the filter; a second-order
    Butterworth at 20 Hz is used by default (it removes the noise above the loop's ~7 Hz crossover
    while costing ~30 degrees of phase there).
    """

    noise_std_N: float = 2.0
    bias_N: float = 0.0
    filter_cutoff_hz: float = 20.0
    filter_order: int = 2

    def __post_init__(self) -> None:
        if self.noise_std_N < 0.0:
            raise CmrrSettingsError("sensor noise must not be negative")

    def make_filter(self, dt_s: float) -> LowPassFilter:
        """The feedback low-pass filter at this sample time."""
        return LowPassFilter.butterworth(self.filter_cutoff_hz, self.filter_order, dt_s)


@dataclass(frozen=True)
class SpindleCurrentModel:
    """Spindle current I = I0 + c F + noise [A] (eq. (7): F v = U I at constant spindle speed).

    ``calibration_error`` scales the gain the controller assumes when it converts the current
    back to force, so the effect of a poor linear calibration can be studied.
    """

    amps_per_N: float = 0.02
    offset_A: float = 1.5
    noise_std_A: float = 0.04
    calibration_error: float = 0.0

    def __post_init__(self) -> None:
        if not self.amps_per_N > 0.0:
            raise CmrrSettingsError("spindle current gain must be positive")
        if self.noise_std_A < 0.0:
            raise CmrrSettingsError("spindle current noise must not be negative")

    def current_A(self, force_N: float, noise: float) -> float:
        """Spindle current [A] for a process force and a standard-normal noise draw."""
        return self.offset_A + self.amps_per_N * force_N + self.noise_std_A * noise

    def force_from_current(self, current_A: float) -> float:
        """The controller's linear conversion back to force [N] (gain and offset)."""
        return (current_A - self.offset_A) / (self.amps_per_N * (1.0 + self.calibration_error))
