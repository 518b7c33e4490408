"""Automatic path learning (chapter section 3.2): follow the wall at constant contact force.

PROBLEM   The test program (straight lines through the guide points) is far from the real
          contour; the robot must find the contour itself and record it, from a person's rough
          points, at any force in 10-20 N and any feed the user may set.
STRATEGY  The route is planned once before any motion (``route.plan_route``: the legs, the wall
          side, the height, the protections); then every 4 ms the controller runs the law
          (``law.controller_period``, compiled: hybrid force/velocity contour following across
          the tool axis, the height held along it) and supervision, and the leg ends and
          protections are checked (``walk.LegEnd``, ``_protection_stop``). The floor under the
          tool is measured anew every ``REFERENCE_SPACING_M`` of travel, not of time.
          docs/learning_model.md is the model: its states, transitions and thresholds.
SOLUTION  ``learn_path(cell, state, route, settings, estimator) -> (Recording, state)``: every
          4 ms the time, motor-side joints, measured TCP pose, sensor and tool-frame wrenches,
          the force normal to the edge, the reference and a contact flag; the run ends at the
          last guide point or on a stop, whose ``LearningStop`` names the place and the cause.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Sequence
from dataclasses import dataclass

import numpy as np

from ..cell import (
    CONTROL_PERIOD_S,
    Cell,
    CellState,
    ForceEstimator,
    GuidePoint,
    Supervisor,
    cell_supervisor,
)
from ..cell.supervision.moves import move_joint, move_linear
from ..errors import CancelledError, RobomachError
from ..transforms import quaternions_from_matrices
from . import law
from . import thresholds as th
from .law import (
    REC_CONTACT,
    REC_JOINTS,
    REC_NORMAL,
    REC_POSITION,
    REC_ROTATION,
    REC_SEGMENT,
    REC_SENSOR,
    REC_TIME,
    REC_TOOL,
    REC_WIDTH,
    REC_YP,
    controller_period,
    initial_state,
    route_height,
)
from .route import LearningRoute, Leg
from .settings import PathLearningSettings
from .walk import LegEnd


@dataclass(frozen=True)
class LearningStop:
    """Where and why a run ended before its last guide point.

    Attributes:
        cause: "protection", "collision", "supervision", "lost" or "timeout".
        position_m: (3,) TCP position at the stop, base frame.
        leg: (from, to) 1-based guide point numbers of the leg it was on.
        after_m: Distance travelled along that leg's wall since its first guide point.
        wall: What the wall did there ("turns 80 deg towards the tool", "straight", ...).
    """

    cause: str
    position_m: np.ndarray
    leg: tuple[int, int]
    after_m: float
    wall: str

    def document(self) -> dict:
        """JSON form (mm, base frame)."""
        return {
            "cause": self.cause,
            "position_mm": [round(float(v) * 1e3, 3) for v in self.position_m],
            "leg": list(self.leg),
            "after_mm": round(self.after_m * 1e3, 1),
            "wall": self.wall,
        }

    @staticmethod
    def from_document(doc: dict | None) -> LearningStop | None:
        if not doc:
            return None
        return LearningStop(
            str(doc["cause"]),
            np.asarray(doc["position_mm"], dtype=float) * 1e-3,
            (int(doc["leg"][0]), int(doc["leg"][1])),
            float(doc["after_mm"]) * 1e-3,
            str(doc["wall"]),
        )


@dataclass(frozen=True)
class Recording:
    """Path-learning samples, one row per 4 ms (SI units, base frame unless said).

    Attributes:
        time_s: (n,)
        joints_rad: (n, 6) motor-side joints.
        position_m: (n, 3) measured TCP position.
        quaternion_wxyz: (n, 4) measured TCP orientation.
        wrench_sensor: (n, 6) raw F/T reading in the sensor frame [N, N*m].
        wrench_tool: (n, 6) compensated contact wrench in the tool frame, about the TCP.
        force_normal_N: (n,) measured contact force normal to the edge, F_n (what the loop
            regulates; negative when the tool is pressed from the wall's other side).
        force_reference_N: (n,) the reference.
        in_contact: (n,) contact flag (measured force above 1 N).
        yp: (n, 3) the direction towards the wall in use.
        segment: (n,) index of the program leg (its first guide point, 0-based).
        stop_reason: Why the run ended.
        completed: True when the run reached its last guide point.
        stop: Where and why it stopped early (None when completed).
        wall_side: The side of the wall the run followed ("left"/"right" of travel), "" when
            unknown (recordings from before the side was kept).
        wall_side_reason: What decided the side (the setting, the pushes, the mesh).
        wall_side_source: "setting", "force" or "mesh" ("" for older recordings): a side the
            person set is never overruled by the checks.
        guide_lift_m: How far the route lifted each guide point off the floor [m] (empty for
            older recordings): the checks look for each point's wall at the height learned.
        guide_travel: The way the route's walk on the mesh travels past each guide point, (3,)
            unit or zero where it does not pass (``LearningRoute.guide_travel``; empty for
            older recordings and without a mesh): the checks take each point's side from it.
    """

    time_s: np.ndarray
    joints_rad: np.ndarray
    position_m: np.ndarray
    quaternion_wxyz: np.ndarray
    wrench_sensor: np.ndarray
    wrench_tool: np.ndarray
    force_normal_N: np.ndarray
    force_reference_N: np.ndarray
    in_contact: np.ndarray
    yp: np.ndarray
    segment: np.ndarray
    stop_reason: str
    completed: bool
    stop: LearningStop | None = None
    wall_side: str = ""
    wall_side_reason: str = ""
    wall_side_source: str = ""
    guide_lift_m: tuple[float, ...] = ()
    guide_travel: tuple[tuple[float, float, float], ...] = ()

    def __len__(self) -> int:
        return len(self.time_s)


def axis6_round_route(robot, guides: Sequence[GuidePoint], closed: bool) -> list[float]:
    """Axis 6's angle at each guide point round the route [rad], the first point's again at the
    end of a closed route: each point solved from the last, axis 6 the nearest equivalent of
    the last (the solver may land a turn away); up to the first point the arm cannot reach."""
    q = np.asarray(guides[0].joints_rad, dtype=float)
    out = [float(q[5])]
    for k in list(range(1, len(guides))) + ([0] if closed else []):
        try:
            q_next = robot.ik(guides[k].T_base_tcp, q)
        except RobomachError:
            break
        q_next[5] = q[5] + math.remainder(q_next[5] - q[5], 2 * math.pi)
        q = q_next
        out.append(float(q[5]))
    return out


def start_joints(robot, guides: Sequence[GuidePoint], closed: bool) -> np.ndarray:
    """Joints to start from: the first guide point's, with axis 6 shifted by whole turns so the
    wrist's turn round the route (``axis6_round_route``) stays inside axis 6's range; the
    recorded joints when nothing fits better, or a point is out of reach (the check says so)."""
    q0 = np.asarray(guides[0].joints_rad, dtype=float).copy()
    lo, hi = robot.lower_rad[5], robot.upper_rad[5]
    if hi - lo < 2 * math.pi + 0.5:
        return q0
    q6 = axis6_round_route(robot, guides, closed)
    if len(q6) < len(guides) + closed:
        return q0
    margin = 0.2
    for turns in sorted(range(-3, 4), key=abs):
        shift = turns * 2 * math.pi
        if min(q6) + shift >= lo + margin and max(q6) + shift <= hi - margin:
            q0[5] += shift
            return q0
    return q0


def _approach(
    cell: Cell,
    state: CellState,
    guides: Sequence[GuidePoint],
    start: np.ndarray,
    axis: np.ndarray,
    closed: bool,
    supervisor: Supervisor,
) -> CellState:
    """To the first guide point: up out of the part, across above the start in the first
    point's arm configuration (axis 6 unwound for the route), and down to the start."""
    robot = cell.robot
    R0 = guides[0].T_base_tcp[:3, :3]
    p_now = state.T_base_tcp[:3, 3]
    above = start - axis * th.APPROACH_CLEARANCE_M
    if float((p_now - above) @ axis) > 0.0:  # below the approach plane: straight up first
        T_up = state.T_base_tcp.copy()
        T_up[:3, 3] = p_now - axis * float((p_now - above) @ axis)
        state = move_linear(cell, state, T_up, supervisor=supervisor)
    T_above = np.eye(4)
    T_above[:3, :3] = R0
    T_above[:3, 3] = above
    q_start = start_joints(robot, guides, closed)
    try:
        q_above = robot.ik(T_above, q_start)
    except Exception:  # noqa: BLE001 - fall back to a straight move from where the arm is
        q_above = None
    if q_above is not None and float(np.max(np.abs(q_above - q_start))) < 1.0:
        state = move_joint(cell, state, q_above, supervisor=supervisor)
    else:
        state = move_linear(cell, state, T_above, supervisor=supervisor)
    T_start = T_above.copy()
    T_start[:3, 3] = start
    return move_linear(cell, state, T_start, 0.01, supervisor=supervisor)


def _wall_turn(
    yps: np.ndarray, positions: np.ndarray, n: int, side: float, axis: np.ndarray
) -> str:
    """What the wall did over the last ~5 mm before sample ``n`` (its turn towards the tool),
    as a clause: "the wall runs straight", "the wall turns 80 deg away from the tool ..."."""
    if n < 2:
        return "no wall had been found yet"
    steps = np.linalg.norm(np.diff(positions[max(0, n - 3000) : n], axis=0), axis=1)
    back = np.cumsum(steps[::-1])
    k = int(np.searchsorted(back, 0.005))
    i0 = max(0, n - 1 - k - 1)
    w0, w1 = yps[i0], yps[n - 1]
    turn = math.degrees(math.atan2(float(np.cross(w0, w1) @ axis) * side, float(w0 @ w1)))
    if abs(turn) < 15.0:
        return "the wall runs straight"
    if turn > 0:
        return f"the wall turns {abs(turn):.0f} deg away from the tool (an outside corner)"
    return f"the wall turns {abs(turn):.0f} deg towards the tool (an inside corner or a boss)"


def contour_law_parameters(settings: PathLearningSettings) -> np.ndarray:
    """The parameter vector of ``law.contour_law`` for these settings, each value at its
    place (``law.P_FORCE`` ...)."""
    values = {
        law.P_FORCE: settings.force_N, law.P_KP: settings.kp_m_s_N, law.P_KI: settings.ki_m_s2_N,
        law.P_VMAX: settings.max_normal_speed_m_s, law.P_SEARCH: settings.search_speed_m_s,
        law.P_SPEED: settings.speed_m_s, law.P_DT: CONTROL_PERIOD_S,
        law.P_BETA: min(1.0, CONTROL_PERIOD_S / th.WALL_DIRECTION_TIME_S),
        law.P_CONE: th.FLOOR_CONE_TAN, law.P_FLOOR_N: th.FLOOR_FORCE_N,
        law.P_CLEARANCE: settings.floor_clearance_m, law.P_LIFT_DECAY: th.LIFT_DECAY_M,
        law.P_HEIGHT_TIME: th.HEIGHT_TIME_S, law.P_HEIGHT_SPEED: th.HEIGHT_SPEED_M_S,
        law.P_BEHIND: th.BEHIND_COS, law.P_CONTACT: th.CONTACT_FLAG_N,
        law.P_FIRST: th.FIRST_SEARCH_ACROSS_M, law.P_TURN: th.SEARCH_TURN_M,
        law.P_SLOW_FROM: th.SLOW_FROM, law.P_SLOWEST_AT: th.SLOWEST_AT, law.P_SLOWEST: th.SLOWEST,
        law.P_CLIMB: th.CLIMB_SHARE, law.P_TOUCHED: th.WALL_FORCE_CLEAR_N,
    }  # fmt: skip
    assert sorted(values) == list(range(law.PARAMETER_COUNT))  # every place filled, once
    params = np.empty(law.PARAMETER_COUNT)
    params[list(values)] = list(values.values())
    return params


@dataclass
class _Protections:
    """The protection rules of one leg: the limits a period is checked against, and the first
    one crossed as (cause, message)."""

    force_limit_N: float
    penetration_m: float
    wander_m: float
    detour_m: float
    leg_length_m: float

    def crossed(
        self, f_abs: float, depth: float, searched: float, off_route: float, travel: float
    ) -> tuple[str, str] | None:
        """The first rule crossed, in this order, as (cause, message); None while none is."""
        if f_abs > self.force_limit_N:
            return "protection", (
                f"protection: the contact force reached {f_abs:.1f} N, over the "
                f"{self.force_limit_N:g} N limit"
            )
        if depth > self.penetration_m:
            return "collision", (
                f"collision: the cutter went {depth * 1e3:.2f} mm into the part (more than "
                f"{th.PENETRATION_STOP_FRACTION:g} of its radius)"
            )
        if searched > th.LOST_WALL_M:
            return "lost", (
                f"protection: the tool searched {searched * 1e3:.0f} mm without finding the wall"
            )
        if off_route > self.wander_m:
            return "lost", (
                f"protection: the wall led the tool {off_route * 1e3:.0f} mm off the leg's "
                "route, so a guide point may be on another wall"
            )
        if travel > self.detour_m:
            return "lost", (
                f"protection: the wall of this leg ran {travel * 1e3:.0f} mm, far longer than "
                f"the {self.leg_length_m * 1e3:.0f} mm leg, so a guide point may be on another wall"
            )
        return None


def learn_path(
    cell: Cell,
    state: CellState,
    route: LearningRoute,
    settings: PathLearningSettings,
    estimator: ForceEstimator,
    *,
    progress: Callable[[float], None] | None = None,
    cancelled: Callable[[], bool] | None = None,
    supervisor: Supervisor | None = None,
) -> tuple[Recording, CellState]:
    """Follow the wall along the planned ``route`` and record it (module docstring).

    The robot first moves above the first guide point in that point's arm configuration, then
    down to it; the force-controlled run starts there and is recorded. Supervision slows the
    run near a limit; a step that would cross one ends the run there, like a protection rule,
    with the cause in ``stop_reason`` and the place in ``stop``.

    Raises:
        CancelledError: ``cancelled()`` returned True.
        SupervisionError: the approach to the first guide point crosses a limit.
    """
    dt = CONTROL_PERIOD_S
    supervisor = supervisor or cell_supervisor(cell)
    legs, axis = route.legs, route.axis
    side = route.wall_side.sign
    heights = route.heights

    def across(v: np.ndarray) -> np.ndarray:
        return v - axis * float(v @ axis)

    state, w, ref = _start(cell, state, route, supervisor)

    # Room for the run at the speed it may fall to (the slowest advance near the force limit).
    slowest = min(settings.speed_m_s, settings.search_speed_m_s)
    n_max = int(sum(leg.length for leg in legs) / slowest / dt * 2.0) + 4000
    record = np.empty((n_max, REC_WIDTH))
    rows = np.array([leg.row(route.leg_offsets(leg)) for leg in legs])
    T_ref = state.T_base_tcp.copy()
    since_ref = 0.0
    settled_at: np.ndarray | None = None
    law = initial_state()
    step, turn = np.zeros(3), np.zeros(3)
    k = 0
    leg, row = legs[0], rows[0]
    end, guard = _leg_watch(route, 0, settings, cell.tool.radius_m)
    leg_travel = 0.0
    t0 = state.time_s
    stop_reason, stop_cause, completed = "reached the last guide point", "", False
    n = 0
    s_now = 0.0
    report_every = max(1, int(1.0 / dt))
    tool_data = estimator.tool_data()
    R_tcp_flange = cell.tool.T_flange_tcp[:3, :3].T.copy()
    params = contour_law_parameters(settings)
    max_turn = th.TURN_RATE_RAD_S * dt
    while True:
        if n >= n_max:
            stop_reason = "stopped: the run took far longer than the program predicts"
            stop_cause = "timeout"
            break
        # --- the controller (measure, the law, record, the turn), compiled ---
        f_abs, touching, ever, searched, off_route, advance, s_now = controller_period(
            state.ft_reading, state.T_base_tcp, state.q_motor, state.time_s - t0, tool_data,
            R_tcp_flange, row, ref, axis, side, T_ref, w, law, params, max_turn, step, turn,
            record, n,
        )  # fmt: skip
        if touching and settled_at is None and ever and f_abs >= settings.force_N:
            # a closed loop ends where its contact first held the set force: the recording's
            # first samples, as the force builds, are below the force filter's band
            settled_at = state.T_base_tcp[:3, 3].copy()
        n += 1
        crossed = guard.crossed(f_abs, state.contact.depth_m, searched, off_route, leg_travel)
        if crossed is not None:
            stop_cause, stop_reason = crossed
            break
        # --- supervision (compiled) and the cell ---
        supervised = supervisor.supervise_increment(state.q_motor, T_ref, step, turn)
        if supervised.stop is not None:
            stop_cause = "supervision"
            stop_reason = f"supervision: {supervised.stop.message}"
            break
        T_ref = supervised.T_ref
        travelled = advance * supervised.scale
        leg_travel += travelled
        state = cell.step(state, supervised.q_next)
        if s_now >= end.watch_from_m and end.reached(T_ref[:3, 3], s_now, settled_at):
            if end.last:
                completed = True
                break
            k += 1
            leg, row = legs[k], rows[k]
            end, guard = _leg_watch(route, k, settings, cell.tool.radius_m)
            leg_travel = 0.0
        since_ref += travelled
        if since_ref >= th.REFERENCE_SPACING_M:
            travel = across(step)
            travel /= max(float(np.linalg.norm(travel)), 1e-12)
            ref, since_ref = heights.at(T_ref[:3, 3], travel, w), 0.0
        if n % report_every == 0:
            if cancelled is not None and cancelled():
                raise CancelledError("path learning was cancelled")
            if progress is not None:
                progress(min(1.0, (k + max(0.0, s_now) / leg.length) / len(legs)))
    if progress is not None:
        progress(1.0)
    if completed:
        return _recording(record[:n], route, settings, stop_reason, None), state
    stop, stop_reason = _stop_at(
        record[:n], T_ref, leg, leg_travel, route, stop_cause or "stopped", stop_reason
    )
    return _recording(record[:n], route, settings, stop_reason, stop), state


def _leg_watch(
    route: LearningRoute, k: int, settings: PathLearningSettings, tool_radius_m: float
) -> tuple[LegEnd, _Protections]:
    """Leg ``k``'s end rule and protections, watched from its start."""
    leg = route.legs[k]
    last = k + 1 == len(route.legs)
    end = LegEnd(leg, route.axis, last=last, closed=route.closed, tool_radius_m=tool_radius_m)
    wander = route.leg_wander_m.get((leg.first, leg.last), 0.0)
    return end, _Protections(
        settings.force_limit_N,
        th.PENETRATION_STOP_FRACTION * tool_radius_m,
        max(th.LOST_WALL_M, th.ROUTE_WANDER_FRACTION * leg.length, wander),
        th.LEG_DETOUR_FACTOR * leg.length + th.LEG_DETOUR_EXTRA_M,
        leg.length,
    )


def _stop_at(
    rec: np.ndarray,
    T_ref: np.ndarray,
    leg: Leg,
    leg_travel_m: float,
    route: LearningRoute,
    cause: str,
    reason: str,
) -> tuple[LearningStop, str]:
    """Where and why a run that did not reach its last guide point stopped: the place, the
    leg, how far along it, and what the wall does there, said after the ``reason``."""
    n = len(rec)
    p_stop = rec[-1, REC_POSITION : REC_POSITION + 3].copy() if n else T_ref[:3, 3].copy()
    leg_numbers = (leg.first + 1, leg.last + 1)
    positions, yps = rec[:, REC_POSITION : REC_POSITION + 3], rec[:, REC_YP : REC_YP + 3]
    wall = _wall_turn(yps, positions, n, route.wall_side.sign, route.axis)
    stop = LearningStop(cause, p_stop, leg_numbers, leg_travel_m, wall)
    return stop, (
        f"{reason}. It stopped at t = {rec[-1, REC_TIME] if n else 0.0:.2f} s, "
        f"{leg_travel_m * 1e3:.0f} mm along the leg G{leg_numbers[0]} -> G{leg_numbers[1]}, "
        f"where {wall}."
    )


def _start(
    cell: Cell, state: CellState, route: LearningRoute, supervisor: Supervisor
) -> tuple[CellState, np.ndarray, np.ndarray]:
    """The run's start (``run_start``) and the approach down to it. Returns (the state there,
    the wall direction, the height reference)."""
    start, w, ref = run_start(route)
    state = _approach(
        cell, state, route.guides, start, route.axis, route.closed, supervisor=supervisor
    )
    return state, w, ref


def run_start(route: LearningRoute) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Where the run starts: the first point at the route's height over the floor under the
    whole cutter there and ahead of it along the wall (a step included), the direction to the
    wall (the mesh's wall point, else the recorded push, else across the first leg on the
    wall's side) and the height reference. Returns (the start, the wall direction, the
    reference)."""
    legs, axis, guide = route.legs, route.axis, route.guides[0]

    def across(v: np.ndarray) -> np.ndarray:
        return v - axis * float(v @ axis)

    w = across(np.cross(axis, legs[0].xp) * route.wall_side.sign)
    pushed = across(-np.asarray(guide.force_N, dtype=float))
    if route.start_towards_wall is not None:
        w = across(np.asarray(route.start_towards_wall, dtype=float))
    elif float(np.linalg.norm(pushed)) >= th.WALL_FORCE_CLEAR_N and float(pushed @ w) > 0.0:
        w = pushed
    w /= float(np.linalg.norm(w))
    # the way along the wall the walk passed the first point (the floor ahead of the cutter,
    # a step up included, is measured along it, as the walk climbs it): the first leg's chord
    # may head into the part, past the step (a point resting on the floor 1 mm before a riser
    # started under the step's top, met the riser and took it for the wall)
    walked = route.guide_travel[0] if route.walks else np.zeros(3)
    travel = across(walked if float(np.linalg.norm(walked)) > 0.5 else legs[0].xp)
    travel /= float(np.linalg.norm(travel))
    start = legs[0].a.copy()
    ref = route.heights.at(start, travel, w)
    row = legs[0].row(route.leg_offsets(legs[0]))
    start += axis * (route_height(row, ref, start, axis) - float(start @ axis))
    return start, w, ref


def _recording(
    rec: np.ndarray,
    route: LearningRoute,
    settings: PathLearningSettings,
    stop_reason: str,
    stop: LearningStop | None,
) -> Recording:
    """The ``Recording`` of the run's rows (``law.REC_TIME`` ...)."""

    def columns(start: int, width: int) -> np.ndarray:
        return rec[:, start : start + width].copy()

    decision = route.wall_side
    return Recording(
        time_s=rec[:, REC_TIME].copy(),
        joints_rad=columns(REC_JOINTS, 6),
        position_m=columns(REC_POSITION, 3),
        quaternion_wxyz=quaternions_from_matrices(
            rec[:, REC_ROTATION : REC_ROTATION + 9].reshape(-1, 3, 3)
        ),
        wrench_sensor=columns(REC_SENSOR, 6),
        wrench_tool=columns(REC_TOOL, 6),
        force_normal_N=rec[:, REC_NORMAL].copy(),
        force_reference_N=np.full(len(rec), settings.force_N),
        in_contact=rec[:, REC_CONTACT] > 0.5,
        yp=columns(REC_YP, 3),
        segment=rec[:, REC_SEGMENT].astype(np.int32),
        stop_reason=stop_reason,
        completed=stop is None,
        stop=stop,
        wall_side=decision.side,
        wall_side_reason=decision.detail,
        wall_side_source=decision.source,
        guide_lift_m=tuple(float(v) for v in route.lifted_m),
        guide_travel=tuple((float(x), float(y), float(z)) for x, y, z in route.guide_travel),
    )
