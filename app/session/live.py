"""What a robot job shows while it runs: the live robot state, its force trace, and cancel.

Jobs drive core functions (``project.learn``, ``scripted_leadthrough``) that own their loop;
stepping through a ``TappedCell`` lets the session show the robot moving, plot the live force
and stop the loop on cancel (the tap raises ``CancelledError``) without changing the core.
"""

from __future__ import annotations

import math
import time
from collections.abc import Callable
from typing import Any, cast

import numpy as np

from robomach_core.cell import CONTROL_PERIOD_S, Cell, CellState, ForceEstimator
from robomach_core.errors import InvalidInputError
from robomach_core.learning.run import Recording

from .jobs import JobContext
from .records import (
    LIVE_NOTIFY_S,
    LIVE_TRACE_EVERY,
    LIVE_TRACE_MAX,
    ForceSource,
    ForceTrace,
)


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


def tapped_cell(cell: Cell, tap: Callable[[CellState], None]) -> Cell:
    """``TappedCell(cell, tap)``, typed as the ``Cell`` it stands in for wherever one is taken:
    every attribute but ``step`` is the cell's (``__getattr__``), a delegation a type checker
    cannot follow (hence the cast, here only)."""
    return cast(Cell, TappedCell(cell, tap))


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

    def force_trace(
        self, recording: Recording | None, busy: bool, max_points: int = 2000
    ) -> ForceTrace:
        """Force vs time, at most ``max_points`` (>= 2) by stride, with the min/max envelope
        of each stride: while a job runs the live force across the path (normal to the edge,
        when the job follows guide points; else |F|), else the recording's force normal to the
        edge."""
        if max_points < 2:
            raise InvalidInputError("max_points must be at least 2")
        live = list(self.trace)
        source: ForceSource
        if busy and live:
            data = np.array(live)
            t, f = data[:, 0], data[:, 1]
            ref = np.full(len(t), np.nan)
            source = "live"
        elif recording is not None:
            t, f = recording.time_s, recording.force_normal_N
            ref, source = recording.force_reference_N, "recording"
        else:
            empty = np.zeros(0)
            return ForceTrace("none", empty, empty, empty, 0)
        n = len(t)
        stride = max(1, math.ceil(n / max_points))
        idx = np.arange(0, n, stride)
        if n and idx[-1] != n - 1:
            idx = np.append(idx, n - 1)
        f = np.asarray(f, dtype=float)
        lo = np.minimum.reduceat(f, idx) if n else f
        hi = np.maximum.reduceat(f, idx) if n else f
        return ForceTrace(source, t[idx], f[idx], ref[idx], n, lo, hi)

    def tapped(
        self,
        cell: Cell,
        estimator: ForceEstimator,
        ctx: JobContext,
        *,
        path_m: np.ndarray | None = None,
        closed: bool = False,
    ) -> Cell:
        """``cell`` seen through a tap that feeds this and checks the job's cancel. With the
        guide points' positions ``path_m`` (n, 3) the live force is the one across the path,
        the quantity the recording keeps (``across_path_force``); else |F|."""
        count = 0
        segments = _segments(path_m, closed) if path_m is not None and len(path_m) >= 2 else None

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
                value = (
                    float(np.sqrt(force @ force))
                    if segments is None
                    else across_path_force(force, state.T_base_tcp, segments)
                )
                self.trace.append((state.time_s - self._t0, value))
            now = time.monotonic()
            if now - self._last_notify >= LIVE_NOTIFY_S:
                self._last_notify = now
                self._on_move()

        return tapped_cell(cell, tap)


def _segments(path_m: np.ndarray, closed: bool) -> tuple[np.ndarray, np.ndarray]:
    """Start points (m, 3) and unit directions (m, 3) of the guide polyline's segments."""
    p = np.asarray(path_m, dtype=float)
    if closed:
        p = np.vstack([p, p[:1]])
    d = np.diff(p, axis=0)
    length = np.linalg.norm(d, axis=1)
    keep = length > 1e-9
    return p[:-1][keep], d[keep] / length[keep, None]


def across_path_force(
    force_N: np.ndarray, T_base_tcp: np.ndarray, segments: tuple[np.ndarray, np.ndarray]
) -> float:
    """The contact force normal to the edge, |F - (F.Zp) Zp| [N]: what path learning regulates
    (``Recording.force_normal_N``), without the floor's push along the tool axis Zp (the tool
    axis made square to Xp, the direction of the guide segment nearest the TCP)."""
    starts, dirs = segments
    rel = T_base_tcp[:3, 3] - starts
    s = np.einsum("ij,ij->i", rel, dirs)
    off = rel - s[:, None] * dirs
    xp = dirs[int(np.argmin(np.einsum("ij,ij->i", off, off)))]
    zp = T_base_tcp[:3, 2] - (T_base_tcp[:3, 2] @ xp) * xp
    zp = zp / max(float(np.linalg.norm(zp)), 1e-12)
    f = np.asarray(force_N, dtype=float)
    return float(np.linalg.norm(f - (f @ zp) * zp))
