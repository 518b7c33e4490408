"""Lead-through: admittance control driven by a push, and the force-control jogging mode.

Chapter section 3.1: the robot is compliant in the directions the operator selects and stiff in
the rest; the operator pushes the tool to where it should be, and sets the orientation with jog
steps about the tool axes (the paper's force-control jogging mode). Because the motion answers
to the measured force, contact with the workpiece pushes back and leading the tool into the part
is safe: the tool stops where the wall's reaction balances the push.

Admittance law per compliant axis i (selected frame): M_i dv_i/dt + D_i v_i = W_push,i + W_c,i,
where W_c is the measured, gravity-compensated contact wrench, both through a small deadband so
sensor noise does not make the robot creep. Stiff axes keep v_i = 0. The
reference pose integrates v; the motor-side joints follow it by one IK step per period.

Every period is supervised (``supervision.Supervisor``): near a joint limit, a singularity, the
edge of reach or an obstacle the motion slows down; a step that would cross one, or that would
make a joint jump (leave the IK's branch), raises ``SupervisionError`` carrying the last safe
state, from which a push or jog the other way moves again. ``touch_off`` is the guarded move
that finds a wall at a set force.
"""

from __future__ import annotations

import functools
import math
from dataclasses import dataclass, field
from typing import Literal, get_args

import numpy as np

from .. import _kernels
from ..errors import InvalidInputError, NoContactError
from ..limits import (
    JOG_RATE_DEG_S,
    JOG_SPEED_MM_S,
    JOG_STEP_MM,
    JOG_TURN_DEG,
    PUSH_DURATION_S,
    TOUCH_OFF_FORCE_N,
    TOUCH_OFF_TRAVEL_MM,
)
from ..transforms import quaternion_from_matrix, rotation_about, unit_vector
from .clock import CONTROL_PERIOD_S
from .sensor import ForceEstimator
from .simulator import Cell, CellState
from .supervision import Supervisor, cell_supervisor, interpolate_pose

Axis = Literal["x", "y", "z", "rx", "ry", "rz"]
AXES: tuple[Axis, ...] = ("x", "y", "z", "rx", "ry", "rz")
_IDENTITY = np.eye(3)
ComplianceFrame = Literal["tool", "base"]
# A jog slowed by supervision may take this many times its nominal periods to complete.
JOG_MAX_PERIODS_FACTOR = 20
# A translational jog's speed when none is given [m/s]: its range's default, which the REST
# API, the workbench and the pendant start their speed fields at too.
JOG_SPEED_M_S = JOG_SPEED_MM_S.default_value() * 1e-3
TOUCH_OFF_DETECT_FRACTION = 0.5  # contact: the wall pushes back with half the set force
TOUCH_OFF_STILL_M_S = 0.0005  # settled: slower than this ...
TOUCH_OFF_STILL_PERIODS = 25  # ... for 0.1 s
TOUCH_OFF_SETTLE_MAX_S = 2.0


@functools.lru_cache(maxsize=64)
def _mask(axes: frozenset[str]) -> np.ndarray:
    mask = np.array([a in axes for a in AXES], dtype=float)
    mask.flags.writeable = False
    return mask


@dataclass(frozen=True)
class ComplianceSelection:
    """Which axes are compliant, and in which frame."""

    axes: frozenset[str] = frozenset({"x", "y", "z"})
    frame: ComplianceFrame = "base"

    def __post_init__(self) -> None:
        unknown = set(self.axes) - set(AXES)
        if unknown:
            raise InvalidInputError(
                f"unknown compliance axes {sorted(unknown)}; use any of {', '.join(AXES)}"
            )
        if self.frame not in get_args(ComplianceFrame):
            raise InvalidInputError(
                f"compliance frame must be 'tool' or 'base', not {self.frame!r}"
            )

    @property
    def mask(self) -> np.ndarray:
        """(6,) 1.0 for compliant axes, 0.0 for stiff ones, in AXES order."""
        return _mask(self.axes)


