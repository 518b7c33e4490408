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
            programmed speed (each controller designed for this cut, ``design``); online
            compensation shifts the joint reference by -Kq_hat^-1 J^T W_f
            (stiffness.online_compensation_step); offline compensation corrects the targets
            before the run, planned from rehearsals of the same cut (``offline``), both with a
            stiffness identified from a simulated CMM campaign, never the truth;
          - the program runs along the stock's path: its offset from that path along n (a
            corrected program, a program read back from an exported file) moves the cut;
          - eq. (1) is non-minimum phase (it dips before it rises); the path interpolator never
            runs the TCP backwards, so the feed is held at zero where the dip would reverse it;
          - the cell's force supervision stops the robot at twice the force limit;
          - the finished wall is the envelope of the ball cutter over the tool positions, clipped
            by the stock (where the tool did not reach the stock surface the stock remains).
SOLUTION  ``run_machining`` returns a ``MachiningRun`` (trace, finished wall at stations,
          summary). The arm's Jacobians are evaluated once per target, so the 4 ms loop is
          scalar arithmetic: C varies over centimetres of path, the allowance over millimetres.
          Each cut is prepared by ``plan_cut`` (``_plan``: the stations, the controller
          designed for the cut, the sample budget) and run by ``cut_planned``.

Modelling choices, stated: the TCP runs the MoveL chain through the targets at the move's
programmed speed (capped), with speed changes between moves ramped at the path acceleration;
zone blending at corners (a few tenths of a millimetre) is not modelled. The offline
compensation densifies the program to a target every ``offline_target_spacing_m`` (the
corrected program is ``MachiningRun.program``). The stock's ``material_factor`` scales the
process gain K the controllers were designed for (a harder or softer casting). The wall error
is measured against the program's own path (the nominal wall is that path moved back by the
tool radius), so it shows what the cut adds to the learning error, not the learning error
itself.
"""

from __future__ import annotations

import math
import time
from collections.abc import Callable
from dataclasses import dataclass, replace
from typing import Any

import numpy as np

from ..cell import CONTROL_PERIOD_S, JointCompliance, Robot
from ..cmrr.feed_dynamics import FeedDynamics
from ..cmrr.simulation import CancelFlag as CancelFlag
from ..cmrr.simulation import ProgressCallback as ProgressCallback
from ..cmrr.simulation import cancel_predicate
from ..postprocess import Targets
from ..stiffness.identification import identify_stiffness as identify_stiffness
from ..stiffness.model import cartesian_compliance
from ..transforms import arc_length_m
from ._loop import _Diverged, run_loop
from ._plan import FORCE_SUPERVISION_FACTOR as FORCE_SUPERVISION_FACTOR
from ._plan import CompensationModel as CompensationModel
from ._plan import CutPlan as CutPlan
from ._plan import FeedSource as FeedSource
from ._plan import _resolve_model
from ._plan import plan_cut as plan_cut
from ._plan import planned_speed_profile as planned_speed_profile
from ._plan import stiffness_model as stiffness_model
from .compliance import (
    compliance_blocks,
    normal_compliance_along,
    path_directions,
)
from .errors import MachiningSettingsError
from .offline import densify_targets as densify_targets
from .path import check_path, project_onto_path
from .program import (
    as_written,
    design_depth_m,
    machining_program,
)
from .schedule import (
    SCHEDULE_DRAWS,
    STAGED_CONTROLLERS,
    draw_stages,
    scheduled_program,
    switches,
)
from .settings import MachiningSettings
from .stock import Stock
from .summary import FinishedWall as FinishedWall
from .summary import MachiningTrace as MachiningTrace
from .summary import finished_wall as finished_wall
from .summary import steady_force_N as steady_force_N
from .summary import summarize

MM = 1e-3


@dataclass(frozen=True, eq=False)
class MachiningRun:
    """A finished run: settings, the program it executed, trace, finished wall and summary;
    ``controller_settings`` the controller as designed for the cut (None: constant feed);
    ``nominal`` the nominal targets an offline-corrected ``program`` pairs with."""

    settings: MachiningSettings
    controller: str
    compensation: str
    program: Targets
    trace: MachiningTrace
    wall: FinishedWall
    summary: dict[str, Any]
    stiffness_model: JointCompliance | None
    controller_settings: Any = None
    nominal: Targets | None = None


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
        out[i] = normals[i] @ cartesian_compliance(robot, q, model)[:3, :3] @ directions[i]
    return out


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


def predicted_force_N(
    settings: MachiningSettings, depth_m: np.ndarray, planned_feed_m_s: np.ndarray
) -> np.ndarray:
    """The first plan of the offline compensation when no rehearsal is at hand: eq. (5) at the
    stock depth and the planned feed, and no more than Fr where a CMRR controller will hold
    the force there."""
    f = steady_force_N(settings.process, depth_m, planned_feed_m_s)
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
    nominal: Targets | None = None,
    program_frame: np.ndarray | None = None,
) -> MachiningRun:
    """Cut ``stock`` with the program ``targets`` on the compliant ``robot``.

    Args:
        robot: The arm with the machining tool's TCP; its name selects the true stiffness.
        targets: The program (positions, orientations, joints, per-target speeds). It runs
            along the stock's path; a program off that path (a corrected one, or one read back
            from an exported file) cuts where its targets are.
        wall_normals_m: (m, 3) wall normals at the targets, pointing at the tool; None takes
            the stock's.
        stock: The part before machining along the program's path.
        settings: Process, force limit, controller, compensation, seed.
        compensation_model: The identified stiffness (a ``JointCompliance`` or the ``model`` of
            ``CompensationSettings``); None identifies one with ``identify_stiffness`` when
            compensation is on.
        progress: Called with the fraction of the path done, about every 1 %.
        cancel: A flag (``is_set()``) or a callable; when true the run raises
            ``CancelledError``.
        nominal: The nominal targets ``targets`` correct one for one (``cut_program``).
        program_frame: The work object ``T_base_wobj`` the program files write positions in:
            the program (and an offline-corrected one) is cut with its positions as written
            (``program.as_written``); None cuts them as given.

    Raises:
        StockError: the stock does not lie along the program's path.
        SampleLimitError: the run would record more than ``settings.max_samples`` samples.
        MachiningSettingsError: no feed keeps the force limit, or the cut diverged.
    """
    from .offline import force_met_N, offline_compensated_run

    model = _resolve_model(robot, settings, compensation_model)
    # The program this configuration runs, and every exporter writes (``program``).
    targets = as_written(
        machining_program(
            targets, settings, design_depth_m=design_depth_m(settings, stock.max_allowance_m)
        ),
        program_frame,
    )
    if settings.compensation != "offline":
        return cut_program(
            robot, targets, wall_normals_m, stock, settings,
            model=model, progress=progress, cancel=cancel, nominal=nominal,
        )  # fmt: skip
    started = time.perf_counter()
    assert model is not None
    s_f, n_f, u_f, c_hat = _stations(robot, targets, stock, settings, model)
    # Every rehearsal cuts the nominal program's plan with the planned correction's offsets;
    # the last cut is the corrected program itself (what the export carries). The first plan
    # is the force of the cut a working compensation meets: the tool on the nominal wall, the
    # full allowance cut (``offline``); each rehearsal's force met, the least at each station
    # (``offline.force_met_N``), plans the next.
    plan = plan_cut(robot, targets, None, stock, settings)
    on_the_wall = replace(
        plan, inputs=replace(plan.inputs, c_true=np.zeros_like(plan.inputs.c_true))
    )
    # Each rehearsal, this one number 0, cuts on its own sensor-noise draw, never the
    # settings' seed: the corrected program's cut (the table's row) meets the settings' draw,
    # as a cell meets a draw no rehearsal saw (``offline`` LIMIT).
    ideal = rehearsal_cut(
        on_the_wall, np.zeros_like(plan.inputs.offset), cancel,
        seed=rehearsal_seed(settings.seed, 0),
    )  # fmt: skip
    # With ``stages`` "planned", a staged controller's stages are planned here, not switched
    # in the cell's cut (``schedule``); its program, plan and nominal wall's cut replace these.
    # ``numbered``: the rehearsal numbers (noise draws) past 0 that planning used.
    stages, numbered = _planned_stages(robot, targets, stock, settings, on_the_wall, ideal, cancel)
    feed: FeedSource = "controller"
    if stages is not None:
        targets, plan, ideal, feed = stages.targets, stages.plan, stages.ideal, "program"
    first = (
        force_met_N(ideal, s_f)
        if ideal.summary["completed"]
        else _first_plan(settings, stock, targets, s_f)
    )

    def rehearse(offset_st: np.ndarray, number: int) -> Rehearsal:
        return rehearsal_cut(
            plan, offset_st, cancel, seed=rehearsal_seed(settings.seed, numbered + number)
        )

    def cut(program: Targets, dense: Targets) -> MachiningRun:
        return cut_program(
            robot, as_written(program, program_frame), None, stock, settings, model=None,
            cancel=cancel, compensation_model_for_record=model, nominal=dense, feed=feed,
        )  # fmt: skip

    run, program, dense, rehearsals, change = offline_compensated_run(
        rehearse, cut, robot, targets, s_f, plan.s_st, c_hat, n_f, u_f, first,
        model=model, progress=progress,
    )  # fmt: skip
    summary = dict(run.summary)
    summary["rehearsals"] = rehearsals
    summary["offline_last_change_um"] = None if not math.isfinite(change) else change / 1e-6
    summary["offline_targets"] = len(program)
    # Whether the cut of the nominal wall itself (the arm held rigid, the first plan's force)
    # completes: where it stops (a staged controller's protection rule on a burr the yielding
    # arm rode over), no correction reaches the nominal wall under this controller, and the
    # offline row stops for the stock's sake, not the compensation's.
    summary["offline_nominal_wall_completed"] = bool(ideal.summary["completed"])
    summary["schedule_draws"] = None
    if stages is not None:
        run = _with_schedule(run, summary, stages, on_the_wall)
    wall_s = time.perf_counter() - started
    summary["wall_time_s"] = wall_s
    summary["realtime_factor"] = summary["sim_time_s"] / wall_s if wall_s > 0 else None
    return replace(run, program=program, nominal=dense, summary=summary)


def _stations(
    robot: Robot, targets: Targets, stock: Stock, settings: MachiningSettings, model: Any
) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """Where offline compensation plans: stations every ``station_spacing_m`` along the
    program's path (s_f), the process force's normal and feed directions there (n_f, u_f)
    and the identified compliance along the wall normal (c_hat)."""
    P = check_path(targets.position_m)
    s_t, _, _ = project_onto_path(P, stock.path_points_m, stock.wall_normals_m)
    s_f = np.arange(0.0, float(s_t[-1]), settings.station_spacing_m)
    n_f, u_f = path_directions(
        stock.path_points_m, stock.wall_normals_m, s_f, settings.feed_force_ratio
    )
    c_hat = normal_compliance_along(
        s_t, compliance_blocks(robot, targets.joints_rad, model), s_f, n_f, u_f
    )
    return s_f, n_f, u_f, c_hat


@dataclass(frozen=True, eq=False)
class _PlannedStages:
    """A staged controller's stages planned offline (``schedule``): the lowest stage its cuts
    of the nominal wall (``draws``) ran at each station (``ratios``), the program carrying it
    as its speeds (``targets``), that program's plan (no feed control) and its cut of the
    nominal wall (``ideal``)."""

    ratios: np.ndarray
    draws: tuple[Rehearsal, ...]
    targets: Targets
    plan: CutPlan
    ideal: Rehearsal


def _planned_stages(
    robot: Robot,
    targets: Targets,
    stock: Stock,
    settings: MachiningSettings,
    on_the_wall: CutPlan,
    ideal: Rehearsal,
    cancel: CancelFlag | Callable[[], bool] | None,
) -> tuple[_PlannedStages | None, int]:
    """The stages planned for a staged controller with ``stages`` "planned": ``ideal`` (the
    nominal wall's cut, draw 0) and ``SCHEDULE_DRAWS`` - 1 more on draws of their own; a draw
    the protection rule stopped counts up to its stop (the lowest stage there). None for any
    other configuration, or when no draw completes (the stages then switch online); with the
    rehearsal numbers past 0 it used, so later rehearsals draw noise of their own."""
    if settings.controller not in STAGED_CONTROLLERS or settings.stages != "planned":
        return None, 0
    zero = np.zeros_like(on_the_wall.inputs.offset)
    draws = (ideal,) + tuple(
        rehearsal_cut(on_the_wall, zero, cancel, seed=rehearsal_seed(settings.seed, d))
        for d in range(1, SCHEDULE_DRAWS)
    )
    if not any(d.summary["completed"] for d in draws):
        return None, SCHEDULE_DRAWS - 1
    ratios = np.min([draw_stages(d, on_the_wall.s_st) for d in draws], axis=0)
    program = scheduled_program(targets, on_the_wall.s_st, ratios)
    plan = plan_cut(robot, program, None, stock, settings, feed="program")
    rigid = replace(plan, inputs=replace(plan.inputs, c_true=np.zeros_like(plan.inputs.c_true)))
    nominal_wall = rehearsal_cut(
        rigid, np.zeros_like(plan.inputs.offset), cancel,
        seed=rehearsal_seed(settings.seed, SCHEDULE_DRAWS),
    )  # fmt: skip
    return _PlannedStages(ratios, draws, program, plan, nominal_wall), SCHEDULE_DRAWS


def _with_schedule(
    run: MachiningRun, summary: dict, stages: _PlannedStages, planned_with: CutPlan
) -> MachiningRun:
    """The row's record of its stage schedule (``summary``, in place) and the run with the
    controller design it was planned with (the cut itself runs no controller)."""
    summary["schedule_draws"] = SCHEDULE_DRAWS
    summary["schedule_draws_completed"] = sum(bool(d.summary["completed"]) for d in stages.draws)
    summary["schedule_switches"] = switches(stages.ratios)
    summary["schedule_lowest_stage"] = float(np.min(stages.ratios))
    controller = planned_with.controller
    summary["schedule_planned_with"] = None if controller is None else controller.describe()
    if planned_with.ctrl_settings is not None:
        from ..cmrr.settings import controller_settings_to_dict

        summary["controller_settings"] = controller_settings_to_dict(planned_with.ctrl_settings)
    return replace(run, controller_settings=planned_with.ctrl_settings)


def _first_plan(
    settings: MachiningSettings, stock: Stock, targets: Targets, s_m: np.ndarray
) -> np.ndarray:
    """Eq. (5) at the stock's depth and the planned feed at arc lengths ``s_m`` (``targets``
    the machining program: its speeds are the feeds it commands)."""
    s_t = arc_length_m(targets.position_m)
    seg = np.clip(np.searchsorted(s_t, s_m, side="left"), 1, len(s_t) - 1)
    v = np.asarray(targets.speed_m_s, dtype=float)[seg]
    planned = np.minimum(v, start_feed_m_s(s_m, s_m, v))
    return predicted_force_N(settings, stock.allowance_m(s_m), planned)


def cut_program(
    robot: Robot,
    targets: Targets,
    wall_normals_m: np.ndarray | None,
    stock: Stock,
    settings: MachiningSettings,
    *,
    model: JointCompliance | None = None,
    progress: ProgressCallback | None = None,
    cancel: CancelFlag | Callable[[], bool] | None = None,
    compensation_model_for_record: JointCompliance | None = None,
    nominal: Targets | None = None,
    compiled: bool = True,
    feed: FeedSource = "controller",
) -> MachiningRun:
    """One cut of ``targets`` along ``stock`` (module docstring); online compensation with
    ``model`` when ``settings.compensation == "online"``; the program's own geometry is the
    rest of the compensation. ``feed`` ``"program"`` runs the program's speeds with no feed
    control (a stage schedule planned offline, ``schedule``; a file that carries none).

    ``nominal`` are the targets ``targets`` correct, one for one (an offline-compensated
    program, or one read back from its exported file): each target's offset is its shift
    from its nominal along the wall normal there, the model's one dimension (the tangential
    part of a correction answers the tangential deflection, which the cut does not model).
    Without it the program is taken along the stock's path, matched to it by projection.
    ``compiled`` False runs the reference loop instead of the compiled one (tests).
    """
    started = time.perf_counter()
    plan = plan_cut(
        robot, targets, wall_normals_m, stock, settings, model=model, nominal=nominal, feed=feed
    )
    return cut_planned(
        plan,
        targets,
        progress=progress,
        cancel=cancel,
        compensation_model_for_record=compensation_model_for_record,
        started=started,
        compiled=compiled,
    )


def cut_planned(
    plan: CutPlan,
    program: Targets,
    *,
    offset_m: np.ndarray | None = None,
    progress: ProgressCallback | None = None,
    cancel: CancelFlag | Callable[[], bool] | None = None,
    compensation_model_for_record: JointCompliance | None = None,
    started: float | None = None,
    compiled: bool = True,
) -> MachiningRun:
    """The planned cut of ``program``; ``offset_m`` (n_st,) replaces the plan's offsets of the
    program from the stock's path (a rehearsal of a corrected program)."""
    started = time.perf_counter() if started is None else started
    settings = plan.settings
    inputs = plan.inputs if offset_m is None else replace(plan.inputs, offset=offset_m)
    try:
        result = run_loop(
            inputs, plan.controller, plan.packed, cancel=cancel_predicate(cancel),
            compiled=compiled,
        )  # fmt: skip
    except _Diverged as exc:
        raise MachiningSettingsError(
            f"the simulated cut diverged at {exc.s_m / MM:.1f} mm along the path (force "
            f"{exc.force_N:.3g} N): F = {settings.process_gain_N:g} d^{settings.depth_exponent:g} "
            f"f^{settings.feed_exponent:g} with a {settings.force_limit_N:g} N limit is beyond "
            "what this arm and controller can cut; check the process K, alpha and beta"
        ) from None
    if progress is not None:
        progress(1.0)
    wall_s = time.perf_counter() - started
    arrays = result.columns
    ds = plan.inputs.ds
    last = len(plan.s_st) - 1
    wall = finished_wall(
        plan.s_st, plan.inputs.allowance, arrays["path_m"], arrays["tool_normal_m"],
        plan.stock.tool_radius_m,
    )  # fmt: skip
    station = np.clip(np.rint(arrays["path_m"] / ds).astype(np.int64), 0, last)
    n = len(arrays["time_s"])
    trace = MachiningTrace(
        reference_N=np.full(n, settings.reference_N),
        limit_N=np.full(n, settings.force_limit_N),
        wall_error_m=wall.error_m[station],
        **arrays,
    )
    summary = summarize(
        settings,
        trace,
        wall,
        v_prog=plan.inputs.v_prog[station],
        cycle_time_s=result.cycle_time_s,
        stop_time_s=result.stop_time_s,
        constant_feed_m_s=plan.constant_feed_m_s,
        wall_time_s=wall_s,
        max_depth_m=plan.stock.max_allowance_m,
    )
    summary["stop_reason"] = result.stop_reason
    summary["feed"] = plan.feed
    ctrl = plan.controller
    summary["controller_design"] = None if ctrl is None else ctrl.describe()
    if plan.ctrl_settings is not None:
        from ..cmrr.settings import controller_settings_to_dict

        summary["controller_settings"] = controller_settings_to_dict(plan.ctrl_settings)
    else:
        summary["controller_settings"] = None
    model = plan.model
    return MachiningRun(
        settings=settings,
        controller=settings.controller,
        compensation=settings.compensation,
        program=program,
        trace=trace,
        wall=wall,
        summary=summary,
        stiffness_model=model if model is not None else compensation_model_for_record,
        controller_settings=plan.ctrl_settings,
    )


