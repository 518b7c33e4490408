"""A person's motions of the robot: paced pushes, jogs and touch-offs, and what the tool sees.

PROBLEM   The simulation runs some twenty times faster than real time, so a person's 2 s push
          was answered in milliseconds and a held button ran the arm into a singularity; a
          refused motion must leave the robot at its last safe state and say why; and reads
          (the GUIs' live pose) must never wait for a motion to finish.
STRATEGY  Every motion drives the core's own loop (``LeadThrough.push``, ``jog``,
          ``touch_off``) through a tapped cell (``live.TappedCell``): each control period the
          tap takes one period of the session's ``RealTimePacer`` budget (sleeping when it is
          empty, with the session lock released), publishes the live pose every
          ``LIVE_NOTIFY_S``, and aborts when the person lets go (``stop``), when the cell
          changes, or when the session closes. Motions run one at a time (a short queue: a
          request that waits longer than ``MOTION_QUEUE_S`` is refused), so a flood of
          requests cannot bank simulated time: over a wall interval T all of them together
          simulate at most T + burst (20 ms).
SOLUTION  ``Teach(robot, real_time=True)`` over the session's ``LiveRobot``: ``push``,
          ``jog(axis, step, frame, speed)``, ``touch_off(axis, direction, force_N,
          max_travel_m, frame)``, ``touch_along`` (calibration's touches) and ``move_to``
          (each answers the robot's snapshot after it),
          ``stop()``, and ``tool_view()`` (gap to the nearest face of the part, contact force,
          height above the table). A ``SupervisionError`` keeps the robot at ``error.state``
          (the last safe state), saves it and is raised again (the API answers 409).
"""

from __future__ import annotations

import threading
import time
from collections.abc import Callable
from dataclasses import dataclass
from typing import TYPE_CHECKING, Literal

import numpy as np

from robomach_core import limits
from robomach_core.cell import (
    AXES,
    CONTROL_PERIOD_S,
    Cell,
    CellState,
    ClearanceProbe,
    ComplianceFrame,
    ComplianceSelection,
    LeadThrough,
    LeadThroughState,
    RealTimePacer,
    halted,
)
from robomach_core.choices import JOG_FRAMES, LABELS, TOUCH_AXES, JogFrame, NearestFace, TouchAxis
from robomach_core.errors import (
    ContactStopError,
    InvalidInputError,
    NoContactError,
    SupervisionError,
)
from robomach_core.part import mesh_query
from robomach_core.teaching import Arrival, go_to_point
from robomach_core.transforms import unit_vector

from .live import tapped_cell
from .records import LIVE_NOTIFY_S, BusyError, ConflictError, RobotSnapshot

if TYPE_CHECKING:
    from .robot import LiveRobot

Selection = ComplianceSelection
MOTION_QUEUE_S = 0.25  # a motion request waits at most this long for the one before it
# The pacer's burst: how far a motion may run ahead of the clock after an idle while. Small, so
# that back-to-back requests (a held button, two clients) add almost nothing to the held time.
PACE_BURST_S = 0.02
PACE_CHUNK_PERIODS = 5
# A push is a hand pushing during [arrival, arrival + duration]: a request that waited for the
# one before it (another client, a held button's next push) loses the time it waited, beyond
# this much (the scheduling of the request itself).
PUSH_GRACE_S = 0.01  # budget taken at once (20 ms): the stop check still runs every period
JOG_CONTACT_N = 3.0  # a jog ending against the part with more than this ...
JOG_SHORT_M = 5e-4  # ... and short of its step by more than this was stopped by contact
# "along -y (work-object frame)": the menu's words, as a compound adjective
FRAME_NAMES = {frame: words.replace(" ", "-") for frame, words in LABELS["jog_frame"].items()}


class _Stopped(Exception):
    """The person let go (or the cell changed): end the motion where it is."""


