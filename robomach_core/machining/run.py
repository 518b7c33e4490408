"""The machining run: the learned program cut on the simulated compliant arm (chapter section 2).

PROBLEM   Show, before the cell, what a program does to the part: how long the cut takes, where
          the force peaks, and how far the finished wall ends from the nominal one, with the
          feed controlled (CMRR, chapter section 4) and the deflection compensated (section 5).
STRATEGY  One 4 ms control period at a time along the program's MoveL path:
          - the depth met is the stock's allowance at the tool minus where the tool's edge is
            along the wall normal n: d = max(a(s) - h, 0), h from the previous period's force;
          - the process force lags towards F = K d^alpha f^beta (eqs. 3-6) at the robot's
            actual feed f, which follows the commanded feed through eq. (1);
          - the force acts on the tool along u = (n - rho t) / |n - rho t|: a normal component
            pushing the tool off the wall and a feed component (ratio rho) against the motion;
          - the arm bends by the simulator's TRUE joint compliance, q_arm = q_motor + Kq^-1 J^T F
            (joint_compliance, chapter eq. 16), i.e. the TCP moves by C F, C = J Kq^-1 J^T;
            only its normal part n^T C u F moves the cut;
          - the F/T sensor adds noise; CMRR filters it and sets the speed ratio that scales the
            programmed speed; online compensation shifts the joint reference by
            -Kq_hat^-1 J^T W_f (stiffness.online_compensation_step), offline compensation
            corrects the targets before the run (stiffness.compensate_targets_and_joints),
            both with a stiffness identified from a simulated CMM campaign, never the truth;
          - the finished wall is the envelope of the ball cutter over the tool positions, clipped
            by the stock (where the tool did not reach the stock surface the stock remains).
SOLUTION  ``run_machining`` returns a ``MachiningRun`` (trace, finished wall at stations,
          summary). The arm's Jacobians are evaluated once per target, so the 4 ms loop is
          scalar arithmetic: C varies over centimetres of path, the allowance over millimetres.

Modelling choices, stated: the TCP runs the MoveL chain through the targets at the move's
programmed speed (capped), with speed changes between moves ramped at the path acceleration;
zone blending at corners (a few tenths of a millimetre) is not modelled. The offline
compensation densifies the program to a target every ``offline_target_spacing_m`` (the
corrected program is ``MachiningRun.program``). The wall error is measured against the
program's own path (the nominal wall is that path moved back by the tool radius), so it shows
what the cut adds to the learning error, not the learning error itself.
"""

from __future__ import annotations

import functools
import math
import time
from collections.abc import Callable
from dataclasses import dataclass, replace
from typing import Any, Protocol

import numpy as np

from ..cmrr.controllers import ControlDesign, make_controller, settings_for
from ..cmrr.controllers.base import Measurement
from ..cmrr.feed_dynamics import FeedDynamics
from ..cmrr.process import ForceSensorModel, PowerLawForceModel
from ..joint_compliance import JointCompliance, true_joint_compliance
from ..postprocess import Targets
from ..robot import Robot
from ..stiffness import (
    CompensationSettings,
    StiffnessIdentification,
    compensate_targets_and_joints,
    identify_joint_stiffness,
    sample_workspace_joints,
    simulate_stiffness_measurements,
    sphere_tip_transform,
)
from ..transforms import make_transform, matrices_from_quaternions, quaternions_from_matrices
from .errors import CancelledError, MachiningSettingsError, SampleLimitError, StockError
from .path import arc_length_m, check_normals, check_path, path_tangents, wall_normals_from_path
from .settings import CONTROL_PERIOD_S, MachiningSettings
from .stock import Stock

MM = 1e-3
# Samples between two checks of the cancel flag.
CANCEL_CHECK_EVERY = 64
# Sensor noise is drawn this many samples at a time.
NOISE_BLOCK = 65_536
# Simulated time after a controller's protection stop before the run ends [s].
STOP_TAIL_S = 0.3
# The controllers are designed for the deepest cut, and no shallower than this [m].
DESIGN_DEPTH_MIN_M = 0.1 * MM
# The stock's path and the program's may differ in length by this much [m].
PATH_LENGTH_TOLERANCE_M = 1.0 * MM


