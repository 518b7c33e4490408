"""Automatic path learning (chapter section 3.2): follow the wall at constant contact force.

PROBLEM   The test program (straight lines through the guide points) is far from the real
          contour; the robot must find the contour itself and record it.
STRATEGY  Path frame per segment: Xp along the segment, Zp the tool axis interpolated from the
          guide orientations, Yp = side * (Zp x Xp) towards the wall. Position control along Xp
          at the learning speed and along Zp; PI force control along Yp to the reference force:
              v_y = Kp e + Ki integral(e),  e = F_ref - F_n,
              F_n = |F_contact - (F_contact . Zp) Zp|  while F_y = -(F_contact . Yp) > 0,
              F_n = F_y  otherwise (out of contact, or pressed from the other side),
          i.e. the tool yields into or out of the program path until the wall pushes back with
          F_ref (the chapter: "the tool tip will yield along the Y axis until it reaches the
          equilibrium") normal to the edge (the chapter's "contact force normal to the edge of
          10 N"): where the wall turns away from the program line, its Yp part alone would
          let the whole force grow as F_ref / cos(angle). At a guide point the reference moves
          to the next segment's frame without a jump. The controller sees only motor-side
          joints and the F/T reading.
SOLUTION  ``learn_path(...) -> Recording``: every 4 ms the time, motor-side joints, measured TCP
          pose, sensor and tool-frame wrenches, reference force and a contact flag; the run ends at
          the last guide point, or on the protection rule (contact force above the limit).
"""

from __future__ import annotations

import math
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from typing import Literal

import numpy as np
import pinocchio as pin

from . import _kernels
from .cell import CONTROL_PERIOD_S, Cell, CellState
from .errors import CancelledError, InvalidInputError, NotEnoughGuidePointsError
from .leadthrough import GuidePoint
from .sensor import GRAVITY_M_S2, ForceEstimator
from .supervision import Supervisor, cell_supervisor
from .transforms import (
    cross3,
    matrix_from_quaternion,
    quaternion_from_matrix,
    quaternions_from_matrices,
    slerp,
)

FORCE_RANGE_N = (1.0, 50.0)
SPEED_RANGE_M_S = (0.0005, 0.05)
CONTACT_FLAG_N = 1.0  # a measured contact force above this counts as contact
LOST_WALL_M = 0.03  # protection: the tool left the program path by more than this
# Force-dependent speed (``_speed_ratio``): full speed up to 1.25 F_ref, 10 % from 2 F_ref.
SLOW_FROM, SLOWEST_AT, SLOWEST = 1.25, 2.0, 0.1
MOVE_MAX_PERIODS_FACTOR = 20  # a MoveL slowed by supervision may take this many times longer


def _speed_ratio(f_n: float, f_ref: float) -> float:
    """Share of the learning speed to advance at: 1 up to ``SLOW_FROM`` x F_ref, falling
    linearly to ``SLOWEST`` at ``SLOWEST_AT`` x F_ref. Along a wall that turns steeply away
    from the program line the tool must back off at speed x tan(angle), more than the Yp loop's
    speed limit when learning fast; slowing where the force climbs lets it (the chapter's
    program is likewise "slower at sharp corner")."""
    over = (f_n / f_ref - SLOW_FROM) / (SLOWEST_AT - SLOW_FROM)
    return min(1.0, max(SLOWEST, 1.0 - (1.0 - SLOWEST) * over))


@dataclass(frozen=True)
class PathLearningSettings:
    """Settings of a path-learning run (SI units).

    Attributes:
        force_N: Contact force reference along Yp (the chapter: 10-20 N; 10 N on the pump).
        speed_m_s: Learning speed along Xp (the chapter: 5 mm/s).
        closed: The contour returns from the last guide point to the first.
        wall_side: Side of the wall relative to the travel direction seen along -Zp; "auto"
            reads it from the contact force recorded with the guide points.
        force_limit_N: Protection rule: the run stops when the contact force exceeds this.
        kp_m_s_N: Proportional gain of the Yp force loop.
        ki_m_s2_N: Integral gain of the Yp force loop.
        max_normal_speed_m_s: Speed limit along Yp.
        search_speed_m_s: Speed limit along Yp, and along Xp, while out of contact (searching
            for the wall), so the tool meets it gently instead of at full speed.
    """

    force_N: float = 10.0
    speed_m_s: float = 0.005
    closed: bool = True
    wall_side: Literal["auto", "left", "right"] = "auto"
    force_limit_N: float = 60.0
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
        if self.wall_side not in ("auto", "left", "right"):
            raise InvalidInputError("wall side must be 'auto', 'left' or 'right'")


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
            regulates; see the module docstring).
        force_reference_N: (n,) the reference.
        in_contact: (n,) contact flag (measured force above 1 N).
        yp: (n, 3) the Yp direction in use (for post-processing).
        segment: (n,) index of the program segment.
        stop_reason: Why the run ended.
        completed: True when the run reached its last guide point.
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

    def __len__(self) -> int:
        return len(self.time_s)