@dataclass(frozen=True)
class ToolView:
    """What the operator sees at the tool tip (base frame, SI units).

    Attributes:
        gap_m: Signed distance of the cutter to the nearest face of the part (< 0: in contact).
        normal: (3,) unit vector from that face towards the cutter.
        force_N: (3,) measured, compensated contact force at the TCP.
        table_gap_m: Height of the cutter's lowest point above the table.
        in_contact: The cutter touches the part.
        face: What the nearest face is: "wall", "floor" (faces up) or "underside".
        wall_gap_m: Gap of the cutter to the nearest wall at the tool's height (the
            wall it works on; across, as a touch-off towards it goes), None when no wall is
            there (above the part).
    """

    gap_m: float
    normal: np.ndarray
    force_N: np.ndarray
    table_gap_m: float
    in_contact: bool
    face: NearestFace = "wall"
    wall_gap_m: float | None = None


def frame_rotation(frame: JogFrame, T_base_tcp: np.ndarray, T_base_wobj: np.ndarray) -> np.ndarray:
    """3x3 rotation of the jog frame in the base frame (its columns: the x, y, z axes)."""
    if frame == "base":
        return np.eye(3)
    if frame == "tool":
        return np.asarray(T_base_tcp[:3, :3], dtype=float)
    if frame == "wobj":
        return np.asarray(T_base_wobj[:3, :3], dtype=float)
    raise InvalidInputError(f"jog frame must be one of {', '.join(JOG_FRAMES)}, not {frame!r}")