class CancelFlag(Protocol):
    """Anything with ``is_set()``, e.g. ``threading.Event``."""

    def is_set(self) -> bool: ...


ProgressCallback = Callable[[float], None]
CompensationModel = JointCompliance | CompensationSettings


@dataclass(frozen=True, eq=False)
class MachiningTrace:
    """Per-sample signals, SI units, each shape (n,).

    ``force_N`` is the true process force; ``measured_force_N`` the raw sensor reading (noise
    added); ``deflection_m`` the arm's bending along the wall normal (positive: off the wall);
    ``tool_normal_m`` where the tool's edge is along the normal relative to the nominal wall
    (deflection, minus the compensation's shift); ``wall_error_m`` the finished wall at the
    tool's station (positive: material left, negative: overcut).
    """

    time_s: np.ndarray
    path_m: np.ndarray
    feed_m_s: np.ndarray
    commanded_feed_m_s: np.ndarray
    speed_ratio: np.ndarray
    depth_m: np.ndarray
    force_N: np.ndarray
    measured_force_N: np.ndarray
    reference_N: np.ndarray
    limit_N: np.ndarray
    deflection_m: np.ndarray
    tool_normal_m: np.ndarray
    wall_error_m: np.ndarray

    def __len__(self) -> int:
        return int(self.time_s.size)


@dataclass(frozen=True, eq=False)
class FinishedWall:
    """The wall after the cut at stations along the path, each shape (k,).

    Attributes:
        s_m: Arc length of the stations.
        allowance_m: The stock before the cut.
        finished_m: The wall after it, relative to the nominal wall along n.
    """

    s_m: np.ndarray
    allowance_m: np.ndarray
    finished_m: np.ndarray

    @property
    def error_m(self) -> np.ndarray:
        """Finished minus nominal [m]: positive material left, negative overcut."""
        return self.finished_m


@dataclass(frozen=True, eq=False)
class MachiningRun:
    """A finished run: settings, the program it executed, trace, finished wall and summary."""

    settings: MachiningSettings
    controller: str
    compensation: str
    program: Targets
    trace: MachiningTrace
    wall: FinishedWall
    summary: dict[str, Any]
    stiffness_model: JointCompliance | None


@functools.lru_cache(maxsize=8)
def identify_stiffness(
    robot_name: str, *, seed: int = 0, poses: int = 30, cmm_noise_m: float = 20e-6
) -> StiffnessIdentification:
    """Kq identified the chapter's way (section 5.2): a simulated CMM campaign under known loads
    at ``poses`` random poses, then eq. (23) by least squares. Seeded, so cached."""
    tip_robot = Robot(robot_name, sphere_tip_transform())
    joints = sample_workspace_joints(tip_robot, poses, seed=seed)
    data = simulate_stiffness_measurements(
        tip_robot, joints, true_joint_compliance(robot_name), cmm_noise_m=cmm_noise_m, seed=seed
    )
    return identify_joint_stiffness(tip_robot, data)


def _cancel_predicate(cancel: CancelFlag | Callable[[], bool] | None) -> Callable[[], bool] | None:
    if cancel is None:
        return None
    is_set = getattr(cancel, "is_set", None)
    if callable(is_set):
        return is_set
    if callable(cancel):
        return cancel
    raise TypeError("cancel must be a callable or have is_set()")


def force_directions(normals: np.ndarray, tangents: np.ndarray, feed_force_ratio: float):
    """(n, 3) unit direction of the process force on the tool: u = (n - rho t) / |n - rho t|."""
    u = normals - feed_force_ratio * tangents
    return u / np.linalg.norm(u, axis=1, keepdims=True)