@dataclass
class _Segment:
    a: np.ndarray
    b: np.ndarray
    qa: np.ndarray
    qb: np.ndarray
    length: float
    xp: np.ndarray
    Ra: np.ndarray  # orientation at a
    omega: np.ndarray  # rotation vector from Ra to Rb, in the frame of Ra (slerp = Ra exp(f w))


def _segments(guides: Sequence[GuidePoint], closed: bool) -> list[_Segment]:
    points = list(guides) + ([guides[0]] if closed else [])
    segs = []
    for g0, g1 in zip(points[:-1], points[1:], strict=True):
        a, b = g0.position_m.copy(), g1.position_m.copy()
        d = b - a
        length = float(np.linalg.norm(d))
        if length < 1e-4:
            continue  # coincident guide points: nothing to travel
        Ra = matrix_from_quaternion(g0.quaternion_wxyz)
        Rb = matrix_from_quaternion(g1.quaternion_wxyz)
        segs.append(
            _Segment(
                a,
                b,
                g0.quaternion_wxyz,
                g1.quaternion_wxyz,
                length,
                d / length,
                Ra,
                pin.log3(Ra.T @ Rb),
            )
        )
    return segs


def _wall_side(guides: Sequence[GuidePoint], segs: list[_Segment], setting: str) -> float:
    """+1 when the wall is on the right of travel (Yp = Zp x Xp ... seen with Zp into the part)."""
    if setting == "right":
        return 1.0
    if setting == "left":
        return -1.0
    votes = 0.0
    for g, seg in zip(guides, segs, strict=False):
        zp = matrix_from_quaternion(g.quaternion_wxyz)[:, 2]
        yp_right = cross3(zp, seg.xp)
        # The wall pushes the tool away from itself: force . Yp < 0 when Yp points at the wall.
        votes += -float(g.force_N @ yp_right)
    if abs(votes) < 1e-6:
        raise InvalidInputError(
            "cannot tell on which side the wall is: record guide points in contact with the wall "
            "or set wall_side to 'left' or 'right'"
        )
    return 1.0 if votes > 0 else -1.0


def move_linear(
    cell: Cell,
    state: CellState,
    T_target: np.ndarray,
    speed_m_s: float = 0.05,
    *,
    supervisor: Supervisor | None = None,
) -> CellState:
    """Position-controlled straight move (MoveL) of the TCP to ``T_target``; no force control.

    Supervised: the move slows near a limit and raises ``SupervisionError`` (carrying the last
    safe cell state) before crossing one.
    """
    supervisor = supervisor or cell_supervisor(cell)
    T0 = state.T_base_tcp.copy()
    q0 = quaternion_from_matrix(T0[:3, :3])
    q1 = quaternion_from_matrix(T_target[:3, :3])
    dist = float(np.linalg.norm(T_target[:3, 3] - T0[:3, 3]))
    n = max(1, int(math.ceil(dist / speed_m_s / CONTROL_PERIOD_S)))
    robot = cell.robot
    progress = 0.0  # periods' worth of motion done (a slowed period counts its scale)
    settle = 0
    for _ in range(MOVE_MAX_PERIODS_FACTOR * n + 10):
        if progress >= n and settle >= 10:
            break
        base = progress
        step = min(1.0, n - progress) if progress < n else 0.0
        q = state.q_motor

        def propose(
            scale: float, base: float = base, step: float = step, q: np.ndarray = q
        ) -> tuple[np.ndarray, np.ndarray]:
            f = min(1.0, (base + scale * step) / n)
            T = np.eye(4)
            T[:3, :3] = matrix_from_quaternion(slerp(q0, q1, f))
            T[:3, 3] = T0[:3, 3] + f * (T_target[:3, 3] - T0[:3, 3])
            return T, robot.ik_step(q, T)

        supervised = supervisor.supervise(q, propose)
        if supervised.stop is not None:
            raise supervised.stop.error(state=state)
        state = cell.step(state, supervised.q_next)
        progress += supervised.scale * step
        if step == 0.0:  # at the target: settling periods
            settle += 1
    return state