class Teach:
    """The paced motions of one session (see the module docstring).

    Args:
        robot: The session's robot.
        real_time: Pace motions to the wall clock (a person at a pendant); False runs them as
            fast as the simulation allows (scripts and in-process tests).
    """

    def __init__(self, robot: LiveRobot, *, real_time: bool = True) -> None:
        self._robot = robot
        self.pacer = RealTimePacer(burst_s=PACE_BURST_S) if real_time else None
        self._motion = threading.Lock()
        self._stop_generation = 0
        self._probe: tuple[int, ClearanceProbe] | None = None
        self._walls: dict[int, list] = {}  # wall sections of the mesh by 0.1 mm of height
        # Listeners (the viser scene) redraw in their own thread: never slow the motion down.
        self._notifier = _Coalescer(lambda: robot.notify("robot"))

    # --- motions -----------------------------------------------------------------------------

    def push(self, wrench: np.ndarray, duration_s: float) -> RobotSnapshot:
        """A constant push (6,) [N, N*m] at the TCP, base axes, for ``duration_s`` of wall time
        under admittance control on the compliant axes; the force's and the torque's
        magnitudes and the duration within ``limits.PUSH_FORCE_N``, ``PUSH_TORQUE_NM`` and
        ``PUSH_DURATION_S``."""
        w = np.asarray(wrench, dtype=float)
        if w.shape != (6,) or not np.all(np.isfinite(w)):
            raise InvalidInputError("a push is 6 finite values: force [N] and torque [N*m]")
        limits.PUSH_FORCE_N.check(float(np.linalg.norm(w[:3])), "push force magnitude [N]")
        limits.PUSH_TORQUE_NM.check(float(np.linalg.norm(w[3:])), "push torque magnitude [N*m]")
        limits.PUSH_DURATION_S.check(duration_s, "push duration [s]")
        arrival = time.monotonic()

        def move(lt: LeadThrough, st: LeadThroughState, sel: Selection) -> LeadThroughState:
            late_s = max(0.0, time.monotonic() - arrival - PUSH_GRACE_S)
            left_s = duration_s - late_s
            return lt.push(st, w, sel, left_s) if left_s >= CONTROL_PERIOD_S else st

        self._run(move)
        return self._robot.snapshot()

    def jog(
        self,
        axis: str,
        step: float,
        *,
        frame: JogFrame = "tool",
        speed: float | None = None,
    ) -> RobotSnapshot:
        """Force-control jogging: move ``step`` [m] along, or [rad] about, an axis of ``frame``
        (tool, base or wobj) at ``speed`` [m/s or rad/s] (default 10 mm/s, 10 deg/s); the
        compliant axes keep answering to the contact force."""
        if axis not in AXES:
            raise InvalidInputError(f"jog axis must be one of {', '.join(AXES)}, not {axis!r}")
        if frame not in JOG_FRAMES:
            raise InvalidInputError(
                f"jog frame must be one of {', '.join(JOG_FRAMES)}, not {frame!r}"
            )
        rotational = axis.startswith("r")
        if speed is not None:
            rng = limits.JOG_RATE_DEG_S if rotational else limits.JOG_SPEED_MM_S
            scale = 180.0 / np.pi if rotational else 1e3
            if speed * scale not in rng:
                raise InvalidInputError(
                    f"jog speed {speed * scale:g} {rng.unit} is outside {rng.text()}"
                )
        wobj = self._robot.workpiece.T_base_wobj
        step = float(step)
        before: list[np.ndarray] = []

        def move(lt: LeadThrough, st: LeadThroughState, sel: Selection) -> LeadThroughState:
            R = frame_rotation(frame, st.cell.T_base_tcp, wobj)
            before.append(R[:, "xyz".index(axis[-1])].copy())
            before.append(st.cell.T_base_tcp.copy())
            return lt.jog(st, axis, float(step), sel, rate=speed, frame_rotation=R)

        self._run(move)
        if before and not rotational:
            self._say_if_stopped_by_contact(before[1], before[0] * float(step), axis, frame)
        return self._robot.snapshot()

    def _say_if_stopped_by_contact(
        self, T_before: np.ndarray, delta: np.ndarray, axis: str, frame: JogFrame
    ) -> None:
        """Raise ``ContactStopError`` when a jog ended short of its step against the part
        (the robot stays where it stopped; before, it stopped there silently at 30-50 N)."""
        snap = self._robot.snapshot()
        force = float(np.linalg.norm(snap.wrench[:3]))
        step = float(np.linalg.norm(delta))
        done = float((snap.position_m - T_before[:3, 3]) @ delta) / step if step > 0 else 1.0
        if force > JOG_CONTACT_N and step - done > JOG_SHORT_M:
            sign = "+" if (delta @ frame_rotation(frame, T_before,
                           self._robot.workpiece.T_base_wobj)[:, "xyz".index(axis)]) > 0 \
                else "-"  # fmt: skip
            raise ContactStopError(
                f"the jog along {sign}{axis} ({FRAME_NAMES[frame]} frame) stopped against the "
                f"part after {max(done, 0.0) * 1e3:.1f} of {step * 1e3:.1f} mm, pressing with "
                f"{force:.0f} N: jog back, or use a touch-off to meet a wall"
            )

    def touch_off(
        self,
        axis: TouchAxis,
        direction: Literal[1, -1],
        force_N: float,
        max_travel_m: float,
        *,
        frame: JogFrame = "base",
    ) -> RobotSnapshot:
        """Guarded move along ``axis`` of ``frame`` until the wall pushes back with ``force_N``
        (``LeadThrough.touch_off``); the robot stays there, in contact. A work-object frame is
        taken as the base axis it is aligned with (refused when it is turned otherwise)."""
        if axis not in TOUCH_AXES:
            raise InvalidInputError(
                f"touch-off axis must be one of {', '.join(TOUCH_AXES)}, not {axis!r}"
            )
        if direction not in (1, -1):
            raise InvalidInputError("touch-off direction must be +1 or -1")
        core_frame: ComplianceFrame = "tool" if frame == "tool" else "base"
        asked_axis, asked_direction = axis, direction
        if frame == "wobj":
            axis, direction = _base_axis_of_wobj(self._robot.workpiece.T_base_wobj, axis,
                                                 direction)  # fmt: skip
        elif frame not in JOG_FRAMES:
            raise InvalidInputError(
                f"touch-off frame must be one of {', '.join(JOG_FRAMES)}, not {frame!r}"
            )

        named = (asked_axis, asked_direction, frame)

        def move(lt: LeadThrough, st: LeadThroughState, sel: Selection) -> LeadThroughState:
            moving = ComplianceSelection(sel.axes, core_frame)
            return lt.touch_off(st, axis, direction, float(force_N), moving, float(max_travel_m))

        try:
            self._run(move)
        except NoContactError as exc:  # said in the frame the user chose
            a, d, f = named
            raise NoContactError(
                f"touch-off: no contact within {max_travel_m * 1e3:.1f} mm along "
                f"{'+' if d > 0 else '-'}{a} ({FRAME_NAMES[f]} frame)",
                state=exc.state,
            ) from None
        return self._robot.snapshot()

    def touch_along(
        self,
        direction: np.ndarray,
        force_N: float,
        max_travel_m: float,
        *,
        back_off: bool = True,
    ) -> tuple[CellState, np.ndarray]:
        """Guarded move along ``direction`` (3,) of the base frame until the part pushes back
        with ``force_N`` (``LeadThrough.touch_off_along``), then, with ``back_off``, back to
        where it started (a stiff jog). Returns the cell where it touched and the measured
        contact wrench there (6,), base axes. Work-object calibration touches this way."""
        from robomach_core.teaching import move_by

        d = np.asarray(direction, dtype=float)
        unit_vector(d, "a touch direction")  # refused here as the touch-off would, before it
        limits.TOUCH_OFF_FORCE_N.check(force_N, "touch force [N]")
        if not (np.isfinite(max_travel_m) and max_travel_m * 1e3 in limits.TOUCH_OFF_TRAVEL_MM
                and max_travel_m > 0):  # fmt: skip
            raise InvalidInputError(
                f"touch travel must be within (0, {limits.TOUCH_OFF_TRAVEL_MM.max:g}] mm"
            )
        found: list[tuple[CellState, np.ndarray]] = []

        def move(lt: LeadThrough, st: LeadThroughState, sel: Selection) -> LeadThroughState:
            start = st.cell.T_base_tcp[:3, 3].copy()
            st = lt.touch_off_along(st, d, float(force_N), float(max_travel_m))
            found.append((st.cell, lt.measured_wrench(st.cell)))
            if back_off:
                st = move_by(lt, st, start - st.cell.T_base_tcp[:3, 3], 0.02)
            return st

        self._run(move)
        if not found:  # let go (or the cell changed) on the way
            raise ConflictError("the touch was stopped before it met the part")
        return found[0]

    def move_to(
        self, T_base_tcp: np.ndarray, *, safe_z_m: float, entry_m: np.ndarray | None = None
    ) -> Arrival:
        """Take the tool to ``T_base_tcp``: up to ``safe_z_m``, turned, over and down into
        place (``teach_motion.go_to_point``), paced and supervised like a jog. Returns where it
        stopped (against the part when it is not where its mesh is)."""
        T = np.asarray(T_base_tcp, dtype=float)
        if T.shape != (4, 4) or not np.all(np.isfinite(T)):
            raise InvalidInputError("a target pose is a finite 4x4 transform")
        arrival: list[Arrival] = []

        def move(lt: LeadThrough, st: LeadThroughState, sel: Selection) -> LeadThroughState:
            end, got = go_to_point(lt, st, T, safe_z_m=safe_z_m, entry_m=entry_m)
            arrival.append(got)
            return end

        self._run(move)
        if not arrival:  # let go (or the cell changed) on the way
            raise ConflictError("the move to the taught point was stopped before it arrived")
        return arrival[0]

    def stop(self) -> None:
        """End the running motion (the person let go); it stops within one control period."""
        self._stop_generation += 1

    # --- what the tool sees ------------------------------------------------------------------

    def tool_view(self) -> ToolView:
        """Gap to the nearest face of the part, contact force and table clearance, now."""
        pose = self._robot.pose()
        epoch, cell = pose.epoch, pose.cell
        snap = self._robot.snapshot()
        if self._probe is None or self._probe[0] != epoch:
            # The mesh the user sees (the real part would tell what no real cell knows).
            self._probe = (epoch, ClearanceProbe(cell.tool, cell.workpiece.cad()))
            self._walls = {}
        probe = self._probe[1]
        table_z = float(pose.leadthrough.supervisor.table_z_m)
        # The probe's coal objects and the mesh's section serve one thread at a time (the
        # pendant polls this while viser's panel does).
        with mesh_query.LOCK:
            gap = probe.gap(snap.T_base_tcp)
            wall_gap = self._wall_gap(cell, snap.T_base_tcp[:3, 3])
        nz = float(gap.normal[2])
        face: NearestFace = "floor" if nz > 0.7 else "underside" if nz < -0.7 else "wall"
        return ToolView(
            float(gap.distance_m),
            gap.normal,
            snap.wrench[:3].copy(),
            probe.height_above_m(snap.T_base_tcp, table_z),
            snap.in_contact,
            face,
            wall_gap,
        )

    def _wall_gap(self, cell: Cell, p_base: np.ndarray) -> float | None:
        """The cutter's gap to the nearest wall of the mesh at the TCP's height (the section
        there, kept per 0.1 mm of height)."""
        from robomach_core.learning.walls import section_loops

        cad = cell.workpiece.cad()
        T = cad.T_base_wobj
        p = (np.asarray(p_base) - T[:3, 3]) @ T[:3, :3]
        key = round(float(p[2]) * 1e4)
        walls = self._walls
        if key not in walls:
            if len(walls) > 64:
                walls.clear()
            walls[key] = section_loops(cad.mesh, key * 1e-4)
        loops = walls[key]
        if not loops:
            return None
        d = min(abs(float(lp.signed_distance(p[None, :2])[0])) for lp in loops)
        return d - cell.tool.radius_m

    # --- internals ---------------------------------------------------------------------------

    def _run(
        self,
        move: Callable[[LeadThrough, LeadThroughState, ComplianceSelection], LeadThroughState],
    ) -> None:
        """Run ``move`` paced, published and stoppable (one motion at a time)."""
        robot = self._robot
        if not self._motion.acquire(timeout=MOTION_QUEUE_S):
            raise BusyError(
                "another push, jog or touch-off is still moving the robot; wait for it "
                "(or let go of the other button)"
            )
        try:
            pose = robot.idle_pose()
            generation = self._stop_generation  # a stop from now on stops this motion
            epoch, start, selection, lt = pose.epoch, pose.state, pose.selection, pose.leadthrough
            last: list[CellState] = [start.cell]
            credit = 0
            last_notify = time.monotonic()

            def tap(cell_state: CellState) -> None:
                nonlocal credit, last_notify
                last[0] = cell_state
                if self._stop_generation != generation or robot.epoch != epoch or robot.closed:
                    raise _Stopped
                if self.pacer is not None:
                    while credit == 0:
                        credit = self.pacer.grant(PACE_CHUNK_PERIODS)
                        if credit == 0:
                            time.sleep(max(self.pacer.wait_s(1), CONTROL_PERIOD_S / 2))
                            if self._stop_generation != generation or robot.epoch != epoch:
                                raise _Stopped
                    credit -= 1
                now = time.monotonic()
                if now - last_notify >= LIVE_NOTIFY_S:
                    last_notify = now
                    robot.show(cell_state, epoch)
                    self._notifier.poke()

            tapped = LeadThrough(
                tapped_cell(lt.cell, tap),
                lt.params,
                lt.estimator,
                supervisor=lt.supervisor,
            )
            error: Exception | None = None
            try:
                end = move(tapped, start, selection)
            except _Stopped:
                end = halted(LeadThroughState(last[0], last[0].T_base_tcp, np.zeros(6)))
            except (SupervisionError, NoContactError) as exc:
                state = exc.state
                end = (
                    state
                    if isinstance(state, LeadThroughState)
                    else halted(LeadThroughState(last[0], last[0].T_base_tcp, np.zeros(6)))
                )
                error = exc
            robot.settle(end, epoch)
            if error is not None:
                raise error
        finally:
            self._motion.release()


