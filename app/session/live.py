"""What a robot job shows while it runs: the live robot state, its force trace, and cancel.

Jobs drive core functions (``project.learn``, ``scripted_leadthrough``) that own their loop;
stepping through a ``TappedCell`` lets the session show the robot moving, plot the live force
and stop the loop on cancel (the tap raises ``CancelledError``) without changing the core.
"""

from __future__ import annotations

import time
from collections.abc import Callable
from typing import Any

import numpy as np

from robomach_core.cell import CONTROL_PERIOD_S, Cell, CellState
from robomach_core.sensor import ForceEstimator

from .jobs import JobContext
from .records import LIVE_NOTIFY_S, LIVE_TRACE_EVERY, LIVE_TRACE_MAX


class TappedCell:
    """A ``Cell`` whose ``step`` also calls ``tap(state)``; every other attribute is the cell's."""

    def __init__(self, cell: Cell, tap: Callable[[CellState], None]) -> None:
        self._cell = cell
        self._tap = tap

    def step(
        self, state: CellState, q_motor_cmd: np.ndarray, dt: float = CONTROL_PERIOD_S
    ) -> CellState:
        new = self._cell.step(state, q_motor_cmd, dt)
        self._tap(new)
        return new

    def __getattr__(self, name: str) -> Any:
        return getattr(self._cell, name)


class LiveFeed:
    """The running job's latest cell state and |F| trace (every ``LIVE_TRACE_EVERY`` periods).

    Args:
        on_move: Called at most every ``LIVE_NOTIFY_S`` while the robot moves.
    """

    def __init__(self, on_move: Callable[[], None]) -> None:
        self._on_move = on_move
        self.cell_state: CellState | None = None
        self.trace: list[tuple[float, float]] = []
        self._t0 = 0.0
        self._last_notify = 0.0

    def start(self, state: CellState) -> None:
        """A job starts from ``state``: the trace restarts at its time."""
        self.cell_state = state
        self._t0 = float(state.time_s)
        self.trace = []

    def stop(self) -> CellState | None:
        """The job ended: the last state it reached (None when it never started)."""
        last, self.cell_state = self.cell_state, None
        return last

    def tapped(self, cell: Cell, estimator: ForceEstimator, ctx: JobContext) -> TappedCell:
        """``cell`` seen through a tap that feeds this and checks the job's cancel."""
        count = 0

        def tap(state: CellState) -> None:
            nonlocal count
            count += 1
            if count % LIVE_TRACE_EVERY:
                return
            ctx.check_cancelled()
            self.cell_state = state
            if len(self.trace) < LIVE_TRACE_MAX:
                force = estimator.contact_wrench_tcp_base(
                    state.ft_reading, cell.flange_rotation(state.T_base_tcp)
                )[:3]
                self.trace.append((state.time_s - self._t0, float(np.sqrt(force @ force))))
            now = time.monotonic()
            if now - self._last_notify >= LIVE_NOTIFY_S:
                self._last_notify = now
                self._on_move()

        return TappedCell(cell, tap)
