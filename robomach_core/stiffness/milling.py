"""Simulated milling passes on the compliant arm and the error they leave on the part.

PROBLEM   Show what the process forces do to a machined surface and what compensation buys:
          the chapter's aluminium end-milling test (150 x 50 mm 6063 block, 3 mm depth,
          20 mm/s, feed and cutting forces ~300 N, normal ~50 N; uncompensated 0.4 mm too deep)
          and the Lund paper's face-milling pass (error across the feed, 273.9 -> 51.4 um max).
STRATEGY  Quasi-static, one 4 ms control step at a time. The motors hold the commanded joints;
          the process wrench is the scenario's nominal wrench scaled by the cutter's engagement
          (the share of the block width its leading edge meets) and by the actual depth of cut
          (so a cutter pushed deeper cuts harder), plus seeded noise and an optional
          oscillation; the arm bends under it by the simulator's true, hidden stiffness
          (non-linear equilibrium). The F/T sensor reads contact + tool weight + bias + noise.
          The cutter's flat bottom (a disc of the cutter radius, tilted with the tool) sweeps a
          grid on the block; the machined surface is the lowest sweep over each grid point.
SOLUTION  ``simulate_milling`` runs one pass with a compensation mode and returns a
          ``MillingRun`` (time series, surface grid, error statistics); ``CHAPTER_END_MILLING``
          and ``LUND_FACE_MILLING`` are the two scenarios.

The tool's own weight is left out of the arm's load: its deflection is constant along a short
cut and is taken up when the TCP is touched off with the tool mounted.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass
from typing import Literal

import numpy as np

from ..cell import (
    CONTROL_PERIOD_S,
    JointCompliance,
    Robot,
    ToolGravity,
    contact_reading,
    gravity_reading,
)
from ..errors import CancelledError, InvalidInputError
from ..transforms import make_transform, pose_error, rotation_about
from .compensation import (
    OnlineCompensationParams,
    OnlineCompensationState,
    compensate_targets_and_joints,
    online_compensation_step,
)
from .model import apply_twist, loaded_equilibrium
from .modes import (
    COMPENSATIONS,
    DEFAULT_OFFLINE_MODEL,
    Compensation,
    OfflineModel,
    variant_name,
)

ErrorMeasure = Literal["surface_depth", "path_lateral"]

# Grid on which the machined surface is evaluated [m].
SURFACE_STEP_ALONG_M = 0.0005
SURFACE_POINTS_ACROSS = 11
# Spacing of the program's robtargets along the cut for offline compensation [m].
TARGET_SPACING_M = 0.001
# Free travel before and after the block [m].
APPROACH_M = 0.005
# Engagement at or above which a step counts as stationary (the Lund paper's statistics).
STATIONARY_ENGAGEMENT = 0.999
# Newton IK along the path stops below these pose errors.
TRACK_TOLERANCE_M = 1e-10
TRACK_TOLERANCE_RAD = 1e-10


@dataclass(frozen=True)
class MillingScenario:
    """One straight milling pass over a rectangular block, tool pointing down.

    Attributes:
        name: Label for plots and summaries.
        block_length_m / block_width_m: Block size along / across the feed.
        depth_of_cut_m: Programmed depth below the block top.
        feed_speed_m_s: TCP speed along the cut.
        cutter_radius_m: Radius of the cutter's flat bottom.
        feed_force_N: Force against the feed at full engagement and nominal depth.
        cutting_force_N: Force across the feed, towards ``cutting_side`` (+1: left of the feed).
        normal_force_N: Force pushing the cutter up, away from the surface.
        feed_angle_deg: Feed direction in the base XY plane (0 = base +X).
        surface_center_m: Centre of the programmed machined surface in the base frame.
        lateral_offset_m: Cutter path offset from the block centre line (partial engagement).
        force_noise_rel: Standard deviation of white force noise, share of the nominal force.
        oscillation_rel / oscillation_hz: Sinusoidal force oscillation (share, frequency).
        error_measure: ``"surface_depth"`` (machined height error, the chapter) or
            ``"path_lateral"`` (TCP deviation across the feed in stationarity, the Lund paper).
    """

    name: str
    block_length_m: float = 0.150
    block_width_m: float = 0.050
    depth_of_cut_m: float = 0.003
    feed_speed_m_s: float = 0.020
    cutter_radius_m: float = 0.0375
    feed_force_N: float = 300.0
    cutting_force_N: float = 300.0
    normal_force_N: float = 50.0
    cutting_side: int = 1
    feed_angle_deg: float = 0.0
    surface_center_m: tuple[float, float, float] = (0.70, 0.10, 0.03)
    lateral_offset_m: float = 0.0
    force_noise_rel: float = 0.03
    oscillation_rel: float = 0.0
    oscillation_hz: float = 0.0
    error_measure: ErrorMeasure = "surface_depth"

    def __post_init__(self) -> None:
        sizes = (self.block_length_m, self.block_width_m, self.depth_of_cut_m)
        if min(sizes) <= 0 or self.feed_speed_m_s <= 0 or self.cutter_radius_m <= 0:
            raise InvalidInputError("block size, depth, feed speed and cutter radius must be > 0")
        if self.cutting_side not in (1, -1):
            raise InvalidInputError("cutting_side must be +1 or -1")
        if self.force_noise_rel < 0 or self.oscillation_rel < 0:
            raise InvalidInputError("force noise and oscillation must be >= 0")

    @property
    def feed_direction(self) -> np.ndarray:
        a = np.radians(self.feed_angle_deg)
        return np.array([np.cos(a), np.sin(a), 0.0])

    @property
    def cross_direction(self) -> np.ndarray:
        """Unit vector left of the feed in the base XY plane."""
        a = np.radians(self.feed_angle_deg)
        return np.array([-np.sin(a), np.cos(a), 0.0])

    @property
    def block_origin_m(self) -> np.ndarray:
        """Start of the block's centre line on the programmed surface, base frame."""
        return np.asarray(self.surface_center_m) - 0.5 * self.block_length_m * self.feed_direction

    def nominal_wrench(self) -> np.ndarray:
        """(6,) process wrench on the arm at full engagement and nominal depth, base axes."""
        f = (
            -self.feed_force_N * self.feed_direction
            + self.cutting_side * self.cutting_force_N * self.cross_direction
            + np.array([0.0, 0.0, self.normal_force_N])
        )
        return np.concatenate([f, np.zeros(3)])


