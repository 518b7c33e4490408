"""A cut prepared up to its loop: the stations along the stock's path and the feed control.

PROBLEM   Every cut of the machining run (``run.cut_program``, each rehearsal of the offline
          compensation, the UR program's feed loop in ``export.urscript_feed``) needs the same
          preparation before its 4 ms loop: where the program lies along the stock, the
          allowance, programmed speed and compliance at each station, a controller designed for
          this cut, and how many samples the loop may need.
STRATEGY  ``plan_cut`` computes it once per cut as a ``CutPlan`` (the loop's ``LoopInputs``,
          the controller and its kernel form); a rehearsal replaces only the program's offsets
          and the sensor-noise seed (``run.rehearsal_cut``).
SOLUTION  The stations every ``station_spacing_m`` carry a(s), the programmed speed ramped at
          the path acceleration, and n^T C u with C = J Kq^-1 J^T (chapter eq. 19) for the true
          stiffness and, for online compensation, the identified one; the controller is
          designed for the deepest cut at the top speed (``design``); the loop's constants are
          eq. (1) discretized and the force filter's second-order section (``run`` module
          docstring).
"""

from __future__ import annotations

import functools
import math
from dataclasses import dataclass
from typing import Any, Literal

import numpy as np

from ..cell import CONTROL_PERIOD_S, JointCompliance, Robot, true_joint_compliance
from ..cmrr.controllers import ControlDesign, make_controller
from ..cmrr.feed_dynamics import FeedDynamics
from ..cmrr.process import ForceSensorModel, PowerLawForceModel
from ..postprocess import Targets
from ..stiffness import CompensationSettings
from ..stiffness.identification import identify_stiffness
from ..transforms import arc_length_m
from ._loop import LoopInputs
from .compliance import (
    compliance_blocks,
    normal_compliance_along,
    path_directions,
    segment_tangents,
)
from .design import designed_controller_settings
from .errors import MachiningSettingsError, SampleLimitError, StockError
from .path import check_normals, check_path, project_onto_path
from .program import check_constant_feed, constant_feed_m_s, design_depth_m
from .settings import MachiningSettings
from .stock import Stock

MM = 1e-3

# Simulated time after a controller's protection stop before the run ends [s].
STOP_TAIL_S = 0.3
# The controllers are designed for the deepest cut, and no shallower than this [m].
DESIGN_DEPTH_MIN_M = 0.1 * MM
# The stock's path and the program's may differ in length (and lie apart) by this much [m].
PATH_LENGTH_TOLERANCE_M = 1.0 * MM
# The cell's force supervision stops the robot at this multiple of the force limit (the
# spindle's overload trip): a cut that runs away is stopped, not simulated to infinity.
FORCE_SUPERVISION_FACTOR = 2.0


CompensationModel = JointCompliance | CompensationSettings
# Where a cut's feed comes from: the settings' controller (constant feed or CMRR, online), or
# the program's own speeds, no feed control (a stage schedule planned offline).
FeedSource = Literal["controller", "program"]


def planned_speed_profile(speed_m_s: np.ndarray, ds_m: float, acceleration_m_s2: float):
    """The path planner's speed along the stations: the programmed speeds with the speed
    changes between moves limited to ``acceleration_m_s2`` (v^2 <= v0^2 + 2 a ds forward, and
    the same backward so the robot slows before a slow move)."""
    from ._kernel import speed_profile

    v2 = np.asarray(speed_m_s, dtype=float) ** 2
    return speed_profile(np.ascontiguousarray(v2), 2.0 * acceleration_m_s2 * ds_m)


def stiffness_model(
    robot_name: str, settings: MachiningSettings, given: CompensationModel | None = None
) -> JointCompliance:
    """The stiffness the compensation uses: ``given`` (a ``JointCompliance`` or the ``model`` of
    ``CompensationSettings``), else the one the CMM campaign identifies on the arm with the
    settings' seed, poses and noise (``stiffness.identification.identify_stiffness``)."""
    if given is None:
        return identify_stiffness(
            robot_name,
            seed=settings.seed,
            poses=settings.identification_poses,
            cmm_noise_m=settings.cmm_noise_m,
        ).model
    if isinstance(given, CompensationSettings):
        return given.model
    if isinstance(given, JointCompliance):
        return given
    raise MachiningSettingsError("compensation_model must be a JointCompliance")


