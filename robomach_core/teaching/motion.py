"""Taking the tool to a taught place by a supervised motion: up, over, turn, and down.

PROBLEM   Click-to-teach puts the tool beside a wall, in a groove, from wherever it stands. A
          straight line there may cross the part; the whole motion must stay under the
          controller's supervision (limits, singularities, collisions), as jogging does; and
          when the part is not where its CAD says, the tool must meet it gently and say so
          instead of pressing on.
STRATEGY  Jogs (``LeadThrough.jog``, stiff, supervised) lift the tool to a safe height above the
          part, turn it to the taught orientation (steps of at most 45 deg about the rotation's
          axis) and carry it over the point; the last part, down into the groove, is a push
          through the admittance (the scripted operator's hand, ``demo_operator.push_to``) with
          the three translations compliant: a wall in the way pushes back and the tool stops
          against it.
SOLUTION  ``go_to_point(lt, state, T_target, safe_z_m=..., speed_m_s=...) -> (state, Arrival)``;
          ``Arrival`` says how far from the target the tool stopped and at what force.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from ..cell import ComplianceSelection, LeadThrough, LeadThroughState
from ..transforms import rotation_log

STIFF = ComplianceSelection(frozenset(), "base")
FREE = ComplianceSelection(frozenset({"x", "y", "z"}), "base")
ARRIVED_M = 1.5e-4  # within this of the target, the tool is there
MAX_JOG_M = 0.2  # LeadThrough.jog's longest translation
MAX_TURN_RAD = math.radians(45.0)  # ... and its largest rotation
TURN_RATE_RAD_S = math.radians(30.0)
DESCENT_TIMEOUT_S = 4.0
# Above the part, a positioning move: well under the 250 mm/s of a robot's reduced speed.
TRAVEL_SPEED_M_S = 0.2


@dataclass(frozen=True)
class Arrival:
    """Where a ``go_to_point`` ended.

    Attributes:
        reached: Within ``ARRIVED_M`` of the target.
        distance_m: Distance of the TCP from the target.
        force_N: Contact force there (0 when free).
    """

    reached: bool
    distance_m: float
    force_N: float

    def describe(self) -> str:
        """One line for people ("" when the tool is there, free)."""
        if self.reached and self.force_N < 1.0:
            return ""
        where = (
            "at the point"
            if self.reached
            else f"{self.distance_m * 1e3:.1f} mm from the point (the part is not where its "
            "mesh is)"
        )
        return f"stopped by contact with the part at {self.force_N:.0f} N, {where}"


def _direction_frame(direction: np.ndarray) -> np.ndarray:
    """A rotation whose x axis is ``direction`` (unit): the jog frame of a straight move."""
    x = direction / np.linalg.norm(direction)
    helper = np.array([0.0, 0.0, 1.0]) if abs(x[2]) < 0.9 else np.array([1.0, 0.0, 0.0])
    y = np.cross(helper, x)
    y /= np.linalg.norm(y)
    return np.column_stack([x, y, np.cross(x, y)])


def move_by(
    lt: LeadThrough, state: LeadThroughState, delta_m: np.ndarray, speed_m_s: float
) -> LeadThroughState:
    """A stiff, supervised straight jog of the TCP by ``delta_m`` (base frame)."""
    delta = np.asarray(delta_m, dtype=float)
    distance = float(np.linalg.norm(delta))
    if distance < 1e-6:
        return state
    frame = _direction_frame(delta)
    steps = max(1, math.ceil(distance / MAX_JOG_M))
    for _ in range(steps):
        state = lt.jog(state, "x", distance / steps, STIFF, rate=speed_m_s, frame_rotation=frame)
    return state


def turn_to(lt: LeadThrough, state: LeadThroughState, R_target: np.ndarray) -> LeadThroughState:
    """Stiff, supervised turns about the TCP to the orientation ``R_target`` (base frame), in
    steps of at most 45 degrees about the rotation's axis."""
    for _ in range(8):
        R_now = state.T_ref[:3, :3]
        w = rotation_log(np.asarray(R_target, dtype=float) @ R_now.T)
        angle = float(np.linalg.norm(w))
        if angle < 1e-4:
            break
        step = min(angle, MAX_TURN_RAD)
        state = lt.jog(
            state, "rx", step, STIFF, rate=TURN_RATE_RAD_S, frame_rotation=_direction_frame(w)
        )
    return state


def go_to_point(
    lt: LeadThrough,
    state: LeadThroughState,
    T_target: np.ndarray,
    *,
    safe_z_m: float,
    speed_m_s: float = TRAVEL_SPEED_M_S,
    entry_m: np.ndarray | None = None,
) -> tuple[LeadThroughState, Arrival]:
    """Lift to ``safe_z_m`` (base z), turn, go over the target and down to it (module
    docstring); with ``entry_m`` (base frame), down there first and across to the target (a
    groove entered in its middle, when the part may not be where its mesh is). Supervision
    errors propagate with the last safe state."""
    from .operator import push_to

    T = np.asarray(T_target, dtype=float)
    p = state.cell.T_base_tcp[:3, 3]
    if p[2] < safe_z_m:
        state = move_by(lt, state, np.array([0.0, 0.0, safe_z_m - p[2]]), speed_m_s)
    state = turn_to(lt, state, T[:3, :3])
    down_at = T[:3, 3] if entry_m is None else np.asarray(entry_m, dtype=float)
    above = down_at.copy()
    above[2] = max(safe_z_m, above[2])
    state = move_by(lt, state, above - state.T_ref[:3, 3], speed_m_s)
    if entry_m is not None:
        state = push_to(lt, state, down_at, FREE, tolerance_m=5e-4, timeout_s=DESCENT_TIMEOUT_S)
    state = push_to(lt, state, T[:3, 3], FREE, tolerance_m=ARRIVED_M, timeout_s=DESCENT_TIMEOUT_S)
    distance = float(np.linalg.norm(state.cell.T_base_tcp[:3, 3] - T[:3, 3]))
    force = float(np.linalg.norm(lt.measured_wrench(state.cell)[:3]))
    return state, Arrival(distance <= ARRIVED_M + 1e-4, distance, force)
