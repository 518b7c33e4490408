"""Model-based adaptive LQ feed control, after Sornmo et al. (the Lund paper), sec. 2.1.

PROBLEM: hold the machining force at Fr when the material-removal parameter Df (deeper cut:
larger Df, larger force at the same feed) changes along the path.
STRATEGY: model the force as dF/dt = -Kf/Df F + Kf v (eq. (9)) driven by the robot's feed
dynamics Gv (eq. (1) of the MRR paper here: the Lund paper's own identified model is not
published). Augment the robot states with the force (eq. (11)), the integral of the force error
(eq. (15)) and the control delay, and choose the state feedback vr = -L xe + lr fr (eq. (13)) by
minimizing the LQ cost (14), solving the discrete algebraic Riccati equation. A Kalman filter
(eqs. (7)-(8)) estimates the robot states from the measured feed; RLS estimates Df.
SOLUTION: start at a constant feed (the Lund paper's 6 mm/s) so the RLS has data; once the
estimate's relative standard deviation is below a threshold, switch to the LQ law (bumpless:
the integral state is set so the command does not jump), and re-solve the Riccati equation
whenever the Df estimate has moved by more than ``resolve_tolerance``.

Units inside this module follow the Lund paper: mm, mm/s, N, N/mm, N s/mm.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from functools import cached_property, lru_cache
from typing import Literal

import numpy as np
import scipy.linalg

from ...cell import zoh
from ..errors import CmrrSettingsError
from .base import ControlDesign, ControlOutput, Measurement, saturate

MM = 1e-3


@dataclass(frozen=True)
class AdaptiveLqSettings:
    """Adaptive LQ with Kalman filter, integral action and RLS estimate of Df.

    Attributes:
        force_weight: Q weight of the force error, per Fr^2.
        integral_weight: Q weight of the force-error integral, per (Fr * integral_time)^2.
        input_weight: R weight of the feed command, per Vr^2.
        integral_time_s: time scale of the integral weight [s].
        startup_speed_ratio: constant speed ratio until the Df estimate has converged
            (the Lund paper started at 6 mm/s).
        min_startup_s: shortest start-up phase [s].
        activation_rel_std: the LQ law starts when the estimated relative standard deviation
            of Df falls below this.
        forgetting_factor: RLS forgetting factor for Df.
        resolve_tolerance: step of the geometric grid of Df values the LQ gain is designed
            for; a new Riccati solution when the estimate moves to another grid point.
        adapt: False freezes Df at its initial value (the Lund paper's Fig. 7 comparison).
        initial_removal_N_s_mm: the initial Df [N s/mm]; None takes the scenario's value.
        stiffness_N_mm: interaction stiffness Kf [N/mm]; None takes the scenario's value.
        derivative_filter_hz: bandwidth of the state-variable filter that gives dF/dt.
        feed_noise_mm_s: assumed noise of the measured feed (Kalman filter).
        feed_disturbance_mm_s: assumed disturbance on the commanded feed (Kalman filter).
    """

    kind: Literal["adaptive-lq"] = field(default="adaptive-lq", init=False)
    force_weight: float = 1.0
    integral_weight: float = 1.0
    input_weight: float = 0.5
    integral_time_s: float = 0.1
    startup_speed_ratio: float = 0.15
    min_startup_s: float = 0.3
    activation_rel_std: float = 0.03
    forgetting_factor: float = 0.97
    resolve_tolerance: float = 0.02
    adapt: bool = True
    initial_removal_N_s_mm: float | None = None
    stiffness_N_mm: float | None = None
    derivative_filter_hz: float = 8.0
    feed_noise_mm_s: float = 0.05
    feed_disturbance_mm_s: float = 1.0

    def __post_init__(self) -> None:
        for name in ("force_weight", "input_weight", "integral_time_s", "derivative_filter_hz"):
            if not getattr(self, name) > 0.0:
                raise CmrrSettingsError(f"adaptive LQ {name} must be positive")
        if self.integral_weight < 0.0:
            raise CmrrSettingsError("adaptive LQ integral weight must not be negative")
        if not 0.0 < self.startup_speed_ratio <= 1.0:
            raise CmrrSettingsError("start-up speed ratio must be in (0, 1]")
        if not 0.5 < self.forgetting_factor <= 1.0:
            raise CmrrSettingsError("forgetting factor must be in (0.5, 1]")
        if not self.activation_rel_std > 0.0 or self.min_startup_s < 0.0:
            raise CmrrSettingsError("activation threshold must be positive, start-up >= 0")
        if not self.resolve_tolerance >= 0.0:
            raise CmrrSettingsError("re-solve tolerance must not be negative")
        for name in ("initial_removal_N_s_mm", "stiffness_N_mm"):
            value = getattr(self, name)
            if value is not None and not value > 0.0:
                raise CmrrSettingsError(f"{name} must be positive")
        if not self.feed_noise_mm_s > 0.0 or not self.feed_disturbance_mm_s > 0.0:
            raise CmrrSettingsError("Kalman filter noise levels must be positive")


@dataclass(frozen=True, eq=False)
class LqDesign:
    """One solution of the LQ problem for a given Df.

    ``gain`` shape (m,) over [robot states, delayed commands, force, integral]; ``feedforward``
    is lr of eq. (13).
    """

    removal_N_s_mm: float
    gain: np.ndarray
    feedforward: float


@dataclass(frozen=True, eq=False)
class AdaptiveLqState:
    """Kalman estimate, delayed commands, integral, RLS, filters, and the current design."""

    x_hat: np.ndarray
    commands_mm_s: tuple[float, ...]
    integral_N_s: float
    theta: float
    covariance: float
    residual_var: float
    svf_force: tuple[float, float]
    svf_feed: tuple[float, float]
    feed_filter: tuple[float, ...]
    time_s: float
    active: bool
    design: LqDesign


@dataclass(frozen=True)
class AdaptiveLqController:
    """vr = -L [x_hat; delayed vr; F; int(Fr - F)] + lr Fr, L from the DARE for Df_hat."""

    settings: AdaptiveLqSettings
    design: ControlDesign
    name: str = "adaptive-lq"
    estimate_names: tuple[str, ...] = ("removal_N_s_m",)

    @cached_property
    def kf(self) -> float:
        """Interaction stiffness [N/mm]."""
        return self.settings.stiffness_N_mm or self.design.interaction_stiffness_N_m * MM

    @cached_property
    def df0(self) -> float:
        """Initial Df [N s/mm]."""
        return self.settings.initial_removal_N_s_mm or self.design.initial_removal_N_s_m * MM

    @cached_property
    def vr_mm_s(self) -> float:
        return self.design.command_speed_m_s / MM

    @cached_property
    def robot(self) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Discrete robot model (Phi, Gamma, C), speed in mm/s (the model is unit-free)."""
        a, b, c = self.design.feed_dynamics.state_space()
        phi, gamma = zoh(a, b, self.design.dt_s)
        return phi, gamma, c

    @cached_property
    def kalman_gain(self) -> np.ndarray:
        """Steady-state Kalman gain for the robot states from the measured feed, eq. (7)."""
        phi, gamma, c = self.robot
        s = self.settings
        qn = np.outer(gamma, gamma) * s.feed_disturbance_mm_s**2 + 1e-9 * np.eye(phi.shape[0])
        rn = np.array([[s.feed_noise_mm_s**2]])
        p = scipy.linalg.solve_discrete_are(phi.T, c[:, None], qn, rn)
        return (p @ c) / float(c @ p @ c + rn[0, 0])

    @cached_property
    def svf(self) -> tuple[np.ndarray, np.ndarray]:
        """Discrete state-variable filter H = w^2/(s^2 + 2 z w s + w^2): states (H u, s H u)."""
        w = 2.0 * math.pi * self.settings.derivative_filter_hz
        a = np.array([[0.0, 1.0], [-w * w, -2.0 * 0.7 * w]])
        return zoh(a, np.array([0.0, w * w]), self.design.dt_s)

    def solve(self, removal_N_s_mm: float) -> LqDesign:
        """LQ gain and feedforward for this Df (eq. (14) via the discrete Riccati equation)."""
        a, b, c = self.design.feed_dynamics.state_space()
        return _solve_lq(
            removal_N_s_mm,
            self.kf,
            a.tobytes(),
            b.tobytes(),
            c.tobytes(),
            self.design.dt_s,
            self.design.control_delay_steps,
            self.design.reference_force_N,
            self.vr_mm_s,
            (
                self.settings.force_weight,
                self.settings.integral_weight,
                self.settings.input_weight,
                self.settings.integral_time_s,
            ),
        )

    @property
    def initial_speed_ratio(self) -> float:
        return self.settings.startup_speed_ratio

    def _grid(self, df_hat: float) -> float | None:
        """Df on a geometric grid of step ``resolve_tolerance`` around Df0 (None if invalid).

        Re-designing only when the grid point changes bounds the number of Riccati solutions
        and lets the cache serve a Df that comes back.
        """
        if not df_hat > 0.0 or not math.isfinite(df_hat):
            return None
        tol = self.settings.resolve_tolerance
        if tol <= 0.0:
            return df_hat
        step = math.log1p(tol)
        return self.df0 * math.exp(step * round(math.log(df_hat / self.df0) / step))

    def initial_state(self) -> AdaptiveLqState:
        n = self.robot[0].shape[0]
        filt = self.design.measurement_filter
        start = self.settings.startup_speed_ratio * self.vr_mm_s
        return AdaptiveLqState(
            x_hat=np.zeros(n),
            commands_mm_s=(start,) * self.design.control_delay_steps,
            integral_N_s=0.0,
            theta=self.df0 * self.vr_mm_s / self.design.reference_force_N,
            covariance=1.0,
            residual_var=0.0,
            svf_force=(0.0, 0.0),
            svf_feed=(0.0, 0.0),
            feed_filter=filt.initial_state() if filt is not None else (),
            time_s=0.0,
            active=False,
            design=self.solve(self.df0),
        )

    def step(
        self, state: AdaptiveLqState, measurement: Measurement
    ) -> tuple[AdaptiveLqState, ControlOutput]:
        s, d = self.settings, self.design
        phi, gamma, c = self.robot
        fr = d.reference_force_N
        force = measurement.force_N
        feed = measurement.feed_m_s / MM
        dt = d.dt_s

        # Kalman filter, measurement update (eq. (7)); the input during the last sample was
        # the oldest command still in the delay line.
        x_hat = state.x_hat + self.kalman_gain * (feed - float(c @ state.x_hat))

        # RLS on the filtered model F = Df (v - dF/dt / Kf): theta = Df Vr / Fr (normalized).
        feed_filter, feed_f = state.feed_filter, feed
        if d.measurement_filter is not None:
            feed_filter, feed_f = d.measurement_filter.step(state.feed_filter, feed)
        sphi, sgam = self.svf
        svf_force = tuple(sphi @ np.array(state.svf_force) + sgam * force)
        svf_feed = tuple(sphi @ np.array(state.svf_feed) + sgam * feed_f)
        y = svf_force[0] / fr
        x = (svf_feed[0] - svf_force[1] / self.kf) / self.vr_mm_s
        theta, p, r2 = state.theta, state.covariance, state.residual_var
        if s.adapt and x > 0.03 and y > 0.03:
            lam = s.forgetting_factor
            residual = y - theta * x
            gain = p * x / (lam + x * p * x)
            theta = theta + gain * residual
            p = min((p - gain * x * p) / lam, 1.0e3)
            r2 = lam * r2 + (1.0 - lam) * residual * residual
        df_hat = theta * fr / self.vr_mm_s
        rel_std = math.sqrt(max(r2 * p, 0.0)) / max(abs(theta), 1e-9)

        time_s = state.time_s + dt
        lq = state.design
        active = state.active
        integral = state.integral_N_s
        delayed = np.array(state.commands_mm_s)
        last_command = state.commands_mm_s[-1] if state.commands_mm_s else None
        grid_df = self._grid(df_hat)
        if s.adapt and grid_df is not None and grid_df != lq.removal_N_s_mm:
            old = lq
            lq = self.solve(grid_df)
            if active:
                # Bumpless re-design: the integral absorbs the change of the other terms.
                before = _lq_command(old, x_hat, delayed, force, integral, fr)
                integral = _matching_integral(lq, x_hat, delayed, force, fr, before, integral)
        ready = not s.adapt or rel_std < s.activation_rel_std
        if not active and time_s >= s.min_startup_s and ready:
            active = True
            # Bumpless switch: choose the integral so the first LQ command equals the current one.
            current = s.startup_speed_ratio * self.vr_mm_s if last_command is None else last_command
            integral = _matching_integral(lq, x_hat, delayed, force, fr, current, integral)

        if active:
            command = _lq_command(lq, x_hat, delayed, force, integral, fr)
            ratio = saturate(command / self.vr_mm_s, d.min_speed_ratio)
            error = fr - force
            pushing = (ratio >= 1.0 and error > 0.0) or (ratio <= d.min_speed_ratio and error < 0.0)
            if not pushing:
                integral += dt * error
        else:
            ratio = s.startup_speed_ratio
        command_mm_s = ratio * self.vr_mm_s

        # Kalman time update with the command that acts during the coming sample.
        acting = state.commands_mm_s[0] if state.commands_mm_s else command_mm_s
        x_next = phi @ x_hat + gamma * acting
        commands = (*state.commands_mm_s[1:], command_mm_s) if state.commands_mm_s else ()
        new_state = AdaptiveLqState(
            x_hat=x_next,
            commands_mm_s=commands,
            integral_N_s=integral,
            theta=theta,
            covariance=p,
            residual_var=r2,
            svf_force=svf_force,
            svf_feed=svf_feed,
            feed_filter=feed_filter,
            time_s=time_s,
            active=active,
            design=lq,
        )
        return new_state, ControlOutput(
            ratio, engaged=active, estimates={"removal_N_s_m": df_hat / MM}
        )

    def describe(self) -> dict[str, float | str]:
        lq = self.solve(self.df0)
        return {
            "stiffness_N_mm": self.kf,
            "initial_removal_N_s_mm": self.df0,
            "adapt": "yes" if self.settings.adapt else "no",
            "force_gain_at_initial_Df": float(lq.gain[-2]),
            "integral_gain_at_initial_Df": float(lq.gain[-1]),
            "feedforward_at_initial_Df": lq.feedforward,
        }


def _lq_command(
    lq: LqDesign, x_hat: np.ndarray, delayed: np.ndarray, force: float, integral: float, fr: float
) -> float:
    """Eq. (13) with the integral state: vr = -L [x; delayed; F; xi] + lr Fr [mm/s]."""
    n = x_hat.size
    g = lq.gain
    feedback = float(g[:n] @ x_hat) + float(g[n:-2] @ delayed) + g[-2] * force + g[-1] * integral
    return -feedback + lq.feedforward * fr


def _matching_integral(
    lq: LqDesign,
    x_hat: np.ndarray,
    delayed: np.ndarray,
    force: float,
    fr: float,
    command: float,
    fallback: float,
) -> float:
    """The integral state for which ``lq`` commands ``command`` at this state."""
    li = lq.gain[-1]
    if abs(li) < 1e-12:
        return fallback
    without = _lq_command(lq, x_hat, delayed, force, 0.0, fr)
    return (without - command) / li


@lru_cache(maxsize=256)
def _solve_lq(
    removal: float,
    kf: float,
    a_bytes: bytes,
    b_bytes: bytes,
    c_bytes: bytes,
    dt_s: float,
    delay: int,
    fr: float,
    vr: float,
    weights: tuple[float, float, float, float],
) -> LqDesign:
    """Discrete LQ design of the augmented model (eq. (11) plus delay line and integral).

    Arguments are hashable (matrices as bytes) so designs for the same Df are cached.
    """
    c = np.frombuffer(c_bytes)
    n = c.size
    force_w, integral_w, input_w, ti = weights
    # Continuous force and integral dynamics driven by the robot output C x, discretized with
    # the robot: states [x, F, xi], input v_c held over the sample.
    m = n + 2
    a = np.zeros((m, m))
    b = np.zeros(m)
    a[:n, :n] = np.frombuffer(a_bytes).reshape(n, n)
    b[:n] = np.frombuffer(b_bytes)
    a[n, :n] = kf * c
    a[n, n] = -kf / removal
    a[n + 1, n] = -1.0
    phi_p, gamma_p = zoh(a, b, dt_s)
    # Delay line: the command reaches the robot ``delay`` samples later.
    size = m + delay
    phi = np.zeros((size, size))
    gamma = np.zeros(size)
    # Order: [x (n), delayed commands (delay, oldest first), F, xi].
    idx_plant = list(range(n)) + [n + delay, n + delay + 1]
    for i, gi in enumerate(idx_plant):
        for j, gj in enumerate(idx_plant):
            phi[gi, gj] = phi_p[i, j]
    if delay == 0:
        for i, gi in enumerate(idx_plant):
            gamma[gi] = gamma_p[i]
    else:
        for i, gi in enumerate(idx_plant):
            phi[gi, n] = gamma_p[i]
        for k in range(delay - 1):
            phi[n + k, n + k + 1] = 1.0
        gamma[n + delay - 1] = 1.0
    q = np.zeros((size, size))
    q[n + delay, n + delay] = force_w / fr**2
    q[n + delay + 1, n + delay + 1] = integral_w / (fr * ti) ** 2
    r = np.array([[input_w / vr**2]])
    p = scipy.linalg.solve_discrete_are(phi, gamma[:, None], q, r)
    gain = (gamma @ p @ phi) / float(r[0, 0] + gamma @ p @ gamma)
    # Feedforward lr: unit static gain from Fr to F without the integral state.
    keep = [i for i in range(size) if i != n + delay + 1]
    phi_k = phi[np.ix_(keep, keep)] - np.outer(gamma[keep], gain[keep])
    out = np.zeros(len(keep))
    out[keep.index(n + delay)] = 1.0
    static = float(out @ np.linalg.solve(np.eye(len(keep)) - phi_k, gamma[keep]))
    lr = 1.0 / static if abs(static) > 1e-12 else 0.0
    return LqDesign(removal_N_s_mm=removal, gain=gain, feedforward=lr)