@dataclass(frozen=True)
class AdmittanceParams:
    """Virtual mass and damping of the admittance, and its speed limits.

    Attributes:
        mass_kg: Virtual mass per translational axis.
        damping_N_s_m: Translational damping: a 10 N push moves the tool at 10 / D m/s.
        inertia_kg_m2: Virtual inertia per rotational axis.
        damping_rot_Nm_s_rad: Rotational damping.
        max_speed_m_s: Translational speed limit (of the speed vector's norm: 50 mm/s in
            every direction, diagonals too).
        max_rate_rad_s: Rotational speed limit (of the angular velocity's norm).
        deadband_N: Forces below this (about 4 sigma of the sensor noise) do not move the robot,
            so it stands still when nobody pushes; larger forces are reduced by it.
        deadband_Nm: The same for torques.
    """

    mass_kg: float = 2.0
    damping_N_s_m: float = 500.0
    inertia_kg_m2: float = 0.05
    damping_rot_Nm_s_rad: float = 10.0
    max_speed_m_s: float = 0.05
    max_rate_rad_s: float = 0.5
    deadband_N: float = 1.0
    deadband_Nm: float = 0.05


@dataclass(frozen=True)
class GuidePoint:
    """A recorded guide point: measured pose, motor-side joints and the time.

    Attributes:
        T_base_tcp: 4x4 TCP pose (from the motor-side joints), metres.
        joints_rad: (6,) motor-side joints.
        time_s: Simulated time of recording.
        force_N: (3,) compensated contact force at recording, base frame (zero when free).
    """

    T_base_tcp: np.ndarray
    joints_rad: np.ndarray
    time_s: float
    force_N: np.ndarray = field(default_factory=lambda: np.zeros(3))

    @property
    def position_m(self) -> np.ndarray:
        return self.T_base_tcp[:3, 3]

    @property
    def quaternion_wxyz(self) -> np.ndarray:
        return quaternion_from_matrix(self.T_base_tcp[:3, :3])


@dataclass(frozen=True)
class LeadThroughState:
    """The cell plus the admittance's own state (reference pose and velocity)."""

    cell: CellState
    T_ref: np.ndarray
    velocity: np.ndarray  # (6,) [v (m/s), omega (rad/s)] in the selection frame


def halted(state: LeadThroughState) -> LeadThroughState:
    """The state held still where it is: reference at the measured pose, no velocity."""
    return LeadThroughState(state.cell, state.cell.T_base_tcp.copy(), np.zeros(6))


