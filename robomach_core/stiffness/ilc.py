"""Iterative learning control of the milling path over repeated runs (the Lund ILC paper).

PROBLEM   A batch of identical parts is milled along the same path; the arm deviates from it
          through servo lag, calibration offsets and the deflection under process forces.
          Learn a path correction u from run to run.
STRATEGY  The paper's models, eq. (1), per Cartesian axis at 250 Hz:
          y_n = G_R (r + u) + d + offset,  d = G_K f,  f = G_M y_n,
          G_R the position-controlled robot (second order with velocity feed-forward), G_K
          the compliance (static C from the stiffness model times a resonance), G_M the process
          K s / (1 + tau s)^2 (force proportional to the feed rate, eq. 2). Update law eq. (7):
          u_{k+1} = Q (u_k + L~ (I - G_K G_M) e_k), L~ = gamma G_R^-1 (advanced one sample;
          the one sampling zero of G_R lies inside the unit circle, so the inverse is stable),
          Q a zero-phase low-pass. Arm-side ILC measures e = r - y_n (tracker); force ILC
          estimates it from the resolvers and the sensor, e = r - y_r - G_K f, eq. (9), and so
          cannot see the calibration offset.
SOLUTION  ``IlcSystem`` (the three models), ``simulate_ilc_run``, ``ilc_update`` and
          ``run_ilc`` (error per iteration), ``square_path`` (the paper's square).
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, replace
from typing import Literal

import numpy as np

from ..cell import CONTROL_PERIOD_S, zoh, zoh_tf
from ..errors import CancelledError, InvalidInputError

IlcKind = Literal["arm", "force"]

# Zero-phase Q filter cut-off [Hz], just below the 12 Hz arm resonance (the paper: "close to
# the first eigenfrequency"); at 25 Hz a 10-15 % model error makes the iterations diverge.
Q_CUTOFF_HZ = 10.0
LEARNING_GAIN = 1.0
# Run-to-run force disturbances are low-passed at this frequency [Hz].
DISTURBANCE_CUTOFF_HZ = 5.0


def _signal():
    """scipy.signal, imported on first use, not at start-up (0.7 s of every process's start)."""
    from scipy import signal

    return signal


@dataclass(frozen=True)
class IlcSystem:
    """G_R, G_K and G_M of eq. (1) for the x, y, z axes of the base frame.

    Attributes:
        compliance_m_N: (3, 3) static compliance C (translational block of J Kq^-1 J^T).
        process_gain_Ns_m: (3, 3) K of G_M: force [N] per TCP velocity [m/s].
        servo_bandwidth_hz / servo_damping: G_R, a second-order position loop with velocity
            feed-forward, (2 zeta w s + w^2) / (s^2 + 2 zeta w s + w^2): no lag on straight
            lines, transients at the corners.
        resonance_hz / resonance_damping: The dynamics of G_K (unit static gain).
        process_time_constant_s: tau of G_M, eq. (2).
        dt: Sampling period [s].
    """

    compliance_m_N: np.ndarray
    process_gain_Ns_m: np.ndarray
    servo_bandwidth_hz: float = 8.0
    servo_damping: float = 0.7
    resonance_hz: float = 12.0
    resonance_damping: float = 0.3
    process_time_constant_s: float = 0.01
    dt: float = CONTROL_PERIOD_S

    def _siso(self, num: list[float], den: list[float]) -> tuple[np.ndarray, ...]:
        A, B, C, D = _signal().tf2ss(num, den)
        Phi, Gamma = zoh(A, B, self.dt)
        return Phi, Gamma, C, D

    def robot_tf(self) -> tuple[np.ndarray, np.ndarray]:
        """Discrete (b, a) of G_R, one axis: b[0] = 0, one sample of delay."""
        w = 2 * np.pi * self.servo_bandwidth_hz
        zw = 2 * self.servo_damping * w
        b, a = zoh_tf([zw, w**2], [1.0, zw, w**2], self.dt)
        b[0] = 0.0  # exactly zero for a strictly proper continuous model; drop round-off
        return b, a

    def _resonance(self) -> tuple[np.ndarray, ...]:
        w = 2 * np.pi * self.resonance_hz
        return self._siso([w**2], [1.0, 2 * self.resonance_damping * w, w**2])

    def _process(self) -> tuple[np.ndarray, ...]:
        tau = self.process_time_constant_s
        return self._siso([1.0, 0.0], [tau**2, 2 * tau, 1.0])

    def loop_matrices(self) -> tuple[np.ndarray, ...]:
        """State space of H = G_K G_M (input y_n, outputs deflection d and force f)."""
        Am, Bm, Cm, _ = self._process()
        Ak, Bk, Ck, _ = self._resonance()
        eye = np.eye(3)
        A_M, B_M, C_M = np.kron(eye, Am), np.kron(eye, Bm), np.kron(eye, Cm)
        A_K, B_K, C_K = np.kron(eye, Ak), np.kron(eye, Bk), np.kron(eye, Ck)
        K_M = np.asarray(self.process_gain_Ns_m, dtype=float)
        C_s = np.asarray(self.compliance_m_N, dtype=float)
        nm, nk = len(A_M), len(A_K)
        A = np.block([[A_M, np.zeros((nm, nk))], [B_K @ C_s @ K_M @ C_M, A_K]])
        B = np.vstack([B_M, np.zeros((nk, 3))])
        C_d = np.hstack([np.zeros((3, nm)), C_K])
        C_f = np.hstack([K_M @ C_M, np.zeros((3, nk))])
        return A, B, C_d, C_f

    def apply_robot(self, x: np.ndarray) -> np.ndarray:
        """G_R x for (N, 3) signals starting at rest."""
        b, a = self.robot_tf()
        return _signal().lfilter(b, a, x, axis=0)

    def apply_process(self, y: np.ndarray) -> np.ndarray:
        """G_M y: (N, 3) force [N] from (N, 3) positions [m]."""
        tau = self.process_time_constant_s
        b, a = zoh_tf([1.0, 0.0], [tau**2, 2 * tau, 1.0], self.dt)
        v = _signal().lfilter(b, a, y, axis=0)
        return v @ np.asarray(self.process_gain_Ns_m, dtype=float).T

    def apply_compliance(self, f: np.ndarray) -> np.ndarray:
        """G_K f: (N, 3) deflection [m] from (N, 3) force [N]."""
        w = 2 * np.pi * self.resonance_hz
        b, a = zoh_tf([w**2], [1.0, 2 * self.resonance_damping * w, w**2], self.dt)
        static = f @ np.asarray(self.compliance_m_N, dtype=float).T
        return _signal().lfilter(b, a, static, axis=0)

    def robot_inverse(self, v: np.ndarray) -> np.ndarray:
        """L~ v = G_R^-1 v, advanced one sample (G_R has one sample of delay)."""
        b, a = self.robot_tf()
        advanced = np.vstack([v[1:], v[-1:]])
        return _signal().lfilter(a, b[1:], advanced, axis=0)


def _disturbance_input(system: IlcSystem) -> np.ndarray:
    """Input matrix of a force added after G_M: it enters G_K through C."""
    A = system.loop_matrices()[0]
    _, Bk, _, _ = system._resonance()
    n_k = 3 * len(Bk)
    B_d = np.zeros((len(A), 3))
    B_d[len(A) - n_k :] = np.kron(np.eye(3), Bk) @ np.asarray(system.compliance_m_N, dtype=float)
    return B_d


@dataclass(frozen=True)
class IlcRun:
    """One execution of the path.

    Attributes:
        y_arm_m: (N, 3) arm-side TCP positions (truth).
        y_resolver_m: (N, 3) positions from the motor resolvers, G_R (r + u).
        force_N: (N, 3) process force (truth).
        y_arm_measured_m / force_measured_N: What the tracker and the F/T sensor report.
    """

    y_arm_m: np.ndarray
    y_resolver_m: np.ndarray
    force_N: np.ndarray
    y_arm_measured_m: np.ndarray
    force_measured_N: np.ndarray


def simulate_ilc_run(
    system: IlcSystem,
    reference_m: np.ndarray,
    correction_m: np.ndarray,
    *,
    offset_m: np.ndarray,
    tracker_noise_m: float,
    force_noise_N: float,
    rng: np.random.Generator,
    force_disturbance_N: float = 0.0,
) -> IlcRun:
    """y_n = G_R (r + u) + offset + G_K (G_M y_n + f_d), simulated sample by sample (eq. 3).

    f_d is a disturbance that differs from run to run (material and tool variation): white
    noise low-passed at ``DISTURBANCE_CUTOFF_HZ``, standard deviation ``force_disturbance_N``.
    """
    r0 = reference_m[0]
    b, a = _signal().butter(2, DISTURBANCE_CUTOFF_HZ, fs=1.0 / system.dt)
    raw = rng.normal(0.0, 1.0, reference_m.shape)
    disturbance = _signal().filtfilt(b, a, raw, axis=0)
    disturbance *= force_disturbance_N / max(float(disturbance.std()), 1e-300)
    y_r = system.apply_robot(reference_m - r0 + correction_m)
    w = y_r + np.asarray(offset_m, dtype=float)
    A, B, C_d, C_f = system.loop_matrices()
    B_d = _disturbance_input(system)
    x = np.zeros(len(A))
    y_n = np.empty_like(w)
    force = np.empty_like(w)
    for k in range(len(w)):
        y_n[k] = w[k] + C_d @ x
        force[k] = C_f @ x + disturbance[k]
        x = A @ x + B @ y_n[k] + B_d @ disturbance[k]
    return IlcRun(
        y_arm_m=y_n + r0,
        y_resolver_m=y_r + r0,
        force_N=force,
        y_arm_measured_m=y_n + r0 + rng.normal(0.0, tracker_noise_m, y_n.shape),
        force_measured_N=force + rng.normal(0.0, force_noise_N, force.shape),
    )


def ilc_update(
    model: IlcSystem,
    correction_m: np.ndarray,
    error_m: np.ndarray,
    *,
    learning_gain: float = LEARNING_GAIN,
    q_cutoff_hz: float | None = Q_CUTOFF_HZ,
) -> np.ndarray:
    """Eq. (7): u_{k+1} = Q (u_k + gamma G_R^-1 (I - G_K G_M) e_k). Shapes (N, 3)."""
    v = error_m - model.apply_compliance(model.apply_process(error_m))
    u = correction_m + learning_gain * model.robot_inverse(v)
    if q_cutoff_hz is None:
        return u
    b, a = _signal().butter(2, q_cutoff_hz, fs=1.0 / model.dt)
    return _signal().filtfilt(b, a, u, axis=0)


def square_path(
    side_m: float = 0.040,
    speed_m_s: float = 0.020,
    *,
    center_m: tuple[float, float, float] = (0.70, 0.10, 0.03),
    ramp_s: float = 0.2,
    dwell_s: float = 0.2,
    dt: float = CONTROL_PERIOD_S,
) -> np.ndarray:
    """The paper's square (Fig. 9) in the base XY plane: (N, 3) positions, at rest at both ends.

    The speed ramps up and down over ``ramp_s``; corners are taken at full speed.
    """
    if side_m <= 0 or speed_m_s <= 0:
        raise InvalidInputError("square side and speed must be positive")
    perimeter = 4 * side_m
    cruise = perimeter / speed_m_s - ramp_s
    t = np.arange(0.0, cruise + 2 * ramp_s + 2 * dwell_s, dt)
    tm = np.clip(t - dwell_s, 0.0, cruise + ramp_s * 2)
    v = speed_m_s * np.clip(np.minimum(tm / ramp_s, (cruise + 2 * ramp_s - tm) / ramp_s), 0, 1)
    s = np.concatenate([[0.0], np.cumsum(0.5 * (v[1:] + v[:-1]) * dt)])
    s = np.clip(s * perimeter / s[-1], 0.0, perimeter)
    corners = np.array([[0, 0], [1, 0], [1, 1], [0, 1], [0, 0]], dtype=float) * side_m
    corners -= side_m / 2
    edge = np.minimum((s // side_m).astype(int), 3)
    frac = (s - edge * side_m) / side_m
    xy = corners[edge] + frac[:, None] * (corners[edge + 1] - corners[edge])
    return np.column_stack([xy, np.zeros(len(s))]) + np.asarray(center_m)


@dataclass(frozen=True)
class IlcResult:
    """Errors over iterations 0..n (iteration 0 is the uncorrected run).

    Attributes:
        kind: ``"arm"`` or ``"force"``.
        reference_m: (N, 3) the desired path.
        errors_m: (n+1, N, 3) true error r - y_n per iteration.
        error_mean_um: (n+1,) mean Euclidean error per iteration.
        error_normalized: (n+1,) sum |e| over samples and axes relative to iteration 0 (the
            paper's Fig. 11 and 13 measure).
        deviation_mean_um: (n+1,) mean Euclidean error around each axis' mean (the offset),
            the measure the paper uses for the force ILC.
        correction_m: (N, 3) the learnt correction after the last iteration.
    """

    kind: str
    reference_m: np.ndarray
    errors_m: np.ndarray
    error_mean_um: np.ndarray
    error_normalized: np.ndarray
    deviation_mean_um: np.ndarray
    correction_m: np.ndarray


def run_ilc(
    truth: IlcSystem,
    model: IlcSystem,
    reference_m: np.ndarray,
    *,
    kind: IlcKind,
    iterations: int = 6,
    offset_m: tuple[float, float, float] = (60e-6, -40e-6, 30e-6),
    tracker_noise_m: float = 10e-6,
    force_noise_N: float = 2.0,
    force_disturbance_N: float = 0.0,
    learning_gain: float = LEARNING_GAIN,
    q_cutoff_hz: float | None = Q_CUTOFF_HZ,
    seed: int = 0,
    progress: Callable[[float], None] | None = None,
    cancel: Callable[[], bool] | None = None,
) -> IlcResult:
    """Repeat the path ``iterations`` times, learning the correction with eq. (7).

    ``truth`` simulates the arm; ``model`` is what the ILC believes (identified C, nominal
    dynamics). Arm-side ILC uses the tracker; force ILC uses eq. (9) on the resolvers and the
    sensor, and so leaves ``offset_m`` (a calibration error in free space) in place.
    """
    if kind not in ("arm", "force"):
        raise InvalidInputError(f"ILC kind must be 'arm' or 'force', not {kind!r}")
    if iterations < 0:
        raise InvalidInputError("ILC iterations must be >= 0")
    rng = np.random.default_rng(seed)
    r = np.asarray(reference_m, dtype=float)
    u = np.zeros_like(r)
    errors = []
    for iteration in range(iterations + 1):
        if cancel is not None and cancel():
            raise CancelledError("ILC study cancelled")
        run = simulate_ilc_run(
            truth,
            r,
            u,
            offset_m=np.asarray(offset_m),
            tracker_noise_m=tracker_noise_m,
            force_noise_N=force_noise_N,
            rng=rng,
            force_disturbance_N=force_disturbance_N,
        )
        errors.append(r - run.y_arm_m)
        if kind == "arm":
            e = r - run.y_arm_measured_m
        else:
            e = r - run.y_resolver_m - model.apply_compliance(run.force_measured_N)
        if iteration < iterations:
            u = ilc_update(model, u, e, learning_gain=learning_gain, q_cutoff_hz=q_cutoff_hz)
        if progress is not None:
            progress((iteration + 1) / (iterations + 1))
    E = np.array(errors)
    magnitude = np.abs(E).sum(axis=(1, 2))
    around = E - E.mean(axis=1, keepdims=True)
    return IlcResult(
        kind=kind,
        reference_m=r,
        errors_m=E,
        error_mean_um=np.linalg.norm(E, axis=2).mean(axis=1) * 1e6,
        error_normalized=magnitude / magnitude[0] if magnitude[0] > 0 else magnitude,
        deviation_mean_um=np.linalg.norm(around, axis=2).mean(axis=1) * 1e6,
        correction_m=u,
    )


def milling_process_gain(
    feed_force_N: float = 300.0, cutting_force_N: float = 200.0, speed_m_s: float = 0.020
) -> np.ndarray:
    """(3, 3) K of G_M for a vertical cutter moving in the XY plane.

    The feed force opposes the velocity and the cutting force acts 90 degrees to its left,
    both proportional to the feed rate (the paper's damping-like process model, eq. 2).
    """
    k_f, k_c = feed_force_N / speed_m_s, cutting_force_N / speed_m_s
    return np.array([[-k_f, -k_c, 0.0], [k_c, -k_f, 0.0], [0.0, 0.0, 0.0]])


def perturbed(
    system: IlcSystem,
    *,
    process_gain_scale: float = 1.0,
    bandwidth_scale: float = 1.0,
    resonance_scale: float = 1.0,
) -> IlcSystem:
    """A copy with scaled process gain, servo bandwidth and resonance (a model that is off)."""
    return replace(
        system,
        process_gain_Ns_m=np.asarray(system.process_gain_Ns_m) * process_gain_scale,
        servo_bandwidth_hz=system.servo_bandwidth_hz * bandwidth_scale,
        resonance_hz=system.resonance_hz * resonance_scale,
    )