def _resolve_model(
    robot: Robot, settings: MachiningSettings, compensation_model: CompensationModel | None
) -> JointCompliance | None:
    if settings.compensation == "off":
        return None
    return stiffness_model(robot.name, settings, compensation_model)


@dataclass(frozen=True, eq=False)
class CutPlan:
    """A cut prepared up to its loop: the stations along the stock's path and the controller.

    Attributes:
        settings, stock: as ``cut_program`` takes them.
        s_st: (n_st,) arc length of the stations [m].
        inputs: the loop's inputs (``_loop.LoopInputs``), the program's offset included.
        ctrl_settings: the controller's settings as designed for this cut (None: constant).
        controller: the controller (None: constant feed); ``packed`` its kernel form.
        constant_feed_m_s: the constant feed (None for a CMRR controller).
        d_max: the deepest cut the program is designed for [m] (``program.design_depth_m``);
            ``model`` the identified stiffness the online compensation uses (None without).
        feed: where the feed comes from (``FeedSource``): ``"program"`` runs the program's
            speeds with no feed control (``controller`` None).
    """

    settings: MachiningSettings
    stock: Stock
    s_st: np.ndarray
    inputs: Any
    ctrl_settings: Any
    controller: Any
    packed: Any
    constant_feed_m_s: float | None
    d_max: float
    model: JointCompliance | None
    feed: FeedSource = "controller"