# The chapter's aluminium block (Table 2). Feeding along base +X at the UR10 work pose, the
# feed force (-X) and the cutting force (+Y) both push the cutter into the part, as in the
# chapter's set-up; the normal force lifts it a little.
CHAPTER_END_MILLING = MillingScenario(name="chapter end milling, 6063 aluminium")
# The Lund paper's face milling in Al 7075: 1 mm depth, 50 N feed-force reference, a larger
# force across the feed (their Fig. 9), the robot oscillating during the cut.
LUND_FACE_MILLING = MillingScenario(
    name="Lund face milling, 7075 aluminium",
    block_length_m=0.100,
    block_width_m=0.016,
    depth_of_cut_m=0.001,
    feed_speed_m_s=0.010,
    cutter_radius_m=0.010,
    feed_force_N=50.0,
    cutting_force_N=150.0,
    normal_force_N=20.0,
    force_noise_rel=0.05,
    oscillation_rel=0.2,
    oscillation_hz=3.0,
    error_measure="path_lateral",
)


def engagement(scenario: MillingScenario, u_m: np.ndarray, v_m: float) -> np.ndarray:
    """Share of the block width the cutter's leading edge cuts, cutter centre at (u, v).

    u along the feed from the block start, v across from the centre line. A point across the
    block is cut when the leading arc u + sqrt(R^2 - (y - v)^2) lies on the block, [0, L].
    """
    u = np.atleast_1d(np.asarray(u_m, dtype=float))
    y = np.linspace(-0.5, 0.5, 101) * scenario.block_width_m
    dy = y - v_m
    R = scenario.cutter_radius_m
    inside = np.abs(dy) < R
    arc = np.sqrt(np.maximum(R**2 - dy**2, 0.0))
    lead = u[:, None] + arc[None, :]
    cutting = inside[None, :] & (lead >= 0.0) & (lead <= scenario.block_length_m)
    return cutting.mean(axis=1)


def predicted_wrenches(scenario: MillingScenario, u_m: np.ndarray) -> np.ndarray:
    """(n, 6) the process model's wrench at cutter positions ``u_m`` on the programmed path."""
    e = engagement(scenario, u_m, scenario.lateral_offset_m)
    return e[:, None] * scenario.nominal_wrench()[None, :]


