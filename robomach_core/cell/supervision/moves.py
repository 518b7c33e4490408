"""Supervised position-controlled moves of the arm: MoveL and MoveJ, as a program runs them.

Each period the reference moves by an increment the supervisor checks (``Supervisor``): the
move slows near a limit and raises ``SupervisionError`` (carrying the last safe cell state)
before crossing one. Path learning's approach to its first point is made of them.
"""

from __future__ import annotations

import math

import numpy as np
import pinocchio as pin

from ..clock import CONTROL_PERIOD_S
from ..simulator import Cell, CellState
from .supervisor import Supervisor, cell_supervisor

MOVE_MAX_PERIODS_FACTOR = 20  # a move slowed by supervision may take this many times longer


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