def normal_compliance(
    robot: Robot,
    joints_rad: np.ndarray,
    normals: np.ndarray,
    directions: np.ndarray,
    model: JointCompliance,
) -> np.ndarray:
    """(n,) n^T C u [m/N]: how far along the wall normal the TCP moves per newton along u,
    C = J Kq^-1 J^T at each joint vector (chapter eq. 19, translational block)."""
    out = np.empty(len(joints_rad))
    for i, q in enumerate(np.asarray(joints_rad, dtype=float)):
        _, J = robot.fk_and_jacobian(q)
        out[i] = normals[i] @ model.cartesian_compliance(J)[:3, :3] @ directions[i]
    return out


def _program_poses(targets: Targets) -> np.ndarray:
    Rs = matrices_from_quaternions(np.asarray(targets.quaternion_wxyz, dtype=float))
    return np.array([make_transform(R, p) for R, p in zip(Rs, targets.position_m, strict=True)])


def densify_targets(targets: Targets, spacing_m: float) -> Targets:
    """Targets every ~``spacing_m`` along the MoveL path, positions and joints linear between
    the program's targets, orientation and speed of the move's end target."""
    s = arc_length_m(targets.position_m)
    grid = np.union1d(np.arange(0.0, s[-1], spacing_m), s)
    seg = np.clip(np.searchsorted(s, grid, side="left"), 1, len(s) - 1)
    pos = np.stack([np.interp(grid, s, targets.position_m[:, i]) for i in range(3)], axis=1)
    joints = np.stack([np.interp(grid, s, targets.joints_rad[:, i]) for i in range(6)], axis=1)
    return Targets(
        position_m=pos,
        quaternion_wxyz=np.asarray(targets.quaternion_wxyz)[seg],
        joints_rad=joints,
        speed_m_s=np.asarray(targets.speed_m_s)[seg],
        curvature_1_m=np.asarray(targets.curvature_1_m)[seg],
        sample_index=np.asarray(targets.sample_index)[seg],
    )


def planned_speed_profile(speed_m_s: np.ndarray, ds_m: float, acceleration_m_s2: float):
    """The path planner's speed along the stations: the programmed speeds with the speed
    changes between moves limited to ``acceleration_m_s2`` (v^2 <= v0^2 + 2 a ds forward, and
    the same backward so the robot slows before a slow move)."""
    v2 = np.asarray(speed_m_s, dtype=float) ** 2
    step = 2.0 * acceleration_m_s2 * ds_m
    out = v2.tolist()
    for i in range(1, len(out)):
        if out[i] > out[i - 1] + step:
            out[i] = out[i - 1] + step
    for i in range(len(out) - 2, -1, -1):
        if out[i] > out[i + 1] + step:
            out[i] = out[i + 1] + step
    return np.sqrt(np.asarray(out))


def start_feed_m_s(
    s_m: np.ndarray, plan_s_m: np.ndarray, plan_feed_m_s: np.ndarray, *, duration_s: float = 1.0
) -> np.ndarray:
    """Feed [m/s] at ``s_m`` of a robot leaving rest under the planned speeds, by eq. (1);
    beyond the first ``duration_s`` of the move, the plan itself."""
    model = FeedDynamics().discretize(CONTROL_PERIOD_S)
    x = model.initial_state()
    pos, feed = [0.0], [0.0]
    for _ in range(int(duration_s / CONTROL_PERIOD_S)):
        command = float(np.interp(x[-1], plan_s_m, plan_feed_m_s))
        x = model.step(x, command)
        if x[-1] <= pos[-1]:
            continue
        pos.append(float(x[-1]))
        feed.append(max(model.feed(x), 0.0))
    out = np.interp(s_m, pos, feed)
    beyond = np.asarray(s_m) > pos[-1]
    return np.where(beyond, np.interp(s_m, plan_s_m, plan_feed_m_s), out)


def steady_force_N(
    process: PowerLawForceModel, depth_m: np.ndarray, feed_m_s: np.ndarray
) -> np.ndarray:
    """Eq. (5) on arrays: K (d/1 mm)^alpha (f/1 mm/s)^beta, zero without depth or feed."""
    d = np.maximum(np.asarray(depth_m, dtype=float), 0.0) / MM
    f = np.maximum(np.asarray(feed_m_s, dtype=float), 0.0) / MM
    out = process.gain_N * d**process.depth_exponent * f**process.feed_exponent
    return np.where((d > 0.0) & (f > 0.0), out, 0.0)