def learn_path(
    cell: Cell,
    state: CellState,
    guides: Sequence[GuidePoint],
    settings: PathLearningSettings,
    estimator: ForceEstimator,
    *,
    progress: Callable[[float], None] | None = None,
    cancelled: Callable[[], bool] | None = None,
    approach_height_m: float = 0.010,
    supervisor: Supervisor | None = None,
) -> tuple[Recording, CellState]:
    """Run the test program through ``guides`` under Yp force control and record it.

    The robot first moves (position control) above the first guide point, down beside it, a
    little away from the wall, then the force-controlled run starts and is recorded.

    Supervision (joint limits, singularities, reach, collisions) slows the run near a limit;
    a step that would cross one ends the run there, like the protection rule, with the cause
    in ``stop_reason``.

    Returns:
        The recording and the cell state at its end.

    Raises:
        NotEnoughGuidePointsError: fewer than two (distinct) guide points.
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
    side = _wall_side(guides, segs, settings.wall_side)
    robot = cell.robot
    dt = CONTROL_PERIOD_S
    supervisor = supervisor or cell_supervisor(cell)

    def frame(seg: _Segment, fraction: float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """(R, Yp, Zp) of the path frame at ``fraction`` of a segment."""
        T, yp, zp = _kernels.path_reference(
            seg.Ra, seg.omega, fraction, seg.a, seg.xp, side, 0.0, 0.0, 0.0
        )
        return T[:3, :3], yp, zp

    # Approach: above the first guide point, then down to it, 1.5 mm away from the wall.
    R0, yp0, _ = frame(segs[0], 0.0)
    start = segs[0].a - 0.0015 * yp0
    above = np.eye(4)
    above[:3, :3] = R0
    above[:3, 3] = start - R0[:, 2] * approach_height_m
    state = move_linear(cell, state, above, supervisor=supervisor)
    at_start = above.copy()
    at_start[:3, 3] = start
    state = move_linear(cell, state, at_start, 0.01, supervisor=supervisor)

    # Room for the run at the speed it may fall to out of contact (the search speed).
    slowest = min(settings.speed_m_s, settings.search_speed_m_s)
    n_max = int(sum(s.length for s in segs) / slowest / dt * 1.6) + 2000
    cols = {
        "time_s": np.empty(n_max),
        "joints_rad": np.empty((n_max, 6)),
        "position_m": np.empty((n_max, 3)),
        "rotation": np.empty((n_max, 3, 3)),
        "wrench_sensor": np.empty((n_max, 6)),
        "wrench_tool": np.empty((n_max, 6)),
        "force_normal_N": np.empty(n_max),
        "in_contact": np.empty(n_max, dtype=bool),
        "yp": np.empty((n_max, 3)),
        "segment": np.empty(n_max, dtype=np.int32),
    }
    seg_index = 0
    seg = segs[0]
    rel = state.T_base_tcp[:3, 3] - seg.a
    s = float(rel @ seg.xp)
    R, yp, zp = frame(seg, s / seg.length)
    y = float(rel @ yp)
    h = float(rel @ zp)
    integral = 0.0
    t0 = state.time_s
    stop_reason = "reached the last guide point"
    completed = False
    n = 0
    report_every = max(1, int(1.0 / dt))
    total = len(segs)
    vmax = settings.max_normal_speed_m_s
    weight = estimator.mass_kg * GRAVITY_M_S2
    com, tcp, bias = estimator.com_m, estimator.tcp_m, estimator.bias
    lower, upper = robot.lower_rad, robot.upper_rad
    times, joints, positions = cols["time_s"], cols["joints_rad"], cols["position_m"]
    rotations, sensor, tool = cols["rotation"], cols["wrench_sensor"], cols["wrench_tool"]
    normal, contact, yps, segment = (
        cols["force_normal_N"],
        cols["in_contact"],
        cols["yp"],
        cols["segment"],
    )
    kp, ki, speed, f_ref = (
        settings.kp_m_s_N,
        settings.ki_m_s2_N,
        settings.speed_m_s,
        settings.force_N,
    )
    search = settings.search_speed_m_s
    while True:
        if n >= n_max:
            stop_reason = "stopped: the run took far longer than the program predicts"
            break
        # --- measure (controller side: motor-side pose and the F/T reading) ---
        T_meas = state.T_base_tcp
        R_meas = T_meas[:3, :3]
        w_base = _kernels.contact_wrench_tcp_base(
            state.ft_reading, cell.flange_rotation(T_meas), weight, com, tcp, bias
        )
        fx, fy, fz = w_base[0], w_base[1], w_base[2]
        f_y = -(fx * yp[0] + fy * yp[1] + fz * yp[2])
        f_abs = math.sqrt(fx * fx + fy * fy + fz * fz)
        f_z = fx * zp[0] + fy * zp[1] + fz * zp[2]
        # The force normal to the edge: the contact force across the tool axis. Where the wall
        # is at an angle theta to the program line (a boss between two guide points) its Yp
        # part is only cos(theta) of it, and holding that part at F_ref pressed with
        # F_ref / cos(theta): 58 N at 20 N on the water pump's bosses, tripping the protection.
        f_n = math.sqrt(max(f_abs * f_abs - f_z * f_z, 0.0)) if f_y > 0.0 else f_y
        # --- record ---
        times[n] = state.time_s - t0
        joints[n] = state.q_motor
        positions[n] = T_meas[:3, 3]
        rotations[n] = R_meas
        sensor[n] = state.ft_reading
        tool[n, :3] = R_meas.T @ w_base[:3]
        tool[n, 3:] = R_meas.T @ w_base[3:]
        normal[n] = f_n
        contact[n] = f_abs > CONTACT_FLAG_N
        yps[n] = yp
        segment[n] = seg_index
        n += 1
        if f_abs > settings.force_limit_N:
            stop_reason = (
                f"protection: contact force {f_abs:.1f} N exceeded the "
                f"{settings.force_limit_N:g} N limit at t = {state.time_s - t0:.2f} s"
            )
            break
        if abs(y) > LOST_WALL_M:
            stop_reason = (
                f"protection: the tool moved {abs(y) * 1e3:.0f} mm off the program path without "
                "finding the wall"
            )
            break
        # --- force control along Yp, position along Xp and Zp ---
        e = f_ref - f_n
        limit = vmax if f_abs > CONTACT_FLAG_N else search
        integral = min(max(integral + ki * e * dt, -limit), limit)
        v_y = min(max(kp * e + integral, -vmax), limit)
        s_base, y_base, h_base = s, y, h
        y += v_y * dt
        # Out of contact the tool advances no faster than it searches sideways: racing blind
        # along the program line at 20-50 mm/s it met the bosses head-on (60-120 N).
        advance = speed if f_abs > CONTACT_FLAG_N else min(speed, search)
        s += advance * _speed_ratio(f_n, f_ref) * dt
        h *= 0.99  # fade any height offset left by a segment change (~1 s)
        if s >= seg.length:
            if seg_index + 1 >= total:
                completed = True
                break
            p_ref = seg.a + s * seg.xp + y * yp + h * zp
            seg_index += 1
            seg = segs[seg_index]
            rel = p_ref - seg.a
            s = float(rel @ seg.xp)
            _, yp, zp = frame(seg, s / seg.length)
            y = float(rel @ yp)
            h = float(rel @ zp)
            s_base, y_base, h_base = s, y, h  # a new segment's first period is not scaled
        # --- supervision: slow near a limit (scale this period's motion), stop before it ---
        q_now = state.q_motor

        def propose(
            scale: float,
            seg: _Segment = seg,
            sb: float = s_base,
            yb: float = y_base,
            hb: float = h_base,
            s1: float = s,
            y1: float = y,
            h1: float = h,
            q_now: np.ndarray = q_now,
        ) -> tuple[np.ndarray, np.ndarray]:
            ss, yy, hh = (
                (s1, y1, h1)
                if scale >= 1.0
                else (sb + scale * (s1 - sb), yb + scale * (y1 - yb), hb + scale * (h1 - hb))
            )
            T_ref, _, _ = _kernels.path_reference(
                seg.Ra, seg.omega, ss / seg.length, seg.a, seg.xp, side, ss, yy, hh
            )
            T_now, J = robot.fk_and_jacobian(q_now)
            return T_ref, _kernels.ik_newton_step(q_now, T_now, J, T_ref, lower, upper, 1e-4)

        supervised = supervisor.supervise(q_now, propose)
        if supervised.stop is not None:
            stop_reason = f"supervision: {supervised.stop.message}"
            break
        if supervised.scale < 1.0:
            s = s_base + supervised.scale * (s - s_base)
            y = y_base + supervised.scale * (y - y_base)
            h = h_base + supervised.scale * (h - h_base)
        _, yp, zp = _kernels.path_reference(
            seg.Ra, seg.omega, s / seg.length, seg.a, seg.xp, side, s, y, h
        )
        state = cell.step(state, supervised.q_next)
        if n % report_every == 0:
            if cancelled is not None and cancelled():
                raise CancelledError("path learning was cancelled")
            if progress is not None:
                progress(min(1.0, (seg_index + s / seg.length) / total))
    if progress is not None:
        progress(1.0)
    rotations = cols.pop("rotation")[:n]
    rec = Recording(
        **{k: v[:n].copy() for k, v in cols.items()},
        quaternion_wxyz=quaternions_from_matrices(rotations),
        force_reference_N=np.full(n, settings.force_N),
        stop_reason=stop_reason,
        completed=completed,
    )
    return rec, state
