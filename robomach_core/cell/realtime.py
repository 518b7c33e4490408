"""Real-time pacing of a person's pushes and jogs: simulated time may not outrun the wall clock.

PROBLEM   The simulation runs tens of times faster than real time, so a 2 s push is answered in
          milliseconds, and a pendant that fires push requests back to back while a button is
          held moves the tool metres in seconds. A person's lead-through must run at wall-clock
          speed; the scripted operator and the headless demo must not (they do not use this).
STRATEGY  A budget of simulated time (a token bucket): it refills at the wall-clock rate (one
          simulated second per wall second) and is capped at ``burst_s``; each control period
          simulated spends ``period_s`` of it. Whatever the requests, the simulated time of all
          of them together over a wall interval T is at most T + burst_s; a single push of
          ``duration_s`` takes duration_s - burst_s to duration_s of wall time; and a held push
          moves at most ``burst_s`` after its release if it is simulated in chunks no longer
          than that.
SOLUTION  ``RealTimePacer``: ``grant(n)`` takes up to n periods now, ``wait_s(n)`` says how long
          until n are available, ``paced(n)`` yields chunk sizes, sleeping in between, so the
          caller simulates each chunk as it is granted. Clock and sleep are injectable.
"""

from __future__ import annotations

import math
import threading
import time
from collections.abc import Callable, Iterator

from ..errors import InvalidInputError
from .clock import CONTROL_PERIOD_S

DEFAULT_BURST_S = 0.1  # a held push stops within this of its release


class RealTimePacer:
    """A budget of simulated time that refills at wall-clock rate, capped at ``burst_s``.

    Args:
        burst_s: Cap of the budget: how far simulated time may run ahead after an idle while.
        period_s: Simulated time of one control period.
        clock: Wall clock in seconds (monotonic); injectable for tests.
        sleep: Sleeps for seconds; injectable for tests.

    The budget starts empty: the first push waits for the clock like every later one.
    Thread-safe: one pacer per person (session), shared by all their requests.
    """

    def __init__(
        self,
        *,
        burst_s: float = DEFAULT_BURST_S,
        period_s: float = CONTROL_PERIOD_S,
        clock: Callable[[], float] = time.monotonic,
        sleep: Callable[[float], None] = time.sleep,
    ) -> None:
        if not (math.isfinite(period_s) and period_s > 0):
            raise InvalidInputError("the control period must be a positive number of seconds")
        if not (math.isfinite(burst_s) and period_s <= burst_s <= 10.0):
            raise InvalidInputError(
                f"the burst must be between one period ({period_s * 1e3:g} ms) and 10 s"
            )
        self.burst_s = float(burst_s)
        self.period_s = float(period_s)
        self._clock = clock
        self._sleep = sleep
        self._lock = threading.Lock()
        self._budget_s = 0.0
        self._last = clock()

    def _refill(self) -> None:
        now = self._clock()
        elapsed = max(0.0, now - self._last)  # a clock that steps back refills nothing
        self._last = now
        self._budget_s = min(self.burst_s, self._budget_s + elapsed)

    def available(self) -> int:
        """Control periods that may be simulated now."""
        with self._lock:
            self._refill()
            return int(math.floor(self._budget_s / self.period_s + 1e-9))

    def grant(self, max_periods: int) -> int:
        """Take up to ``max_periods`` periods of the budget now; returns how many were taken."""
        if max_periods < 0:
            raise InvalidInputError("cannot ask for a negative number of periods")
        with self._lock:
            self._refill()
            n = min(int(max_periods), int(math.floor(self._budget_s / self.period_s + 1e-9)))
            self._budget_s -= n * self.period_s
            return n

    def wait_s(self, periods: int = 1) -> float:
        """Wall seconds until ``periods`` periods are available (0 when they are now)."""
        need = min(periods * self.period_s, self.burst_s)
        with self._lock:
            self._refill()
            return max(0.0, need - self._budget_s)

    def paced(self, periods: int, *, max_chunk: int | None = None) -> Iterator[int]:
        """Chunk sizes summing to ``periods``, each yielded when the budget grants it.

        Simulate each chunk as it comes; stop iterating to stop the motion (a released
        button). A chunk is at most ``max_chunk`` periods (default: the burst), so the motion
        stops within that of the release.
        """
        if periods < 0:
            raise InvalidInputError("cannot pace a negative number of periods")
        limit = max_chunk or max(1, int(math.floor(self.burst_s / self.period_s + 1e-9)))
        remaining = int(periods)
        while remaining > 0:
            n = self.grant(min(limit, remaining))
            if n == 0:
                self._sleep(max(self.wait_s(min(limit, remaining)), self.period_s))
                continue
            remaining -= n
            yield n

    def periods_for(self, duration_s: float) -> int:
        """Control periods of a push of ``duration_s`` seconds."""
        if not (math.isfinite(duration_s) and duration_s >= 0):
            raise InvalidInputError(f"duration {duration_s:g} s must be finite and >= 0")
        return int(round(duration_s / self.period_s))