@dataclass(frozen=True, eq=False)
class Rehearsal:
    """What a rehearsal of offline compensation needs of its cut: whether it completed, its
    wall error, the finished wall and the force it met along the path (``summary`` and
    ``trace`` as a ``MachiningRun`` names them)."""

    summary: dict[str, Any]
    wall: FinishedWall
    trace: Any


def rehearsal_seed(seed: int, number: int) -> int:
    """The sensor-noise seed of offline compensation's rehearsal ``number`` (0 the nominal
    wall's cut, 1, 2, ... the rehearsals of the plans) under the settings' ``seed``: a draw of
    its own, deterministic, never ``seed``'s (numpy ``SeedSequence([seed, number])``)."""
    return int(np.random.SeedSequence([seed, number]).generate_state(1, np.uint64)[0])


def rehearsal_cut(
    plan: CutPlan,
    offset_m: np.ndarray,
    cancel: CancelFlag | Callable[[], bool] | None,
    *,
    seed: int,
) -> Rehearsal:
    """The planned cut with these offsets on the sensor-noise draw ``seed``
    (``rehearsal_seed``), without the run's summary (the plan reads the wall and the force
    only)."""
    from types import SimpleNamespace

    inputs = replace(plan.inputs, offset=offset_m, seed=seed)
    try:
        result = run_loop(inputs, plan.controller, plan.packed, cancel=cancel_predicate(cancel))
    except _Diverged as exc:
        raise MachiningSettingsError(
            f"the simulated cut diverged at {exc.s_m / MM:.1f} mm along the path"
        ) from None
    c = result.columns
    wall = finished_wall(
        plan.s_st, inputs.allowance, c["path_m"], c["tool_normal_m"], plan.stock.tool_radius_m
    )
    return Rehearsal(
        {
            "completed": result.cycle_time_s is not None,
            "wall_error_max_mm": float(np.max(np.abs(wall.error_m))) / MM,
        },
        wall,
        SimpleNamespace(path_m=c["path_m"], force_N=c["force_N"], speed_ratio=c["speed_ratio"]),
    )


class _FeedState:
    """Private scalar copy of ``DiscreteFeedModel.step`` for the 4-state eq. (1); tests check
    it equals the public model (the loops of ``_loop`` and ``_kernel`` write it out)."""

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
    """Private scalar copy of ``LowPassFilter.step`` for one second-order section; tests check
    it equals the public filter."""

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