@dataclass(frozen=True)
class MillingRun:
    """One simulated pass.

    Attributes:
        compensation: The compensation used (``modes.variant_name``: ``offline_linear``, ...).
        time_s: (n,) control-step times.
        position_nominal_m / position_actual_m: (n, 3) programmed and arm-side TCP positions.
        wrench: (n, 6) process wrench on the arm, base axes [N, N*m].
        engagement: (n,) share of the block width being cut.
        surface_u_m: (m,) grid positions along the block.
        surface_error_m: (m, k) machined-height error, positive = cut too deep, across the
            block in the second axis (``SURFACE_POINTS_ACROSS`` points).
        error_u_m / error_m: positions along the cut and the errors the statistics use
            (centre-line surface error, or the lateral path error in stationarity).
        error_max_m / error_std_m / error_mean_m: max |error|, standard deviation and mean.
    """

    compensation: str
    time_s: np.ndarray
    position_nominal_m: np.ndarray
    position_actual_m: np.ndarray
    wrench: np.ndarray
    engagement: np.ndarray
    surface_u_m: np.ndarray
    surface_error_m: np.ndarray
    error_u_m: np.ndarray
    error_m: np.ndarray
    error_max_m: float
    error_std_m: float
    error_mean_m: float


def _track_ik(robot: Robot, Ts: np.ndarray, q_start: np.ndarray) -> np.ndarray:
    """Joints along a finely sampled path, each pose solved (``Robot.ik``) from the last."""
    qs = np.empty((len(Ts), 6))
    q = q_start
    for i, T in enumerate(Ts):
        q = qs[i] = robot.ik(T, q, tolerance_m=TRACK_TOLERANCE_M, tolerance_rad=TRACK_TOLERANCE_RAD)
    return qs


def program_poses(scenario: MillingScenario, u_m: np.ndarray) -> np.ndarray:
    """(n, 4, 4) programmed TCP poses with the cutter centre at ``u_m`` along the cut."""
    R = rotation_about("z", np.radians(scenario.feed_angle_deg)) @ np.diag([1.0, -1.0, -1.0])
    origin = scenario.block_origin_m + scenario.lateral_offset_m * scenario.cross_direction
    return np.array([make_transform(R, origin + u * scenario.feed_direction) for u in u_m])


def _block_coordinates(scenario: MillingScenario, p: np.ndarray) -> np.ndarray:
    """(n, 3) positions as (u along feed, v across, h above the programmed surface)."""
    d = p - scenario.block_origin_m
    return np.stack([d @ scenario.feed_direction, d @ scenario.cross_direction, d[:, 2]], axis=1)


