"""Automatic path learning (chapter section 3.2): follow the wall at constant contact force.

PROBLEM   The test program (straight lines through the guide points) is far from the real
          contour; the robot must find the contour itself and record it. The chapter's run is
          compliant only along Yp, across the program line: that follows the wall while it stays
          near the line, but a person's points are rough. Where a leg skips an outside corner or
          a boss, the line runs far from the wall (the tool chases it sideways, or meets its far
          side head on and trips the protection); where a point rests on the groove's floor, the
          tool is dragged along it.
STRATEGY  Hybrid force/velocity contour following in the plane across the tool axis (the
          chapter's "constant contact force normal to the edge", section 3.2, with the path
          direction taken from the wall instead of the line):
            - the wall direction w (from the tool towards the wall) is the measured contact force
              across the axis, reversed and low-passed; before the first contact it is Yp of the
              first leg (the wall side: ``wall_side``);
            - the tool advances along the wall's tangent t = side * (w x Zp) at the learning
              speed, slower where the force climbs (``speed_ratio``), and moves along w under PI
              force control to the reference:
                  v_w = Kp e + Ki integral(e),  e = F_ref - F_n,  F_n = |F across Zp|;
              out of contact it searches along w and advances no faster than it searches, so at
              an outside corner it turns round the wall instead of heading for the next point;
            - the guide points give the route: the progress along the current leg (the tool's
              projection on it) sets the tool orientation (slerp between the legs' guide
              orientations) and the height (the leg's, along the guide points' mean tool axis),
              and ends the leg; a force from the floor (along the axis) lifts the run until it is
              clear of the floor by ``floor_clearance_m``.
          The law of one period is ``contour_following.contour_law`` (compiled). The controller
          sees only motor-side joints and the F/T reading; supervision (joint limits,
          singularities, reach, collisions, and a cutter driven into the part) slows and stops
          it as for any motion.
SOLUTION  ``learn_path(...) -> Recording``: every 4 ms the time, motor-side joints, measured TCP
          pose, sensor and tool-frame wrenches, the force normal to the edge, the reference and a
          contact flag; the run ends at the last guide point or on a stop, whose ``LearningStop``
          names the place (leg, position) and the cause.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Sequence
from dataclasses import dataclass

import numpy as np
import pinocchio as pin

from ..cell import Cell, CellState
from ..clock import CONTROL_PERIOD_S
from ..errors import CancelledError, InvalidInputError, NotEnoughGuidePointsError
from ..leadthrough import GuidePoint
from ..limits import FLOOR_CLEARANCE_MM, LEARNING_FORCE_N, LEARNING_SPEED_MM_S
from ..sensor import ForceEstimator
from ..supervision import Supervisor, cell_supervisor
from ..transforms import matrix_from_quaternion, quaternions_from_matrices
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
    law_parameters,
    leg_progress,
)
from .side import (
    WALL_FORCE_CLEAR_N,
    WALL_SIDE_CHOICES,
    WallSideDecision,
    WallSideSetting,
    mean_tool_axis,
    resolve_wall_side,
)

FORCE_RANGE_N = (LEARNING_FORCE_N.min, LEARNING_FORCE_N.max)
SPEED_RANGE_M_S = (LEARNING_SPEED_MM_S.min * 1e-3, LEARNING_SPEED_MM_S.max * 1e-3)
CONTACT_FLAG_N = 1.0  # a measured contact force above this counts as contact
LOST_WALL_M = 0.03  # protection: the tool searched this far without finding the wall
ROUTE_WANDER_FRACTION = 1.0  # protection: the wall led the tool this far (x leg) off the leg
# Force-dependent speed (``contour_following.speed_ratio``): full speed up to 1.25 F_ref,
# 10 % from 2 F_ref.
SLOW_FROM, SLOWEST_AT, SLOWEST = 1.25, 2.0, 0.1
MOVE_MAX_PERIODS_FACTOR = 20  # a MoveL slowed by supervision may take this many times longer
WALL_DIRECTION_TIME_S = 0.02  # low-pass of the measured wall direction
# A contact force from more than 135 deg off the wall direction is the wall behind the tool.
BEHIND_COS = math.cos(math.radians(135.0))
FLOOR_FORCE_N = 2.0  # a push along the tool axis above this is the floor
FLOOR_LIFT_SPEED_M_S = 0.002
HEIGHT_TIME_S = 0.25  # the height returns to the leg's within about this
HEIGHT_SPEED_M_S = 0.01
PENETRATION_STOP_FRACTION = 0.5  # of the cutter radius: deeper is a collision, not a contact
LEG_END_MARGIN_M = 0.002  # a leg ends this far before its guide point's plane
# ... or at the tool's nearest approach to its guide point, when that comes within NEAR_END_M
# (across the tool axis) and recedes by END_PASSED_M: a point a person left beyond an outside
# corner, whose plane the wall round the corner never reaches (before, the tool went on along
# the next wall until the protection stopped it 30 mm off the leg).
NEAR_END_M = 0.006
END_PASSED_M = 0.0002
LEG_DETOUR_FACTOR = 4.0  # a leg's wall longer than this x the leg (+ LEG_DETOUR_EXTRA_M): lost
LEG_DETOUR_EXTRA_M = 0.05
FIRST_SEARCH_ACROSS_M = 0.006  # the first search goes straight across this far, then also along
SEARCH_TURN_M = 0.006  # out of contact this long after a wall, search along the leg again
APPROACH_CLEARANCE_M = 0.03  # the approach travels this far above the first point
CLOSE_LOOP_M = 0.001  # a closed route ends at its nearest approach within this of its start
CLOSE_LOOP_OVERRUN_M = 0.01  # ... or this far past the first guide point's plane
TURN_RATE_RAD_S = 0.5  # the tool's orientation follows the route's at most this fast


@dataclass(frozen=True)
class PathLearningSettings:
    """Settings of a path-learning run (SI units).

    Attributes:
        force_N: Contact force reference normal to the edge (the chapter: 10-20 N; 10 N on
            the pump).
        speed_m_s: Learning speed along the wall (the chapter: 5 mm/s).
        closed: The contour returns from the last guide point to the first.
        wall_side: Side of the wall relative to the travel direction, looking along the tool
            axis into the part; "auto" decides from a clear wall push at the guide points or
            the part's mesh, and refuses otherwise (``wall_side.resolve_wall_side``).
        force_limit_N: Protection rule: the run stops when the contact force exceeds this.
        floor_clearance_m: Height kept above a floor the run meets (and above the floor under
            a guide point, when the part's mesh is known): the machining height.
        kp_m_s_N: Proportional gain of the force loop.
        ki_m_s2_N: Integral gain of the force loop.
        max_normal_speed_m_s: Speed limit of the force loop.
        search_speed_m_s: Speed towards the wall, and along it, while out of contact (searching
            for the wall), so the tool meets it gently instead of at full speed.
    """

    force_N: float = 10.0
    speed_m_s: float = 0.005
    closed: bool = True
    wall_side: WallSideSetting = "auto"
    force_limit_N: float = 60.0
    floor_clearance_m: float = 0.0005
    kp_m_s_N: float = 1.5e-3
    ki_m_s2_N: float = 0.03
    max_normal_speed_m_s: float = 0.025
    search_speed_m_s: float = 0.005

    def __post_init__(self) -> None:
        lo, hi = FORCE_RANGE_N
        if not (lo <= self.force_N <= hi):
            raise InvalidInputError(f"contact force {self.force_N:g} N is outside {lo:g}-{hi:g} N")
        lo, hi = SPEED_RANGE_M_S
        if not (lo <= self.speed_m_s <= hi):
            raise InvalidInputError(
                f"learning speed {self.speed_m_s * 1e3:g} mm/s is outside "
                f"{lo * 1e3:g}-{hi * 1e3:g} mm/s"
            )
        if self.force_limit_N <= self.force_N:
            raise InvalidInputError("the force limit must be above the force reference")
        if self.wall_side not in WALL_SIDE_CHOICES:
            raise InvalidInputError(f"wall side must be one of {', '.join(WALL_SIDE_CHOICES)}")
        FLOOR_CLEARANCE_MM.check(self.floor_clearance_m * 1e3)


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

    def __len__(self) -> int:
        return len(self.time_s)


@dataclass
class _Segment:
    a: np.ndarray
    b: np.ndarray
    length: float
    xp: np.ndarray
    Ra: np.ndarray  # orientation at a
    omega: np.ndarray  # rotation vector from Ra to Rb, in the frame of Ra (slerp = Ra exp(f w))
    first: int  # 0-based guide index of a
    last: int  # 0-based guide index of b


def _segments(guides: Sequence[GuidePoint], closed: bool) -> list[_Segment]:
    n = len(guides)
    order = list(range(n)) + ([0] if closed else [])
    segs = []
    for i0, i1 in zip(order[:-1], order[1:], strict=True):
        g0, g1 = guides[i0], guides[i1]
        a, b = g0.position_m.copy(), g1.position_m.copy()
        d = b - a
        length = float(np.linalg.norm(d))
        if length < 1e-4:
            continue  # coincident guide points: nothing to travel
        Ra = matrix_from_quaternion(g0.quaternion_wxyz)
        Rb = matrix_from_quaternion(g1.quaternion_wxyz)
        segs.append(_Segment(a, b, length, d / length, Ra, pin.log3(Ra.T @ Rb), i0, i1))
    return segs


def _leg_row(seg: _Segment) -> np.ndarray:
    """The leg as a row of ``contour_following``'s leg table (``LEG_A`` ...)."""
    return np.concatenate([seg.a, seg.xp, [seg.length], seg.Ra.ravel(), seg.omega, [seg.first]])


def move_linear(
    cell: Cell,
    state: CellState,
    T_target: np.ndarray,
    speed_m_s: float = 0.05,
    *,
    supervisor: Supervisor | None = None,
) -> CellState:
    """Position-controlled straight move (MoveL) of the TCP to ``T_target``; no force control.

    The reference moves by equal increments, (p1 - p0) / n and log3(R0^T R1) / n in its own
    axes (the slerp's constant rate), over n periods at ``speed_m_s``: the increments path
    learning's loop runs through ``Supervisor.supervise_increment``, compiled.

    Supervised: the move slows near a limit and raises ``SupervisionError`` (carrying the last
    safe cell state) before crossing one.
    """
    supervisor = supervisor or cell_supervisor(cell)
    T_ref = state.T_base_tcp.copy()
    T_target = np.asarray(T_target, dtype=float)
    dist = float(np.linalg.norm(T_target[:3, 3] - T_ref[:3, 3]))
    n = max(1, int(math.ceil(dist / speed_m_s / CONTROL_PERIOD_S)))
    step = (T_target[:3, 3] - T_ref[:3, 3]) / n
    turn = pin.log3(T_ref[:3, :3].T @ T_target[:3, :3]) / n
    progress = 0.0  # periods' worth of motion done (a slowed period counts its scale)
    settle = 0
    for _ in range(MOVE_MAX_PERIODS_FACTOR * n + 10):
        if progress >= n and settle >= 10:
            break
        part = min(1.0, n - progress) if progress < n else 0.0
        supervised = supervisor.supervise_increment(state.q_motor, T_ref, step * part, turn * part)
        if supervised.stop is not None:
            raise supervised.stop.error(state=state)
        T_ref = supervised.T_ref
        state = cell.step(state, supervised.q_next)
        progress += supervised.scale * part
        if part == 0.0:  # at the target: settling periods
            settle += 1
    return state


def move_joint(
    cell: Cell,
    state: CellState,
    q_target: np.ndarray,
    speed_rad_s: float = 0.5,
    *,
    supervisor: Supervisor | None = None,
) -> CellState:
    """Joint-interpolated move (MoveJ / MoveAbsJ) to ``q_target``, supervised like MoveL."""
    supervisor = supervisor or cell_supervisor(cell)
    q0 = state.q_motor.copy()
    q1 = np.asarray(q_target, dtype=float)
    span = float(np.max(np.abs(q1 - q0)))
    n = max(1, int(math.ceil(span / speed_rad_s / CONTROL_PERIOD_S)))
    robot = cell.robot
    progress = 0.0
    for _ in range(MOVE_MAX_PERIODS_FACTOR * n + 10):
        if progress >= n:
            break
        base = progress
        step = min(1.0, n - progress)

        def propose(scale: float, base: float = base, step: float = step):
            q = q0 + (q1 - q0) * min(1.0, (base + scale * step) / n)
            return robot.fk(q), q

        supervised = supervisor.supervise(state.q_motor, propose)
        if supervised.stop is not None:
            raise supervised.stop.error(state=state)
        state = cell.step(state, supervised.q_next)
        progress += supervised.scale * step
    for _ in range(10):  # settle
        state = cell.step(state, state.q_motor)
    return state


def _wrist_turns(robot, guides: Sequence[GuidePoint], closed: bool) -> np.ndarray:
    """Joints to start from: the first guide point's, with axis 6 shifted by whole turns so the
    wrist's turn round the route (the guide points solved in order, each seeded by the last)
    stays inside axis 6's range; the recorded joints when nothing fits better."""
    q0 = np.asarray(guides[0].joints_rad, dtype=float).copy()
    lo, hi = robot.lower_rad[5], robot.upper_rad[5]
    if hi - lo < 2 * math.pi + 0.5:
        return q0
    q6 = [q0[5]]
    seed = q0
    order = list(range(1, len(guides))) + ([0] if closed else [])
    for k in order:
        try:
            q = robot.ik(guides[k].T_base_tcp, seed)
        except Exception:  # noqa: BLE001 - an unreachable point is reported by the check
            return q0
        # the nearest equivalent of axis 6 to the last (the solver may land a turn away)
        q[5] = seed[5] + math.remainder(q[5] - seed[5], 2 * math.pi)
        q6.append(q[5])
        seed = q
    lo_need, hi_need = min(q6), max(q6)
    margin = 0.2
    for turns in sorted(range(-3, 4), key=abs):
        shift = turns * 2 * math.pi
        if lo_need + shift >= lo + margin and hi_need + shift <= hi - margin:
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
    above = start - axis * APPROACH_CLEARANCE_M
    if float((p_now - above) @ axis) > 0.0:  # below the approach plane: straight up first
        T_up = state.T_base_tcp.copy()
        T_up[:3, 3] = p_now - axis * float((p_now - above) @ axis)
        state = move_linear(cell, state, T_up, supervisor=supervisor)
    T_above = np.eye(4)
    T_above[:3, :3] = R0
    T_above[:3, 3] = above
    q_start = _wrist_turns(robot, guides, closed)
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
    """What the wall did over the last ~5 mm before sample ``n``: its turn towards the tool."""
    if n < 2:
        return "no wall found yet"
    steps = np.linalg.norm(np.diff(positions[max(0, n - 3000) : n], axis=0), axis=1)
    back = np.cumsum(steps[::-1])
    k = int(np.searchsorted(back, 0.005))
    i0 = max(0, n - 1 - k - 1)
    w0, w1 = yps[i0], yps[n - 1]
    turn = math.degrees(math.atan2(float(np.cross(w0, w1) @ axis) * side, float(w0 @ w1)))
    if abs(turn) < 15.0:
        return "a straight stretch of wall"
    if turn > 0:
        return f"the wall turns {abs(turn):.0f} deg away from the tool (an outside corner)"
    return f"the wall turns {abs(turn):.0f} deg towards the tool (an inside corner or a boss)"


def contour_law_parameters(settings: PathLearningSettings) -> np.ndarray:
    """The parameter vector of ``contour_following.contour_law`` for these settings."""
    return law_parameters(
        force_N=settings.force_N,
        kp_m_s_N=settings.kp_m_s_N,
        ki_m_s2_N=settings.ki_m_s2_N,
        max_normal_speed_m_s=settings.max_normal_speed_m_s,
        search_speed_m_s=settings.search_speed_m_s,
        speed_m_s=settings.speed_m_s,
        beta=min(1.0, CONTROL_PERIOD_S / WALL_DIRECTION_TIME_S),
        dt_s=CONTROL_PERIOD_S,
        floor_force_N=FLOOR_FORCE_N,
        floor_lift_speed_m_s=FLOOR_LIFT_SPEED_M_S,
        floor_clearance_m=settings.floor_clearance_m,
        height_time_s=HEIGHT_TIME_S,
        height_speed_m_s=HEIGHT_SPEED_M_S,
        behind_cos=BEHIND_COS,
        contact_flag_N=CONTACT_FLAG_N,
        first_search_across_m=FIRST_SEARCH_ACROSS_M,
        search_turn_m=SEARCH_TURN_M,
        slow_from=SLOW_FROM,
        slowest_at=SLOWEST_AT,
        slowest=SLOWEST,
    )


def _leg_limits(
    seg: _Segment, wall_wander: dict[tuple[int, int], float]
) -> tuple[float, float, float]:
    """A leg's protections and end: how far the wall may lead the tool off its line (farther
    where the part's mesh says its wall runs so), how long its wall may run, and the progress
    along it where the next leg takes over [m]."""
    length = seg.length
    return (
        max(
            LOST_WALL_M, ROUTE_WANDER_FRACTION * length, wall_wander.get((seg.first, seg.last), 0.0)
        ),
        LEG_DETOUR_FACTOR * length + LEG_DETOUR_EXTRA_M,
        length - min(LEG_END_MARGIN_M, 0.25 * length),
    )


def _protection_stop(
    settings: PathLearningSettings,
    f_abs: float,
    depth: float,
    penetration_stop: float,
    searched: float,
    off_route: float,
    wander: float,
    leg_travel: float,
    leg_length: float,
) -> tuple[str, str]:
    """The cause and the message of the protection rule that stops the run (the first of
    them, in this order)."""
    if f_abs > settings.force_limit_N:
        return "protection", (
            f"protection: contact force {f_abs:.1f} N exceeded the "
            f"{settings.force_limit_N:g} N limit"
        )
    if depth > penetration_stop:
        return "collision", (
            f"collision: the cutter went {depth * 1e3:.2f} mm into the part "
            f"(more than {PENETRATION_STOP_FRACTION:g} of its radius)"
        )
    if searched > LOST_WALL_M:
        return "lost", (
            f"protection: the tool searched {searched * 1e3:.0f} mm without finding the wall"
        )
    if off_route > wander:
        return "lost", (
            f"protection: the wall led the tool {off_route * 1e3:.0f} mm off the leg's "
            "route: a guide point may be on another wall"
        )
    return "lost", (
        f"protection: the wall of this leg ran {leg_travel * 1e3:.0f} mm, far longer "
        f"than the {leg_length * 1e3:.0f} mm leg: a guide point may be on another wall"
    )


def learn_path(
    cell: Cell,
    state: CellState,
    guides: Sequence[GuidePoint],
    settings: PathLearningSettings,
    estimator: ForceEstimator,
    *,
    progress: Callable[[float], None] | None = None,
    cancelled: Callable[[], bool] | None = None,
    supervisor: Supervisor | None = None,
    wall_side: WallSideDecision | None = None,
    start_towards_wall: np.ndarray | None = None,
    leg_wander_m: dict[tuple[int, int], float] | None = None,
) -> tuple[Recording, CellState]:
    """Follow the wall along the route through ``guides`` and record it (module docstring).

    The robot first moves above the first guide point in that point's arm configuration, then
    down to it; the force-controlled run starts there and is recorded.

    Supervision (joint limits, singularities, reach, collisions) slows the run near a limit;
    a step that would cross one ends the run there, like the protection rule, with the cause
    in ``stop_reason`` and the place in ``stop``.

    Args:
        wall_side: The side already decided (with the part's mesh, ``resolve_wall_side``);
            default: ``settings.wall_side``, "auto" deciding from the guide points' forces.
        start_towards_wall: (3,) direction from the first guide point to the wall it was taught
            on (from the part's mesh, ``learning_route``); default: the force recorded there
            when it is a push, else across the first leg on the wall's side.
        leg_wander_m: {(i, j): m} how far the wall of the leg from guide point i to j may lead
            the tool off it (the part's mesh, ``learning_route.leg_wander``), where more than
            the default protection allows.

    Returns:
        The recording and the cell state at its end.

    Raises:
        NotEnoughGuidePointsError: fewer than two (distinct) guide points.
        WallSideError: "auto" and the guide points do not tell the side.
        CancelledError: ``cancelled()`` returned True.
        SupervisionError: the approach to the first guide point crosses a limit.
    """
    if len(guides) < 2:
        raise NotEnoughGuidePointsError(
            f"path learning needs at least 2 guide points, got {len(guides)}"
        )
    segs = _segments(guides, settings.closed)
    if not segs:
        raise NotEnoughGuidePointsError("the guide points coincide; record distinct points")
    decision = wall_side or resolve_wall_side(guides, settings.wall_side, closed=settings.closed)
    side = decision.sign
    dt = CONTROL_PERIOD_S
    supervisor = supervisor or cell_supervisor(cell)
    axis = mean_tool_axis(guides)  # Zp: the height axis, into the part

    state = _approach(cell, state, guides, segs[0].a, axis, settings.closed, supervisor=supervisor)

    # Room for the run at the speed it may fall to (the slowest advance near the force limit).
    slowest = min(settings.speed_m_s, settings.search_speed_m_s)
    n_max = int(sum(s.length for s in segs) / slowest / dt * 2.0) + 4000
    record = np.empty((n_max, REC_WIDTH))
    legs = np.array([_leg_row(seg) for seg in segs])
    seg_index = 0
    seg = segs[0]
    leg = legs[0]
    total = len(segs)

    def across(v: np.ndarray) -> np.ndarray:
        return v - axis * float(v @ axis)

    T_ref = state.T_base_tcp.copy()
    w = across(np.cross(axis, seg.xp) * side)
    pushed = across(-np.asarray(guides[0].force_N, dtype=float))
    if start_towards_wall is not None:
        w = across(np.asarray(start_towards_wall, dtype=float))
    elif float(np.linalg.norm(pushed)) >= WALL_FORCE_CLEAR_N and float(pushed @ w) > 0.0:
        w = pushed
    w /= float(np.linalg.norm(w))
    ever_touched = False
    first_touch = T_ref[:3, 3].copy()
    closing_best = math.inf  # closed route: the nearest the last leg came to the first touch
    end_best = math.inf  # the nearest the tool came to this leg's guide point (NEAR_END_M)
    law = initial_state()
    step, turn = np.zeros(3), np.zeros(3)
    leg_travel = 0.0
    t0 = state.time_s
    stop_reason = "reached the last guide point"
    stop_cause = ""
    completed = False
    n = 0
    report_every = max(1, int(1.0 / dt))
    tool_data = estimator.tool_data()
    R_tcp_flange = cell.tool.T_flange_tcp[:3, :3].T.copy()
    penetration_stop = PENETRATION_STOP_FRACTION * cell.tool.radius_m
    params = contour_law_parameters(settings)
    max_turn = TURN_RATE_RAD_S * dt
    force_limit = settings.force_limit_N
    last_leg = total == 1
    wall_wander = leg_wander_m or {}
    wander, detour, leg_end = _leg_limits(seg, wall_wander)
    while True:
        if n >= n_max:
            stop_reason = "stopped: the run took far longer than the program predicts"
            stop_cause = "timeout"
            break
        # --- the controller (measure, the law, record, the turn), compiled ---
        f_abs, touching, ever, searched, off_route, step_len = controller_period(
            state.ft_reading, state.T_base_tcp, state.q_motor, state.time_s - t0, tool_data,
            R_tcp_flange, leg, axis, side, T_ref, w, law, params, max_turn, step, turn, record, n,
        )  # fmt: skip
        if touching and not ever_touched and ever:
            first_touch = state.T_base_tcp[:3, 3].copy()
        ever_touched = ever
        n += 1
        depth = state.contact.depth_m
        if (
            f_abs > force_limit
            or depth > penetration_stop
            or searched > LOST_WALL_M
            or off_route > wander
            or leg_travel > detour
        ):
            stop_cause, stop_reason = _protection_stop(
                settings, f_abs, depth, penetration_stop, searched, off_route, wander,
                leg_travel, seg.length,
            )  # fmt: skip
            break
        # --- supervision (compiled) and the cell ---
        supervised = supervisor.supervise_increment(state.q_motor, T_ref, step, turn)
        if supervised.stop is not None:
            stop_cause = "supervision"
            stop_reason = f"supervision: {supervised.stop.message}"
            break
        T_ref = supervised.T_ref
        leg_travel += step_len * supervised.scale
        state = cell.step(state, supervised.q_next)
        s_now, gap = leg_progress(T_ref, leg, first_touch, axis)
        if last_leg and settings.closed and ever_touched:
            # The loop closes where it first met the wall: past the last leg's half, finish at
            # the nearest approach to that point (no chord across the start).
            if s_now >= 0.5 * seg.length:
                if gap < CLOSE_LOOP_M and gap > closing_best:
                    completed = True
                    break
                closing_best = min(closing_best, gap)
            if s_now >= seg.length + CLOSE_LOOP_OVERRUN_M:
                completed = True  # the wall did not come back within reach of the start
                break
        else:
            passed = False
            if s_now >= max(seg.length - NEAR_END_M, 0.5 * seg.length):
                d_end = float(np.linalg.norm(across(T_ref[:3, 3] - seg.b)))
                passed = end_best < NEAR_END_M and d_end > end_best + END_PASSED_M
                end_best = min(end_best, d_end)
            if last_leg:
                # An open route ends at the tool's nearest approach to its last point: at the
                # point's plane along a straight wall, farther round a curved one (whose chord's
                # plane comes first); past the plane by CLOSE_LOOP_OVERRUN_M if the wall never
                # comes within NEAR_END_M of the point.
                if passed or s_now >= seg.length + CLOSE_LOOP_OVERRUN_M:
                    completed = True
                    break
            elif s_now >= leg_end or passed:
                seg_index += 1
                seg, leg = segs[seg_index], legs[seg_index]
                last_leg = seg_index + 1 >= total
                wander, detour, leg_end = _leg_limits(seg, wall_wander)
                leg_travel = 0.0
                end_best = math.inf
        if n % report_every == 0:
            if cancelled is not None and cancelled():
                raise CancelledError("path learning was cancelled")
            if progress is not None:
                progress(min(1.0, (seg_index + max(0.0, s_now) / seg.length) / total))
    if progress is not None:
        progress(1.0)
    rec = record[:n]
    stop = None
    if not completed:
        p_stop = rec[-1, REC_POSITION : REC_POSITION + 3].copy() if n else T_ref[:3, 3].copy()
        leg_numbers = (seg.first + 1, seg.last + 1)
        positions, yps = rec[:, REC_POSITION : REC_POSITION + 3], rec[:, REC_YP : REC_YP + 3]
        wall = _wall_turn(yps, positions, n, side, axis)
        stop = LearningStop(stop_cause or "stopped", p_stop, leg_numbers, leg_travel, wall)
        stop_reason = (
            f"{stop_reason} at t = {rec[-1, REC_TIME] if n else 0.0:.2f} s, "
            f"{leg_travel * 1e3:.0f} mm along the leg G{leg_numbers[0]} -> G{leg_numbers[1]}, "
            f"where {wall}"
        )

    def columns(start: int, width: int) -> np.ndarray:
        return rec[:, start : start + width].copy()

    return (
        Recording(
            time_s=rec[:, REC_TIME].copy(),
            joints_rad=columns(REC_JOINTS, 6),
            position_m=columns(REC_POSITION, 3),
            quaternion_wxyz=quaternions_from_matrices(
                rec[:, REC_ROTATION : REC_ROTATION + 9].reshape(-1, 3, 3)
            ),
            wrench_sensor=columns(REC_SENSOR, 6),
            wrench_tool=columns(REC_TOOL, 6),
            force_normal_N=rec[:, REC_NORMAL].copy(),
            force_reference_N=np.full(n, settings.force_N),
            in_contact=rec[:, REC_CONTACT] > 0.5,
            yp=columns(REC_YP, 3),
            segment=rec[:, REC_SEGMENT].astype(np.int32),
            stop_reason=stop_reason,
            completed=completed,
            stop=stop,
            wall_side=decision.side,
            wall_side_reason=decision.detail,
        ),
        state,
    )