def predicted_force_N(
    settings: MachiningSettings, depth_m: np.ndarray, planned_feed_m_s: np.ndarray
) -> np.ndarray:
    """The force the offline compensation plans for: eq. (5) at the stock depth and the planned
    feed, and no more than Fr where a CMRR controller will hold the force there."""
    process = settings.process
    f = steady_force_N(process, depth_m, planned_feed_m_s)
    if settings.controller != "constant":
        f = np.minimum(f, settings.reference_N)
    return f


def run_machining(
    robot: Robot,
    targets: Targets,
    wall_normals_m: np.ndarray | None,
    stock: Stock,
    settings: MachiningSettings,
    *,
    compensation_model: CompensationModel | None = None,
    progress: ProgressCallback | None = None,
    cancel: CancelFlag | Callable[[], bool] | None = None,
) -> MachiningRun:
    """Cut ``stock`` with the program ``targets`` on the compliant ``robot``.

    Args:
        robot: The arm with the machining tool's TCP; its name selects the true stiffness.
        targets: The program (positions, orientations, joints, per-target speeds).
        wall_normals_m: (m, 3) wall normals at the targets, pointing at the tool; None derives
            them from the path with the wall on the right of travel (built-in parts).
        stock: The part before machining along the same path.
        settings: Process, force limit, controller, compensation, seed.
        compensation_model: The identified stiffness (a ``JointCompliance`` or the ``model`` of
            ``CompensationSettings``); None identifies one with ``identify_stiffness`` when
            compensation is on.
        progress: Called with the fraction of the path done, about every 1 %.
        cancel: A flag (``is_set()``) or a callable; when true the run raises
            ``CancelledError``.

    Raises:
        StockError: the stock does not lie along the program's path.
        SampleLimitError: the run would record more than ``settings.max_samples`` samples.
    """
    started = time.perf_counter()
    cancelled = _cancel_predicate(cancel)
    P = check_path(targets.position_m)
    m = len(P)
    N = wall_normals_from_path(P) if wall_normals_m is None else check_normals(wall_normals_m, m)
    S = arc_length_m(P)
    L = float(S[-1])
    if abs(stock.path_length_m - L) > PATH_LENGTH_TOLERANCE_M:
        raise StockError(
            f"the stock lies along a {stock.path_length_m / MM:.1f} mm path, the program's is "
            f"{L / MM:.1f} mm long; build the stock on the program's path"
        )
    process: PowerLawForceModel = settings.process
    d_max = stock.max_allowance_m
    truth = true_joint_compliance(robot.name)
    model: JointCompliance | None = None
    if settings.compensation != "off":
        if compensation_model is None:
            model = identify_stiffness(
                robot.name,
                seed=settings.seed,
                poses=settings.identification_poses,
                cmm_noise_m=settings.cmm_noise_m,
            ).model
        elif isinstance(compensation_model, CompensationSettings):
            model = compensation_model.model
        elif isinstance(compensation_model, JointCompliance):
            model = compensation_model
        else:
            raise MachiningSettingsError("compensation_model must be a JointCompliance")

    # Along the program: force direction and normal compliance (true and identified).
    U = force_directions(N, path_tangents(P), settings.feed_force_ratio)
    c_true_t = normal_compliance(robot, targets.joints_rad, N, U, truth)
    c_hat_t = (
        normal_compliance(robot, targets.joints_rad, N, U, model) if model is not None else None
    )

    # Stations: allowance, programmed speed (the move's end target's), compliance.
    ds = settings.station_spacing_m
    n_st = int(math.floor(L / ds)) + 2
    s_st = np.arange(n_st) * ds
    allowance = stock.allowance_m(s_st)
    seg = np.clip(np.searchsorted(S, s_st, side="left"), 1, m - 1)
    v_prog = planned_speed_profile(
        np.minimum(np.asarray(targets.speed_m_s, dtype=float)[seg], settings.command_speed_cap_m_s),
        ds,
        settings.path_acceleration_m_s2,
    )
    if np.any(v_prog <= 0.0):
        raise MachiningSettingsError("every programmed speed must be positive")
    c_true = np.interp(s_st, S, c_true_t)
    c_hat = np.interp(s_st, S, c_hat_t) if c_hat_t is not None else np.zeros(n_st)

    constant_feed = (
        settings.constant_feed_m_s
        if settings.constant_feed_m_s is not None
        else settings.safe_constant_feed_m_s(d_max)
    )
    is_constant = settings.controller == "constant"

    # Offline compensation: corrected targets for the force planned from stock and feed.
    program = targets
    offset = np.zeros(n_st)  # commanded path's shift along n [m]
    if settings.compensation == "offline":
        assert model is not None
        dense = densify_targets(targets, settings.offline_target_spacing_m)
        s_d = arc_length_m(dense.position_m)
        v_d = np.interp(s_d, s_st, v_prog)
        planned = np.minimum(v_d, constant_feed) if is_constant else v_d
        # The robot starts the cut from rest: the plan follows eq. (1) out of it.
        planned = np.minimum(planned, start_feed_m_s(s_d, s_d, planned))
        f_pred = predicted_force_N(settings, stock.allowance_m(s_d), planned)
        n_d = np.stack([np.interp(s_d, S, N[:, i]) for i in range(3)], axis=1)
        n_d /= np.linalg.norm(n_d, axis=1, keepdims=True)
        u_d = np.stack([np.interp(s_d, S, U[:, i]) for i in range(3)], axis=1)
        u_d /= np.linalg.norm(u_d, axis=1, keepdims=True)
        wrenches = np.zeros((len(s_d), 6))
        wrenches[:, :3] = f_pred[:, None] * u_d
        Ts = _program_poses(dense)
        Ts_c, q_c = compensate_targets_and_joints(
            robot, Ts, dense.joints_rad, wrenches, model, "linear"
        )
        program = replace(
            dense,
            position_m=Ts_c[:, :3, 3].copy(),
            quaternion_wxyz=quaternions_from_matrices(Ts_c[:, :3, :3]),
            joints_rad=np.asarray(q_c),
        )
        shift = np.einsum("ij,ij->i", Ts_c[:, :3, 3] - Ts[:, :3, 3], n_d)
        offset = np.interp(s_st, s_d, shift)  # MoveL between corrected targets

    # Feed control.
    dt = CONTROL_PERIOD_S
    sensor = ForceSensorModel(
        noise_std_N=settings.sensor_noise_N, filter_cutoff_hz=settings.sensor_filter_cutoff_hz
    )
    sensor_filter = sensor.make_filter(dt)
    v_top = float(v_prog.max())
    design = ControlDesign(
        dt_s=dt,
        command_speed_m_s=v_top,
        reference_force_N=settings.reference_N,
        min_speed_ratio=settings.min_speed_ratio,
        nominal_force_gain_N=process.force_gain_N(max(d_max, DESIGN_DEPTH_MIN_M)),
        nominal_feed_exponent=process.feed_exponent,
        feed_dynamics=FeedDynamics(),
        measurement_filter=sensor_filter,
        control_delay_steps=1,
    )
    if is_constant:
        ctrl = None
    else:
        ctrl_settings = settings.controller_settings or settings_for(settings.controller)
        ctrl = make_controller(ctrl_settings, design)

    slowest = (
        float(np.min(np.minimum(v_prog, constant_feed)))
        if is_constant
        else settings.min_speed_ratio * float(v_prog.min())
    )
    worst = int(math.ceil(L / slowest / dt)) + 1
    if worst > settings.max_samples:
        raise SampleLimitError(
            f"this run could need {worst} samples ({worst * dt:.0f} s at the slowest feed "
            f"{slowest / MM:.2f} mm/s), more than the cap of {settings.max_samples}; raise "
            "max_samples, the speeds or the minimum speed ratio"
        )
    n_max = min(settings.max_samples, 2 * worst + int(STOP_TAIL_S / dt) + 2)

    robot_model = FeedDynamics().discretize(dt)
    if robot_model.a.shape != (4, 4) or len(sensor_filter.sos) != 1:
        raise MachiningSettingsError("the machining loop expects eq. (1) and a 2nd-order filter")
    rng = np.random.default_rng(settings.seed)
    noise: list[float] = []  # drawn in blocks as the cut goes (a stalled run may be long)

    # Hot-loop constants as plain floats and lists (scalar Python beats numpy at this size).
    inv_ds = 1.0 / ds
    last = n_st - 1
    a_l = allowance.tolist()
    v_l = v_prog.tolist()
    ct_l = c_true.tolist()
    ch_l = c_hat.tolist()
    off_l = offset.tolist()
    K = process.gain_N
    alpha_d, beta_f = process.depth_exponent, process.feed_exponent
    tau = process.time_constant_s
    lag = math.exp(-dt / tau) if tau > 0 else 0.0
    sigma = settings.sensor_noise_N
    online = settings.compensation == "online"
    tau_c = 1.0 / (2.0 * math.pi * settings.online_filter_cutoff_hz)
    alpha_c = dt / (dt + tau_c)  # the first-order filter of online_compensation_step
    fr = settings.reference_N

    rt: list[float] = []
    rs: list[float] = []
    rf: list[float] = []
    rcf: list[float] = []
    rr: list[float] = []
    rd: list[float] = []
    rF: list[float] = []
    rm: list[float] = []
    rdef: list[float] = []
    rh: list[float] = []
    force = 0.0
    w_f = 0.0
    filt = _FilterState.start(sensor_filter)
    x = _FeedState.start(robot_model)
    ctrl_state = ctrl.initial_state() if ctrl is not None else None
    first_ratio = ctrl.initial_speed_ratio if ctrl is not None else 1.0
    pending = [first_ratio]  # one period of control delay
    stop_time: float | None = None
    cycle_time: float | None = None
    next_progress = 0.0
    k = 0
    while True:
        if k >= n_max:
            raise SampleLimitError(
                f"the run did not finish within {n_max} samples ({n_max * dt:.0f} s); the feed "
                "stalled"
            )
        if cancelled is not None and k % CANCEL_CHECK_EVERY == 0 and cancelled():
            raise CancelledError(f"machining run {settings.controller} cancelled")
        t = k * dt
        s = x.position
        j = int(s * inv_ds)
        if j > last:
            j = last
        elif j < 0:
            j = 0
        feed = x.feed()
        deflection = ct_l[j] * force
        h = off_l[j] + deflection - ch_l[j] * w_f
        depth = a_l[j] - h
        if depth < 0.0:
            depth = 0.0
        if k % NOISE_BLOCK == 0:
            noise = rng.standard_normal(NOISE_BLOCK).tolist()
        raw = force + sigma * noise[k % NOISE_BLOCK]
        measured = filt.step(raw)
        if ctrl is not None:
            ctrl_state, out = ctrl.step(ctrl_state, Measurement(measured, feed))
            if out.stop and stop_time is None:
                stop_time = t
            pending.append(0.0 if stop_time is not None else out.speed_ratio)
            ratio = pending.pop(0)
            command = ratio * v_l[j]
        else:
            command = constant_feed if constant_feed < v_l[j] else v_l[j]
            ratio = command / v_l[j]
        if stop_time is not None:
            ratio = command = 0.0
        rt.append(t)
        rs.append(s)
        rf.append(feed)
        rcf.append(command)
        rr.append(ratio)
        rd.append(depth)
        rF.append(force)
        rm.append(raw)
        rdef.append(deflection)
        rh.append(h)
        k += 1
        if s >= L:
            cycle_time = t
            break
        if stop_time is not None and t - stop_time >= STOP_TAIL_S:
            break
        # Process force, eq. (3): exact first-order lag towards eq. (5) at this depth and feed.
        if depth > 0.0 and feed > 0.0:
            target = K * (depth * 1e3) ** alpha_d * (feed * 1e3) ** beta_f
        else:
            target = 0.0
        force = lag * force + (1.0 - lag) * target
        if online:
            w_f += alpha_c * (raw - w_f)
        x.step(command)  # the robot's feed, eq. (1)
        if progress is not None and s >= next_progress * L:
            progress(min(s / L, 1.0))
            next_progress = s / L + 0.01
    if progress is not None:
        progress(1.0)
    wall_s = time.perf_counter() - started

    names = (
        "time_s path_m feed_m_s commanded_feed_m_s speed_ratio depth_m force_N "
        "measured_force_N deflection_m tool_normal_m"
    ).split()
    columns = (rt, rs, rf, rcf, rr, rd, rF, rm, rdef, rh)
    arrays = {name: np.asarray(values) for name, values in zip(names, columns, strict=True)}
    wall = finished_wall(
        s_st, allowance, arrays["path_m"], arrays["tool_normal_m"], stock.tool_radius_m
    )
    station = np.clip(np.rint(arrays["path_m"] * inv_ds).astype(np.int64), 0, last)
    n = len(arrays["time_s"])
    trace = MachiningTrace(
        reference_N=np.full(n, fr),
        limit_N=np.full(n, settings.force_limit_N),
        wall_error_m=wall.error_m[station],
        **arrays,
    )
    summary = summarize(
        settings,
        trace,
        wall,
        v_prog=v_prog[station],
        cycle_time_s=cycle_time,
        stop_time_s=stop_time,
        constant_feed_m_s=constant_feed if is_constant else None,
        wall_time_s=wall_s,
        max_depth_m=d_max,
    )
    return MachiningRun(
        settings=settings,
        controller=settings.controller,
        compensation=settings.compensation,
        program=program,
        trace=trace,
        wall=wall,
        summary=summary,
        stiffness_model=model,
    )