def _program_offsets(
    targets: Targets, stock: Stock, nominal: Targets | None
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(s_t, offset_t, lateral_t) of the program's targets along the stock's path: paired one
    for one with ``nominal`` when given, else by projection (``cut_program``)."""
    P = check_path(targets.position_m)
    m = len(P)
    if nominal is not None:
        P0 = check_path(nominal.position_m)
        if P0.shape != P.shape:
            raise StockError(
                f"the program has {m} targets, its nominal program {len(P0)}: they must pair"
            )
        s_t, _, lateral = project_onto_path(P0, stock.path_points_m, stock.wall_normals_m)
        n_t = _normals_at(stock, s_t)
        return s_t, np.einsum("ij,ij->i", P - P0, n_t), lateral
    return project_onto_path(P, stock.path_points_m, stock.wall_normals_m)


def _station_directions(
    stock: Stock,
    s_st: np.ndarray,
    s_t: np.ndarray,
    wall_normals_m: np.ndarray | None,
    feed_force_ratio: float,
) -> tuple[np.ndarray, np.ndarray]:
    """(n, u) at the stations: the wall normal (the stock's, or ``wall_normals_m`` given at the
    program's targets at ``s_t``) and the process force's direction with the stock's path
    tangent (``compliance.path_directions``)."""
    if wall_normals_m is None:
        return path_directions(stock.path_points_m, stock.wall_normals_m, s_st, feed_force_ratio)
    given = check_normals(wall_normals_m, len(s_t))
    n = np.stack([np.interp(s_st, s_t, given[:, i]) for i in range(3)], axis=1)
    n /= np.linalg.norm(n, axis=1, keepdims=True)
    u = n - feed_force_ratio * segment_tangents(stock.path_points_m, s_st)
    return n, u / np.linalg.norm(u, axis=1, keepdims=True)


def _normals_at(stock: Stock, s_m: np.ndarray) -> np.ndarray:
    """(k, 3) unit wall normals of the stock at arc lengths ``s_m``."""
    n = np.stack([np.interp(s_m, stock.path_s_m, stock.wall_normals_m[:, i]) for i in range(3)], 1)
    return n / np.linalg.norm(n, axis=1, keepdims=True)


def _feed_plan(
    settings: MachiningSettings,
    d_max: float,
    v_prog: np.ndarray,
    c_true: np.ndarray,
    sensor_filter: Any,
    feed: FeedSource,
) -> tuple[bool, float, Any, Any, float]:
    """Where the cut's feed comes from: (the constant feed is run, that feed (inf when the
    programmed speeds run: a CMRR controller or a schedule planned offline), the controller's
    settings and the controller (None, None without one), a typical feed [m/s] for the
    recording's first size)."""
    scheduled = feed == "program"
    is_constant = settings.controller == "constant" and not scheduled
    constant_feed = constant_feed_m_s(settings, d_max) if not scheduled else math.inf
    if is_constant:
        check_constant_feed(settings, d_max)
    ctrl_settings, ctrl = (
        (None, None) if scheduled else _feed_control(settings, d_max, v_prog, c_true, sensor_filter)
    )
    typical = (
        float(np.mean(np.minimum(v_prog, constant_feed)))
        if ctrl is None
        else 0.5 * float(np.mean(v_prog))
    )
    return is_constant, constant_feed, ctrl_settings, ctrl, typical


def _slowest(
    settings: MachiningSettings, v_prog: np.ndarray, constant_feed: float, ctrl: Any
) -> float:
    """The slowest feed the cut may run [m/s]: the program's (or the constant feed) without a
    controller, the least speed ratio of the slowest move with one."""
    if ctrl is None:
        return float(np.min(np.minimum(v_prog, constant_feed)))
    return settings.min_speed_ratio * float(v_prog.min())


def plan_cut(
    robot: Robot,
    targets: Targets,
    wall_normals_m: np.ndarray | None,
    stock: Stock,
    settings: MachiningSettings,
    *,
    model: JointCompliance | None = None,
    nominal: Targets | None = None,
    feed: FeedSource = "controller",
) -> CutPlan:
    """Everything ``cut_program`` computes before its loop (its docstring); ``feed``
    ``"program"`` runs the program's own speeds (a stage schedule planned offline,
    ``machining.schedule``) with no feed control, ``"controller"`` the settings'
    controller."""
    P = check_path(targets.position_m)
    m = len(P)
    s_t, off_t, lateral = _program_offsets(targets, stock, nominal)
    L = stock.path_length_m
    _check_along(stock, arc_length_m(P if nominal is None else nominal.position_m)[-1], lateral)
    process: PowerLawForceModel = settings.process
    d_max = design_depth_m(settings, stock.max_allowance_m)
    truth = true_joint_compliance(robot.name)
    online = settings.compensation == "online"
    if online and model is None:
        model = _resolve_model(robot, settings, None)

    # Stations along the stock's path: allowance, programmed speed (the move's end target's),
    # the normal compliance (true and identified; ``compliance``), and the program's offset
    # from the path (MoveL between its targets).
    ds = settings.station_spacing_m
    n_st = int(math.floor(L / ds)) + 2
    s_st = np.arange(n_st) * ds
    allowance = stock.allowance_m(s_st)
    seg = np.clip(np.searchsorted(s_t, s_st, side="left"), 1, m - 1)
    v_prog = planned_speed_profile(
        np.minimum(np.asarray(targets.speed_m_s, dtype=float)[seg], settings.command_speed_cap_m_s),
        ds,
        settings.path_acceleration_m_s2,
    )
    if not np.all(v_prog > 0.0):
        raise MachiningSettingsError("every programmed speed must be positive")
    N_st, U_st = _station_directions(stock, s_st, s_t, wall_normals_m, settings.feed_force_ratio)
    # The arm's pose along the path: a corrected program's nominal joints (a correction moves
    # them by micro-radians; the compliance does not change with it).
    joints = (targets if nominal is None else nominal).joints_rad
    c_true = normal_compliance_along(s_t, compliance_blocks(robot, joints, truth), s_st, N_st, U_st)
    c_hat = np.zeros(n_st)
    if online:
        assert model is not None  # resolved above: online compensation has a model
        c_hat = normal_compliance_along(
            s_t, compliance_blocks(robot, joints, model), s_st, N_st, U_st
        )
    offset = np.interp(s_st, s_t, off_t)
    dt = CONTROL_PERIOD_S
    sensor_filter = _sensor_filter(settings.sensor_filter_cutoff_hz, dt)
    is_constant, constant_feed, ctrl_settings, ctrl, typical_feed = _feed_plan(
        settings, d_max, v_prog, c_true, sensor_filter, feed
    )
    n_max = _sample_budget(settings, L, _slowest(settings, v_prog, constant_feed, ctrl), dt)

    robot_model = _feed_model(dt)
    if robot_model.a.shape != (4, 4) or len(sensor_filter.sos) != 1:
        raise MachiningSettingsError("the machining loop expects eq. (1) and a 2nd-order filter")
    tau = process.time_constant_s
    tau_c = 1.0 / (2.0 * math.pi * settings.online_filter_cutoff_hz)
    inputs = LoopInputs(
        allowance=allowance,
        v_prog=v_prog,
        c_true=c_true,
        c_hat=c_hat,
        offset=offset,
        ds=ds,
        length=L,
        dt=dt,
        constant_feed=float(constant_feed) if is_constant else math.inf,
        # The stock's material: its coefficient scales K of the process the controller was
        # designed for.
        gain_K=process.gain_N * stock.material_factor,
        alpha_d=process.depth_exponent,
        beta_f=process.feed_exponent,
        lag=math.exp(-dt / tau) if tau > 0 else 0.0,
        sigma=settings.sensor_noise_N,
        filt=np.ascontiguousarray(sensor_filter.sos[0], dtype=float),
        filt_z=np.asarray(sensor_filter.initial_state(), dtype=float),
        feed_a=np.ascontiguousarray(robot_model.a, dtype=float),
        feed_b=np.ascontiguousarray(robot_model.b, dtype=float),
        feed_c=np.ascontiguousarray(robot_model.c, dtype=float),
        online=online,
        alpha_c=dt / (dt + tau_c),  # the first-order filter of online_compensation_step
        supervision_N=FORCE_SUPERVISION_FACTOR * settings.force_limit_N,
        stop_tail_s=STOP_TAIL_S,
        n_max=n_max,
        capacity=int(min(n_max, max(4096, 1.3 * L / max(typical_feed, 1e-9) / dt))),
        seed=settings.seed,
    )
    return CutPlan(
        settings=settings,
        stock=stock,
        s_st=s_st,
        inputs=inputs,
        ctrl_settings=ctrl_settings,
        controller=ctrl,
        packed=_packed(ctrl),
        constant_feed_m_s=float(constant_feed) if is_constant else None,
        d_max=d_max,
        model=model if online else None,
        feed=feed,
    )


def _check_along(stock: Stock, own_length_m: float, lateral_m: np.ndarray) -> None:
    """Refuse a program that does not run along the stock's path: its length (``own_length_m``,
    its nominal's for a corrected program) differs from the path's by more than
    ``PATH_LENGTH_TOLERANCE_M`` or 1 %, or a target lies more than that beside it."""
    L = stock.path_length_m
    own = own_length_m
    if float(np.max(lateral_m)) > PATH_LENGTH_TOLERANCE_M or abs(own - L) > max(
        PATH_LENGTH_TOLERANCE_M, 0.01 * L
    ):
        raise StockError(
            f"the stock lies along a {L / MM:.1f} mm path, the program's is {own / MM:.1f} mm "
            f"long and up to {float(np.max(lateral_m)) / MM:.1f} mm beside it; build the stock "
            "on the program's path"
        )


def _feed_control(
    settings: MachiningSettings,
    d_max: float,
    v_prog: np.ndarray,
    c_true: np.ndarray,
    sensor_filter: Any,
) -> tuple[Any, Any]:
    """The feed control designed for this cut (``design``): the controller's settings and the
    controller, None and None for constant feed. It is designed for the deepest cut ``d_max``
    (no shallower than ``DESIGN_DEPTH_MIN_M``) at the top programmed speed, with the
    interaction stiffness 1 / mean(n^T C u) of the true arm along the path, eq. (1) as the
    robot's feed dynamics and one period of control delay."""
    process: PowerLawForceModel = settings.process
    v_top = float(v_prog.max())
    ctrl_settings = designed_controller_settings(
        settings,
        max_depth_m=d_max,
        speed_m_s=v_top,
        interaction_stiffness_N_m=1.0 / float(np.mean(c_true)) if np.all(c_true > 0) else None,
    )
    design = ControlDesign(
        dt_s=CONTROL_PERIOD_S,
        command_speed_m_s=v_top,
        reference_force_N=settings.reference_N,
        min_speed_ratio=settings.min_speed_ratio,
        nominal_force_gain_N=process.force_gain_N(max(d_max, DESIGN_DEPTH_MIN_M)),
        nominal_feed_exponent=process.feed_exponent,
        feed_dynamics=FeedDynamics(),
        measurement_filter=sensor_filter,
        control_delay_steps=1,
    )
    ctrl = None if ctrl_settings is None else make_controller(ctrl_settings, design)
    return ctrl_settings, ctrl


def _sample_budget(
    settings: MachiningSettings, length_m: float, slowest_m_s: float, dt: float
) -> int:
    """The loop's sample cap: twice the samples the whole path takes at the slowest feed (a
    CMRR controller's minimum ratio of the slowest programmed speed, or the constant feed),
    plus the tail after a stop, within ``settings.max_samples``.

    Raises:
        SampleLimitError: the path at the slowest feed alone needs more than
            ``settings.max_samples``.
    """
    worst = int(math.ceil(length_m / slowest_m_s / dt)) + 1
    if worst > settings.max_samples:
        raise SampleLimitError(
            f"this run could need {worst} samples ({worst * dt:.0f} s at the slowest feed "
            f"{slowest_m_s / MM:.2f} mm/s), more than the cap of {settings.max_samples}; raise "
            "max_samples, the speeds or the minimum speed ratio"
        )
    return min(settings.max_samples, 2 * worst + int(STOP_TAIL_S / dt) + 2)


@functools.lru_cache(maxsize=16)
def _sensor_filter(cutoff_hz: float, dt_s: float) -> Any:
    """The CMRR feedback's low-pass filter (one design per setting in this process)."""
    return ForceSensorModel(filter_cutoff_hz=cutoff_hz).make_filter(dt_s)


@functools.lru_cache(maxsize=4)
def _feed_model(dt_s: float) -> Any:
    """Eq. (1) discretized at ``dt_s`` with the path position (one per period here)."""
    return FeedDynamics().discretize(dt_s)


def _packed(ctrl: Any) -> Any:
    """The kernel form of ``ctrl`` (``_kernel.pack_controller``); an adaptive LQ's is shared by
    every cut of this process that designs the same controller, so its table of LQ designs
    grows once."""
    from ..cmrr.controllers import AdaptiveLqController
    from ._kernel import pack_controller

    if not isinstance(ctrl, AdaptiveLqController):
        return pack_controller(ctrl)
    d = ctrl.design
    filt = d.measurement_filter
    key = (
        ctrl.settings, ctrl.kf, ctrl.df0, ctrl.vr_mm_s, d.reference_force_N, d.dt_s,
        d.control_delay_steps, d.min_speed_ratio, d.feed_dynamics,
        None if filt is None else filt.sos.tobytes(),
    )  # fmt: skip
    packed = _LQ_TABLES.get(key)
    if packed is None:
        packed = pack_controller(ctrl)
        if len(_LQ_TABLES) >= 64:
            _LQ_TABLES.pop(next(iter(_LQ_TABLES)))
        _LQ_TABLES[key] = packed
    return packed


# Adaptive LQ controllers packed in this process, by their design: their tables of LQ designs
# grow as cuts meet new Df values, and serve every later cut with the same design.
_LQ_TABLES: dict[tuple, Any] = {}