class LeadThrough:
    """Admittance controller over a cell; one instance per session (holds the force estimator).

    Args:
        cell: The simulated cell.
        params: Admittance parameters.
        estimator: The controller's gravity/bias compensation; tared on construction.
        supervisor: Joint limits, singularities, reach and collisions (default: the cell's).
    """

    def __init__(
        self,
        cell: Cell,
        params: AdmittanceParams | None = None,
        estimator: ForceEstimator | None = None,
        *,
        supervisor: Supervisor | None = None,
    ) -> None:
        self.cell = cell
        self.supervisor = supervisor or cell_supervisor(cell)
        self.params = params or AdmittanceParams()
        self.estimator = estimator or cell.force_estimator()
        p = self.params
        self._mass = np.array([p.mass_kg] * 3 + [p.inertia_kg_m2] * 3)
        self._damping = np.array([p.damping_N_s_m] * 3 + [p.damping_rot_Nm_s_rad] * 3)
        self._limit = np.array([p.max_speed_m_s] * 3 + [p.max_rate_rad_s] * 3)
        self._deadband = np.array([p.deadband_N] * 3 + [p.deadband_Nm] * 3)

    def start(self, cell_state: CellState, *, tare_samples: int = 50) -> LeadThroughState:
        """Tare the sensor (tool free, robot still) and hold the current pose."""
        readings, rotations = [], []
        state = cell_state
        for _ in range(tare_samples):
            state = self.cell.step(state, state.q_motor)
            readings.append(state.ft_reading)
            rotations.append(self.cell.flange_rotation(state.T_base_tcp))
        if not state.in_contact:
            self.estimator.tare(np.array(readings), np.array(rotations))
        return LeadThroughState(state, state.T_base_tcp.copy(), np.zeros(6))

    def measured_wrench(self, state: CellState) -> np.ndarray:
        """(6,) compensated contact wrench at the TCP, base axes (what the controller knows)."""
        return self.estimator.contact_wrench_tcp_base(
            state.ft_reading, self.cell.flange_rotation(state.T_base_tcp)
        )

    def step(
        self,
        state: LeadThroughState,
        push_wrench: np.ndarray,
        selection: ComplianceSelection,
        dt: float = CONTROL_PERIOD_S,
        *,
        frame_rotation: np.ndarray | None = None,
    ) -> LeadThroughState:
        """One period of admittance control under the push wrench (6,) at the TCP, base axes.

        Supervised: near a limit the motion slows down; a step that would cross one raises
        ``SupervisionError`` carrying the last safe state (``error.state``, held still).
        ``frame_rotation`` (3x3, base frame), when given, is the frame of the selection's axes
        instead of its ``frame`` (a guarded move along any direction).
        """
        return self._advance(
            state, state.T_ref, push_wrench, selection, dt, frame_rotation=frame_rotation
        )[0]

    def _advance(
        self,
        state: LeadThroughState,
        T_ref_in: np.ndarray,
        push_wrench: np.ndarray,
        selection: ComplianceSelection,
        dt: float,
        *,
        frame_rotation: np.ndarray | None = None,
    ) -> tuple[LeadThroughState, float]:
        """One supervised period from reference ``T_ref_in`` (``state.T_ref`` moved by a jog).

        Returns the next state and the speed scale supervision applied (1.0: none).
        """
        if frame_rotation is not None:
            R = frame_rotation
        else:
            R = state.cell.T_base_tcp[:3, :3] if selection.frame == "tool" else _IDENTITY
        w_total = np.asarray(push_wrench, dtype=float) + self.measured_wrench(state.cell)
        # Damping taken implicitly, v+ = (M v + dt W) / (M + D dt): stable against a stiff wall
        # (the contact loop gain k dt^2 / (M + D dt) stays well below 1 at 4 ms).
        T_ref, v = _kernels.admittance_reference(
            T_ref_in,
            np.ascontiguousarray(R),
            state.velocity,
            w_total,
            selection.mask,
            self._mass,
            self._damping,
            self._deadband,
            self._limit,
            dt,
        )
        q = state.cell.q_motor
        robot = self.cell.robot

        def propose(scale: float) -> tuple[np.ndarray, np.ndarray]:
            T = T_ref if scale >= 1.0 else interpolate_pose(state.T_ref, T_ref, scale)
            return T, robot.ik_step(q, T)

        step = self.supervisor.supervise(q, propose)
        if step.stop is not None:
            raise step.stop.error(state=halted(state))
        if step.scale < 1.0:
            v = v * step.scale
        cell_state = self.cell.step(state.cell, step.q_next, dt)
        return LeadThroughState(cell_state, step.T_ref, v), step.scale

    def push(
        self,
        state: LeadThroughState,
        push_wrench: np.ndarray,
        selection: ComplianceSelection,
        duration_s: float,
    ) -> LeadThroughState:
        """Apply a constant push for ``duration_s`` seconds (supervised like ``step``)."""
        if duration_s not in PUSH_DURATION_S:
            raise InvalidInputError(
                f"push duration {duration_s:g} s is outside {PUSH_DURATION_S.text()}"
            )
        w = np.asarray(push_wrench, dtype=float)
        if w.shape != (6,) or not np.all(np.isfinite(w)):
            raise InvalidInputError("push wrench must be 6 finite values [N, N*m]")
        for _ in range(int(round(duration_s / CONTROL_PERIOD_S))):
            state = self.step(state, w, selection)
        return state

    def jog(
        self,
        state: LeadThroughState,
        axis: Axis,
        step: float,
        selection: ComplianceSelection,
        *,
        frame: ComplianceFrame = "tool",
        rate: float | None = None,
        frame_rotation: np.ndarray | None = None,
    ) -> LeadThroughState:
        """Force-control jogging: move the reference by ``step`` (m, or rad for rx/ry/rz).

        The motion runs at ``rate`` (m/s or rad/s; default 10 mm/s or 10 deg/s) while the
        compliant axes keep answering to the measured force, so a jog into the part is safe.
        Near a limit supervision slows it (it still completes the step) and refuses to cross
        it with ``SupervisionError`` (``error.state``: the last safe state). ``frame_rotation``
        (3x3, base frame), when given, is the frame of the axis instead of ``frame`` (e.g. the
        work object's).
        """
        if axis not in AXES:
            raise InvalidInputError(f"jog axis must be one of {', '.join(AXES)}, not {axis!r}")
        if not math.isfinite(step):
            raise InvalidInputError("jog step must be finite")
        rotational = axis.startswith("r")
        if rotational and abs(step) > math.radians(JOG_TURN_DEG.max):
            raise InvalidInputError(
                f"a rotational jog step is at most {JOG_TURN_DEG.max:g} degrees"
            )
        if not rotational and abs(step) > JOG_STEP_MM.max * 1e-3:
            raise InvalidInputError(f"a translational jog step is at most {JOG_STEP_MM.max:g} mm")
        speed = rate or (
            math.radians(JOG_RATE_DEG_S.default_value()) if rotational else JOG_SPEED_M_S
        )
        n = max(1, int(math.ceil(abs(step) / speed / CONTROL_PERIOD_S)))
        unit = {"x": 0, "y": 1, "z": 2}[axis[-1]]
        R_frame = state.cell.T_base_tcp[:3, :3] if frame == "tool" else np.eye(3)
        if frame_rotation is not None:
            R_frame = np.asarray(frame_rotation, dtype=float)
        direction = R_frame[:, unit]
        # Near a limit supervision scales each period's increment down; the jog goes on until
        # the whole step is done (progress counts increments), or the motion is refused.
        progress = 0.0
        for _ in range(JOG_MAX_PERIODS_FACTOR * n):
            if progress >= n - 1e-9:
                break
            fraction = min(1.0, n - progress)
            T_ref = state.T_ref.copy()
            if rotational:
                T_ref[:3, :3] = rotation_about(direction, step / n * fraction) @ T_ref[:3, :3]
            else:
                T_ref[:3, 3] += direction * step / n * fraction
            state, scale = self._advance(state, T_ref, np.zeros(6), selection, CONTROL_PERIOD_S)
            progress += fraction * scale
        return state

    def touch_off(
        self,
        state: LeadThroughState,
        axis: Literal["x", "y", "z"],
        direction: Literal[1, -1],
        force_N: float,
        selection: ComplianceSelection,
        max_travel_m: float,
    ) -> LeadThroughState:
        """Guarded move: push along ``axis`` of the selection's frame until contact at ``force_N``.

        The push ``force_N * direction * axis`` drives the admittance, compliant along that
        axis only (of ``selection.frame``; the other axes are held, so the move stays on its
        line whatever friction does), so the tool travels at (F - deadband) / D until the wall
        pushes back and settles where the contact balances the push (the chapter's "the tool
        tip will yield ... until it reaches the equilibrium"); it then stops there, in
        contact, still pushing: record the guide point next. One action per guide point.

        Raises:
            InvalidInputError: a bad axis, direction, force or travel.
            NoContactError: nothing touched within ``max_travel_m`` (``error.state``: there).
                The other timeout: in contact but still creeping after 2 s returns the state.
            SupervisionError: a limit or an obstacle on the way (``error.state``: before it).
        """
        if axis not in ("x", "y", "z"):
            raise InvalidInputError(f"touch-off axis must be x, y or z, not {axis!r}")
        if direction not in (1, -1):
            raise InvalidInputError("touch-off direction must be +1 or -1")
        self._check_touch(force_N, max_travel_m)
        index = {"x": 0, "y": 1, "z": 2}[axis]
        R_frame = state.cell.T_base_tcp[:3, :3] if selection.frame == "tool" else _IDENTITY
        u = direction * R_frame[:, index]
        moving = ComplianceSelection(frozenset({axis}), selection.frame)
        where = f"{'+' if direction > 0 else '-'}{axis} ({selection.frame} frame)"
        return self._guarded(state, u, force_N, max_travel_m, moving, None, where)

    def touch_off_along(
        self,
        state: LeadThroughState,
        direction: np.ndarray,
        force_N: float,
        max_travel_m: float,
    ) -> LeadThroughState:
        """``touch_off`` along any direction (3,) of the base frame: compliant along it only
        (a frame whose x axis is the direction), the rest held. Work-object calibration
        touches a face along its normal this way, whatever the part's placement.

        Raises:
            InvalidInputError: a direction that is not a finite non-zero vector, a bad force
                or travel.
            NoContactError: nothing touched within ``max_travel_m`` (``error.state``: there).
            SupervisionError: a limit or an obstacle on the way (``error.state``: before it).
        """
        u = unit_vector(np.asarray(direction, dtype=float).reshape(-1), "a touch-off direction")
        self._check_touch(force_N, max_travel_m)
        helper = np.array([0.0, 0.0, 1.0]) if abs(u[2]) < 0.9 else np.array([1.0, 0.0, 0.0])
        y = np.cross(helper, u)
        y /= np.linalg.norm(y)
        frame = np.column_stack([u, y, np.cross(u, y)])
        moving = ComplianceSelection(frozenset({"x"}), "base")
        where = "({:+.2f}, {:+.2f}, {:+.2f}) (base frame)".format(*u)
        return self._guarded(state, u, force_N, max_travel_m, moving, frame, where)

    @staticmethod
    def _check_touch(force_N: float, max_travel_m: float) -> None:
        if force_N not in TOUCH_OFF_FORCE_N:
            raise InvalidInputError(
                f"touch-off force {force_N:g} N is outside {TOUCH_OFF_FORCE_N.text()}"
            )
        travel_max_m = TOUCH_OFF_TRAVEL_MM.max * 1e-3
        if not (math.isfinite(max_travel_m) and 0.0 < max_travel_m <= travel_max_m):
            raise InvalidInputError(f"touch-off travel must be in (0, {travel_max_m * 1e3:g}] mm")

    def _guarded(
        self,
        state: LeadThroughState,
        u: np.ndarray,
        force_N: float,
        max_travel_m: float,
        moving: ComplianceSelection,
        frame: np.ndarray | None,
        where: str,
    ) -> LeadThroughState:
        """The guarded move of ``touch_off`` along the unit vector ``u`` (base frame)."""
        push = np.concatenate([force_N * u, np.zeros(3)])
        start = state.cell.T_base_tcp[:3, 3].copy()
        speed = max(force_N - self.params.deadband_N, 0.1) / self.params.damping_N_s_m
        speed = min(speed, self.params.max_speed_m_s)
        periods = int(math.ceil(1.5 * max_travel_m / speed / CONTROL_PERIOD_S))
        periods += int(TOUCH_OFF_SETTLE_MAX_S / CONTROL_PERIOD_S)
        touched = False
        still = 0
        missed = f"touch-off: no contact within {max_travel_m * 1e3:.1f} mm along {where}"
        for _ in range(periods):
            state = self.step(state, push, moving, frame_rotation=frame)
            f_along = -float(self.measured_wrench(state.cell)[:3] @ u)  # the wall pushes back
            touched = touched or f_along > TOUCH_OFF_DETECT_FRACTION * force_N
            if not touched:
                if float((state.cell.T_base_tcp[:3, 3] - start) @ u) > max_travel_m:
                    raise NoContactError(missed, state=halted(state))
                continue
            speed_now = float(np.linalg.norm(state.velocity[:3]))
            still = still + 1 if speed_now < TOUCH_OFF_STILL_M_S else 0
            if still >= TOUCH_OFF_STILL_PERIODS:
                return state
        if touched:
            return state  # in contact; still settling after TOUCH_OFF_SETTLE_MAX_S
        raise NoContactError(missed, state=halted(state))

    def record(self, state: LeadThroughState) -> GuidePoint:
        """A guide point at the current measured pose."""
        w = self.measured_wrench(state.cell)
        return GuidePoint(
            state.cell.T_base_tcp.copy(), state.cell.q_motor.copy(), state.cell.time_s, w[:3].copy()
        )