class _FeedState:
    """Private scalar copy of ``DiscreteFeedModel.step`` for the 4-state eq. (1) (the hot loop);
    tests check it equals the public model."""

    __slots__ = ("a", "b", "c", "x0", "x1", "x2", "position")

    def __init__(self, a: list, b: list, c: list) -> None:
        self.a, self.b, self.c = a, b, c
        self.x0 = self.x1 = self.x2 = self.position = 0.0

    @classmethod
    def start(cls, model: Any) -> _FeedState:
        return cls(model.a.tolist(), model.b.tolist(), model.c.tolist())

    def feed(self) -> float:
        c = self.c
        return c[0] * self.x0 + c[1] * self.x1 + c[2] * self.x2 + c[3] * self.position

    def step(self, command: float) -> None:
        a, b = self.a, self.b
        x0, x1, x2, x3 = self.x0, self.x1, self.x2, self.position
        r0, r1, r2, r3 = a
        self.x0 = r0[0] * x0 + r0[1] * x1 + r0[2] * x2 + r0[3] * x3 + b[0] * command
        self.x1 = r1[0] * x0 + r1[1] * x1 + r1[2] * x2 + r1[3] * x3 + b[1] * command
        self.x2 = r2[0] * x0 + r2[1] * x1 + r2[2] * x2 + r2[3] * x3 + b[2] * command
        self.position = r3[0] * x0 + r3[1] * x1 + r3[2] * x2 + r3[3] * x3 + b[3] * command