def _base_axis_of_wobj(
    T_base_wobj: np.ndarray, axis: str, direction: int
) -> tuple[TouchAxis, Literal[1, -1]]:
    """The base axis and sign a work-object axis is aligned with (within 0.1 degree)."""
    column = np.asarray(T_base_wobj[:3, "xyz".index(axis)], dtype=float) * direction
    i = int(np.argmax(np.abs(column)))
    if abs(column[i]) < np.cos(np.radians(0.1)):
        raise InvalidInputError(
            "a touch-off in the work-object frame needs the work object aligned with the base "
            "axes; use the base or tool frame"
        )
    return TOUCH_AXES[i], (1 if column[i] > 0 else -1)


class _Coalescer:
    """Calls ``action`` in a daemon thread after ``poke`` (pokes meanwhile: one more call)."""

    def __init__(self, action: Callable[[], None]) -> None:
        self._action = action
        self._wanted = threading.Event()
        self._thread: threading.Thread | None = None
        self._lock = threading.Lock()

    def poke(self) -> None:
        self._wanted.set()
        with self._lock:
            if self._thread is None or not self._thread.is_alive():
                self._thread = threading.Thread(target=self._loop, name="teach-notify", daemon=True)
                self._thread.start()

    def _loop(self) -> None:
        while self._wanted.wait(timeout=5.0):
            self._wanted.clear()
            self._action()