def _swept_surface(
    scenario: MillingScenario, p_tcp: np.ndarray, axis: np.ndarray
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Grid (u, v) and the lowest height the cutter bottom reached over each grid point."""
    u = np.arange(0.0, scenario.block_length_m + 1e-12, SURFACE_STEP_ALONG_M)
    v = np.linspace(-0.5, 0.5, SURFACE_POINTS_ACROSS) * scenario.block_width_m
    U, V = np.meshgrid(u, v, indexing="ij")
    gu, gv = U.reshape(-1), V.reshape(-1)
    height = np.full(gu.shape, scenario.depth_of_cut_m)
    c = _block_coordinates(scenario, p_tcp)
    n = np.stack(
        [axis @ scenario.feed_direction, axis @ scenario.cross_direction, axis[:, 2]], axis=1
    )
    R2 = scenario.cutter_radius_m**2
    for start in range(0, len(c), 400):
        cc, nn = c[start : start + 400], n[start : start + 400]
        du = gu[None, :] - cc[:, :1]
        dv = gv[None, :] - cc[:, 1:2]
        plane = cc[:, 2:3] - (nn[:, :1] * du + nn[:, 1:2] * dv) / nn[:, 2:3]
        plane = np.where(du**2 + dv**2 <= R2, plane, np.inf)
        height = np.minimum(height, plane.min(axis=0))
    return u, v, height.reshape(U.shape)


def simulate_milling(
    robot: Robot,
    scenario: MillingScenario,
    truth: JointCompliance,
    *,
    compensation: Compensation = "off",
    model: JointCompliance | None = None,
    offline_model: OfflineModel = DEFAULT_OFFLINE_MODEL,
    tool_gravity: ToolGravity | None = None,
    true_tool_gravity: ToolGravity | None = None,
    sensor_force_noise_N: float = 0.5,
    sensor_torque_noise_Nm: float = 0.03,
    seed: int = 0,
    progress: Callable[[float], None] | None = None,
    cancel: Callable[[], bool] | None = None,
) -> MillingRun:
    """Run one pass of ``scenario`` with a compensation mode.

    Args:
        robot: The arm with the spindle's TCP.
        scenario: The cut.
        truth: The simulator's joint stiffness (bends the arm).
        compensation: ``"off"``, ``"online"`` (chapter fig. 15, needs ``model`` and
            ``tool_gravity``) or ``"offline"`` (needs ``model``; targets every
            ``TARGET_SPACING_M`` corrected for the predicted wrench).
        model: Identified joint stiffness the controller uses.
        offline_model: The offline correction: ``"linear"`` or ``"nonlinear"`` (eq. 32).
        tool_gravity: Identified tool weight and sensor bias (online mode).
        true_tool_gravity: What the sensor really carries (defaults to ``tool_gravity``).
        sensor_force_noise_N / sensor_torque_noise_Nm: F/T noise per axis.
        seed: Seeds the process and sensor noise.
        progress: Called with the completed fraction.
        cancel: Polled each step; True stops the run with ``CancelledError``.
    """
    if compensation not in COMPENSATIONS:
        choices = ", ".join(COMPENSATIONS)
        raise InvalidInputError(f"unknown compensation {compensation!r}; choose one of {choices}")
    if compensation != "off" and model is None:
        raise InvalidInputError(f"compensation {compensation!r} needs an identified model")
    if compensation == "online" and tool_gravity is None:
        raise InvalidInputError("online compensation needs the identified tool gravity")
    rng = np.random.default_rng(seed)
    dt = CONTROL_PERIOD_S
    R_cut = scenario.cutter_radius_m
    u_start, u_end = -R_cut - APPROACH_M, scenario.block_length_m + R_cut + APPROACH_M
    n = int(np.ceil((u_end - u_start) / (scenario.feed_speed_m_s * dt))) + 1
    t = np.arange(n) * dt
    u_nominal = u_start + scenario.feed_speed_m_s * t
    Ts_nominal = program_poses(scenario, u_nominal)
    q_first = robot.ik(Ts_nominal[0])
    qs_nominal = _track_ik(robot, Ts_nominal, q_first)

    if compensation == "offline":
        assert model is not None  # checked above: every compensation but "off" needs one
        qs_command = _offline_command(
            robot, scenario, model, offline_model, (u_start, u_end), u_nominal, Ts_nominal,
            q_first, qs_nominal,
        )  # fmt: skip
    else:
        qs_command = qs_nominal

    true_tool = true_tool_gravity or tool_gravity or ToolGravity(2.5, (0.0, 0.0, 0.07))
    online = None
    if compensation == "online":
        assert model is not None and tool_gravity is not None  # checked above
        online = OnlineCompensationParams(model, tool_gravity)
    state = OnlineCompensationState()
    p_sensor_tcp = robot.T_flange_tcp[:3, 3]
    W_nominal = scenario.nominal_wrench()
    noise = rng.normal(0.0, scenario.force_noise_rel, n)
    oscillation = scenario.oscillation_rel * np.sin(2 * np.pi * scenario.oscillation_hz * t)
    sensor_noise = np.concatenate(
        [
            rng.normal(0.0, sensor_force_noise_N, (n, 3)),
            rng.normal(0.0, sensor_torque_noise_Nm, (n, 3)),
        ],
        axis=1,
    )
    R0 = robot.flange_pose(qs_command[0])[:3, :3].copy()
    reading = gravity_reading(R0, true_tool) + sensor_noise[0]
    W = np.zeros(6)
    position = np.empty((n, 3))
    axis = np.empty((n, 3))
    wrenches = np.empty((n, 6))
    engaged = np.empty(n)
    report_every = max(n // 50, 1)
    for k in range(n):
        if cancel is not None and cancel():
            raise CancelledError("milling simulation cancelled")
        q_cmd = qs_command[k]
        if online is not None:
            state, q_cmd = online_compensation_step(robot, state, q_cmd, reading, online, dt)
        # The chip the cutter meets depends on where the arm already is: predict the pose under
        # the last wrench, take the wrench there, then settle the arm under that wrench.
        predicted = loaded_equilibrium(robot, q_cmd, W, truth, mode="linear").T_base_tcp
        u, v, h = _block_coordinates(scenario, predicted[None, :3, 3])[0]
        depth_ratio = max(scenario.depth_of_cut_m - h, 0.0) / scenario.depth_of_cut_m
        engaged[k] = engagement(scenario, np.array([u]), v)[0]
        W = engaged[k] * depth_ratio * (1.0 + noise[k] + oscillation[k]) * W_nominal
        settled = loaded_equilibrium(robot, q_cmd, W, truth)
        T_actual = settled.T_base_tcp
        position[k] = T_actual[:3, 3]
        axis[k] = T_actual[:3, 2]
        wrenches[k] = W
        R_actual = robot.flange_pose(settled.joints_arm_rad)[:3, :3].copy()
        reading = (
            gravity_reading(R_actual, true_tool)
            + contact_reading(R_actual, p_sensor_tcp, W)
            + sensor_noise[k]
        )
        if progress is not None and (k % report_every == 0 or k == n - 1):
            progress((k + 1) / n)

    return _milling_run(
        scenario, variant_name(compensation, offline_model), t, u_nominal, Ts_nominal[:, :3, 3],
        position, axis, wrenches, engaged,
    )  # fmt: skip


def _offline_command(
    robot: Robot,
    scenario: MillingScenario,
    model: JointCompliance,
    offline_model: OfflineModel,
    u_range_m: tuple[float, float],
    u_nominal: np.ndarray,
    Ts_nominal: np.ndarray,
    q_first: np.ndarray,
    qs_nominal: np.ndarray,
) -> np.ndarray:
    """(n, 6) joints the offline-compensated program commands at each step: targets every
    ``TARGET_SPACING_M`` over ``u_range_m`` corrected for the predicted wrench (t_0 - C W, or
    the non-linear iteration of eq. 32), and MoveL between them, so the correction varies
    linearly between targets. The targets' joints are tracked from ``q_first`` (the seed of
    the nominal path's), the commanded ones from the nominal path's first joints."""
    u_start, u_end = u_range_m
    u_targets = np.arange(u_start, u_end + TARGET_SPACING_M, TARGET_SPACING_M)
    T_targets = program_poses(scenario, u_targets)
    q_targets = _track_ik(robot, T_targets, q_first)
    T_corrected, _ = compensate_targets_and_joints(
        robot, T_targets, q_targets, predicted_wrenches(scenario, u_targets), model, offline_model
    )
    twists = np.array([pose_error(a, b) for a, b in zip(T_targets, T_corrected, strict=True)])
    step_twists = np.stack(
        [np.interp(u_nominal, u_targets, twists[:, j]) for j in range(6)], axis=1
    )
    Ts_command = np.array([apply_twist(T, w) for T, w in zip(Ts_nominal, step_twists, strict=True)])
    return _track_ik(robot, Ts_command, qs_nominal[0])


def _milling_run(
    scenario: MillingScenario,
    compensation: str,
    t: np.ndarray,
    u_nominal: np.ndarray,
    p_nominal: np.ndarray,
    position: np.ndarray,
    axis: np.ndarray,
    wrenches: np.ndarray,
    engaged: np.ndarray,
) -> MillingRun:
    """The pass's ``MillingRun``: the surface the cutter swept and the error the scenario
    measures, the over-cut depth on the block's centre line (``surface_depth``, the
    statistics over the whole grid) or the path's lateral error where the cutter is
    stationary in the cut (``path_lateral``, the Lund paper's)."""
    surface_u, _, height = _swept_surface(scenario, position, axis)
    surface_error = -height
    if scenario.error_measure == "surface_depth":
        error_u = surface_u
        error = surface_error[:, SURFACE_POINTS_ACROSS // 2]
        stats = surface_error.reshape(-1)
    else:
        stationary = engaged >= STATIONARY_ENGAGEMENT
        deviation = (position - p_nominal) @ scenario.cross_direction
        error_u = u_nominal[stationary]
        error = deviation[stationary]
        stats = error
    return MillingRun(
        compensation=compensation,
        time_s=t,
        position_nominal_m=p_nominal.copy(),
        position_actual_m=position,
        wrench=wrenches,
        engagement=engaged,
        surface_u_m=surface_u,
        surface_error_m=surface_error,
        error_u_m=error_u,
        error_m=error,
        error_max_m=float(np.max(np.abs(stats))) if stats.size else 0.0,
        error_std_m=float(np.std(stats)) if stats.size else 0.0,
        error_mean_m=float(np.mean(stats)) if stats.size else 0.0,
    )