class _FilterState:
    """Private scalar copy of ``LowPassFilter.step`` for one second-order section (the hot
    loop); tests check it equals the public filter."""

    __slots__ = ("b0", "b1", "b2", "a1", "a2", "z1", "z2")

    def __init__(self, sos_row: list, z: tuple[float, ...]) -> None:
        self.b0, self.b1, self.b2, _, self.a1, self.a2 = sos_row
        self.z1, self.z2 = z

    @classmethod
    def start(cls, lowpass: Any) -> _FilterState:
        return cls(lowpass.sos[0].tolist(), lowpass.initial_state())

    def step(self, x: float) -> float:
        out = self.b0 * x + self.z1
        self.z1 = self.b1 * x - self.a1 * out + self.z2
        self.z2 = self.b2 * x - self.a2 * out
        return out


def finished_wall(
    s_st: np.ndarray,
    allowance_m: np.ndarray,
    path_m: np.ndarray,
    tool_normal_m: np.ndarray,
    tool_radius_m: float,
) -> FinishedWall:
    """The wall the ball cutter leaves: at each station the lowest reach of the ball over the
    tool positions within one radius along the path, h + r - sqrt(r^2 - ds^2), clipped by the
    stock (where the tool never reached the stock surface the stock remains)."""
    ds = float(s_st[1] - s_st[0])
    n_st = len(s_st)
    idx = np.clip(np.rint(path_m / ds).astype(np.int64), 0, n_st - 1)
    reach = np.full(n_st, np.inf)
    np.minimum.at(reach, idx, tool_normal_m)
    envelope = reach.copy()
    r = tool_radius_m
    for shift in range(1, int(r / ds) + 1):
        rise = r - math.sqrt(max(r * r - (shift * ds) ** 2, 0.0))
        envelope[shift:] = np.minimum(envelope[shift:], reach[:-shift] + rise)
        envelope[:-shift] = np.minimum(envelope[:-shift], reach[shift:] + rise)
    return FinishedWall(s_st, allowance_m, np.minimum(allowance_m, envelope))


