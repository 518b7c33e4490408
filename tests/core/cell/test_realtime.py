from __future__ import annotations

import numpy as np
import pytest

from robomach_core.cell import Cell, ComplianceSelection, LeadThrough, RealTimePacer
from robomach_core.cell.simulator import CONTROL_PERIOD_S
from robomach_core.errors import InvalidInputError


class FakeClock:
    """A wall clock that only moves when told to (or when someone sleeps)."""

    def __init__(self) -> None:
        self.now = 100.0

    def __call__(self) -> float:
        return self.now

    def sleep(self, seconds: float) -> None:
        self.now += seconds


@pytest.fixture()
def clock() -> FakeClock:
    return FakeClock()


def test_a_push_takes_its_duration_of_wall_time(clock):
    pacer = RealTimePacer(clock=clock, sleep=clock.sleep)
    clock.sleep(5.0)  # idle before: the budget is full (capped at the burst)
    start = clock.now
    chunks = list(pacer.paced(pacer.periods_for(2.0)))
    assert sum(chunks) == 500
    assert max(chunks) <= 25  # 0.1 s chunks: a released button stops within 100 ms
    assert 2.0 - pacer.burst_s - 1e-9 <= clock.now - start <= 2.0 + CONTROL_PERIOD_S


def test_a_flood_of_requests_moves_no_further_than_the_held_time(clock):
    """A pendant firing 0.1 s pushes every 20 ms for 2 s: at most 2 s (+ the burst) simulated."""
    pacer = RealTimePacer(clock=clock, sleep=clock.sleep)
    clock.sleep(30.0)
    simulated = 0
    for _ in range(100):
        simulated += pacer.grant(pacer.periods_for(0.1))
        clock.now += 0.02
    assert simulated * CONTROL_PERIOD_S <= 2.0 + pacer.burst_s + 1e-9
    assert simulated * CONTROL_PERIOD_S >= 2.0 - 0.02  # and it does keep moving


def test_the_budget_refills_at_wall_clock_rate_and_is_capped(clock):
    pacer = RealTimePacer(burst_s=0.2, clock=clock, sleep=clock.sleep)
    assert pacer.available() == 0  # starts empty
    clock.now += 0.04
    assert pacer.available() == 10
    assert pacer.grant(4) == 4
    assert pacer.available() == 6
    assert pacer.wait_s(10) == pytest.approx(0.016)
    clock.now += 1000.0
    assert pacer.available() == 50  # capped at the 0.2 s burst
    clock.now -= 5.0  # a clock stepping back refills nothing and breaks nothing
    assert pacer.available() == 50


def test_paced_pushes_through_the_core_lead_through(clock):
    """The app's use: simulate each granted chunk; the whole push equals an unpaced one."""
    xyz = ComplianceSelection(frozenset({"x", "y", "z"}), "base")
    push = np.array([0.0, 10.0, 0.0, 0.0, 0.0, 0.0])
    ends = []
    for paced in (True, False):
        cell = Cell()  # the same seed: the same sensor noise in both runs
        lt = LeadThrough(cell)
        state = lt.start(cell.initial_state())
        if not paced:
            ends.append(lt.push(state, push, xyz, 0.5))
            continue
        pacer = RealTimePacer(clock=clock, sleep=clock.sleep)
        t0 = clock.now
        for n in pacer.paced(pacer.periods_for(0.5)):
            state = lt.push(state, push, xyz, n * CONTROL_PERIOD_S)
        assert clock.now - t0 == pytest.approx(0.5, abs=0.01)
        ends.append(state)
    np.testing.assert_allclose(ends[0].cell.q_motor, ends[1].cell.q_motor, atol=1e-12)
    assert np.linalg.norm(ends[0].cell.T_base_tcp[:3, 3] - ends[1].cell.T_base_tcp[:3, 3]) < 1e-9


def test_bad_settings_are_refused(clock):
    with pytest.raises(InvalidInputError):
        RealTimePacer(burst_s=0.0, clock=clock)
    with pytest.raises(InvalidInputError):
        RealTimePacer(period_s=-1.0, clock=clock)
    pacer = RealTimePacer(clock=clock, sleep=clock.sleep)
    with pytest.raises(InvalidInputError):
        pacer.grant(-1)
    with pytest.raises(InvalidInputError):
        pacer.periods_for(float("nan"))