def summarize(
    settings: MachiningSettings,
    trace: MachiningTrace,
    wall: FinishedWall,
    *,
    v_prog: np.ndarray,
    cycle_time_s: float | None,
    stop_time_s: float | None,
    constant_feed_m_s: float | None,
    wall_time_s: float,
    max_depth_m: float,
) -> dict[str, Any]:
    """The figures of a run, units in the keys.

    ``force_rms_error_N`` is taken where the reference is binding: where the steady force at
    the programmed speed and the depth met would exceed Fr (CMRR must act there); elsewhere
    the force is below Fr at full programmed speed by design.
    """
    fr = settings.reference_N
    process = settings.process
    full_speed = steady_force_N(process, trace.depth_m, v_prog)
    binding = full_speed >= fr
    sel = binding if np.any(binding) else trace.depth_m > 0.0
    err = trace.force_N[sel] - fr
    e = wall.error_m
    i_max = int(np.argmax(np.abs(e)))
    removed = float(np.trapezoid(wall.allowance_m - wall.finished_m, wall.s_m))
    volume_mm3 = removed * settings.axial_engagement_m / MM**3
    sim_time = float(trace.time_s[-1]) if len(trace) else 0.0
    return {
        "controller": settings.controller,
        "compensation": settings.compensation,
        "completed": cycle_time_s is not None,
        "cycle_time_s": cycle_time_s,
        "stop_time_s": stop_time_s,
        "samples": len(trace),
        "path_length_mm": float(wall.s_m[-1]) / MM,
        "force_peak_N": float(np.max(trace.force_N)),
        "force_limit_N": settings.force_limit_N,
        "force_reference_N": fr,
        "force_rms_error_N": float(np.sqrt(np.mean(err**2))) if err.size else 0.0,
        "force_over_limit_fraction": float(np.mean(trace.force_N > settings.force_limit_N)),
        "wall_error_max_mm": float(abs(e[i_max])) / MM,
        "wall_error_max_at_path_mm": float(wall.s_m[i_max]) / MM,
        "wall_error_rms_mm": float(np.sqrt(np.mean(e**2))) / MM,
        "material_left_max_mm": max(0.0, float(e.max())) / MM,
        "overcut_max_mm": max(0.0, float(-e.min())) / MM,
        "deflection_max_mm": float(np.max(trace.deflection_m)) / MM,
        "depth_max_mm": max_depth_m / MM,
        "feed_mean_mm_s": float(np.mean(trace.feed_m_s)) / MM,
        "constant_feed_mm_s": None if constant_feed_m_s is None else constant_feed_m_s / MM,
        "removed_volume_mm3": volume_mm3,
        "mrr_mean_mm3_s": volume_mm3 / cycle_time_s if cycle_time_s else None,
        "sim_time_s": sim_time,
        "wall_time_s": wall_time_s,
        "realtime_factor": sim_time / wall_time_s if wall_time_s > 0 else None,
    }
