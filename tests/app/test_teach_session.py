"""The session's teaching motions in process (``app/session/teach.py``): frames, touch-off,
the last safe state after a refusal, letting go, pacing, and the force trace's envelope."""

from __future__ import annotations

import threading
import time

import numpy as np
import pytest

from app.session import Session
from app.session.live import LiveFeed
from robomach_core.errors import InvalidInputError, NoContactError, SupervisionError
from robomach_core.learning.run import Recording
from tests.jobs import done

WOBJ_M = np.array([0.80, 0.16, 0.0])  # the water pump's work object (rotation: identity)


@pytest.fixture
def fast() -> Session:
    """Unpaced (as fast as the simulation allows): the motions' logic, not their timing."""
    s = Session(real_time=False)
    yield s
    s.close()


def test_jog_frames_move_along_their_axes(fast: Session) -> None:
    fast.robot.select([], "base")
    for frame in ("base", "wobj", "tool"):
        p0 = fast.robot.snapshot().position_m.copy()
        R = fast.robot.snapshot().T_base_tcp[:3, :3]
        fast.teach.jog("x", 0.01, frame=frame, speed=0.04)
        d = fast.robot.snapshot().position_m - p0
        expected = R[:, 0] if frame == "tool" else np.array([1.0, 0.0, 0.0])
        assert np.linalg.norm(d - 0.01 * expected) < 2e-4, (frame, d)
    with pytest.raises(InvalidInputError, match="jog frame"):
        fast.teach.jog("x", 0.01, frame="world")  # type: ignore[arg-type]
    with pytest.raises(InvalidInputError, match="jog speed"):
        fast.teach.jog("x", 0.01, speed=0.2)


def test_touch_off_stops_at_the_groove_floor_and_wall(fast: Session) -> None:
    fast.robot.select(["x", "y", "z"], "base")
    fast.teach.jog("x", 0.2, frame="wobj", speed=0.05)  # home is at wobj x = -202.5 mm
    fast.teach.jog("x", 0.0025, frame="wobj", speed=0.05)
    fast.teach.jog("y", -0.0665, frame="wobj", speed=0.05)
    fast.teach.jog("z", -0.2, frame="wobj", speed=0.05)
    fast.teach.jog("z", -0.118, frame="wobj", speed=0.05)
    p = fast.robot.snapshot().position_m - WOBJ_M
    assert abs(p[0]) < 1e-3 and abs(p[1] + 0.0625) < 1e-3 and abs(p[2] - 0.030) < 1e-3, p
    fast.teach.touch_off("z", -1, 10.0, 0.03, frame="wobj")
    assert 0.0145 < fast.robot.snapshot().position_m[2] < 0.0152  # the floor at 14 mm, ball 1 mm
    fast.teach.jog("z", 0.003, frame="wobj", speed=0.02)
    fast.teach.touch_off("y", -1, 10.0, 0.01, frame="wobj")
    view = fast.teach.tool_view()
    assert view.in_contact and view.gap_m <= 0 and np.linalg.norm(view.force_N) > 5.0
    assert abs(fast.robot.snapshot().position_m[1] - WOBJ_M[1] + 0.064) < 3e-4  # the wall - radius
    with pytest.raises(NoContactError):
        fast.teach.touch_off("y", 1, 10.0, 0.001, frame="wobj")


def test_a_refused_push_keeps_the_last_safe_state(fast: Session) -> None:
    fast.robot.select(["x", "y", "z"], "base")
    q_prev = fast.robot.snapshot().joints_rad
    with pytest.raises(SupervisionError) as info:
        for _ in range(200):
            fast.teach.push(np.array([0, 0, 25.0, 0, 0, 0]), 0.2)
            q_prev = fast.robot.snapshot().joints_rad
    assert info.value.cause and info.value.axis is not None
    q = fast.robot.snapshot().joints_rad
    assert np.allclose(q, info.value.state.cell.q_motor)
    assert np.degrees(np.max(np.abs(q - q_prev))) < 5.0
    stored = fast.store.load_project(fast.current_project().id).robot["joints_rad"]
    assert np.allclose(stored, q)  # saved
    fast.teach.push(np.array([0, 0, -25.0, 0, 0, 0]), 0.2)  # and the way back is free
    assert fast.robot.snapshot().position_m[2] < info.value.state.cell.T_base_tcp[2, 3] - 0.005


def test_a_paced_push_takes_its_time_and_stops_when_let_go() -> None:
    s = Session()
    try:
        s.robot.select(["x", "y", "z"], "base")
        t = time.monotonic()
        s.teach.push(np.array([10.0, 0, 0, 0, 0, 0]), 0.5)
        assert time.monotonic() - t >= 0.45
        # Let go early: the push ends there (how soon is benchmarks/bench_answer_times.py's).
        x0 = s.robot.snapshot().position_m[0]
        threading.Timer(0.3, s.teach.stop).start()
        t = time.monotonic()
        s.teach.push(np.array([-10.0, 0, 0, 0, 0, 0]), 3.0)
        held_s, moved_m = time.monotonic() - t, abs(s.robot.snapshot().position_m[0] - x0)
        full_m = (10.0 - 1.0) * 3.0 / 500.0  # the whole 3 s push, (F - deadband) T / D
        assert held_s < 3.0 and moved_m < full_m / 2, (held_s, moved_m, full_m)
    finally:
        s.close()


def test_the_force_trace_keeps_spikes_in_its_envelope() -> None:
    n = 10_000
    t = np.arange(n) * 0.004
    f = np.full(n, 10.0)
    f[4321] = 29.0  # one spike a decimated trace would skip
    rec = Recording.__new__(Recording)
    object.__setattr__(rec, "time_s", t)
    object.__setattr__(rec, "force_normal_N", f)
    object.__setattr__(rec, "force_reference_N", np.full(n, 10.0))
    trace = LiveFeed(lambda: None).force_trace(rec, False, 200)
    assert len(trace.time_s) <= 201 and trace.force_N.max() == 10.0
    assert trace.force_max_N.max() == 29.0 and trace.force_min_N.min() == 10.0


# --- issue 15: stops that say so, frames named as chosen, the gap to the wall ----------------


def _into_the_groove(session: Session) -> None:
    """The tool 1 mm off the pump groove's outer wall, 3 mm above its floor (taught by a
    click: the supervised move of ``Teach.move_to``)."""
    session.pointing.teach_at_surface(np.array([0.04, -0.065, 0.0185]))
    session.clear_guide_points()


def test_a_jog_stopped_by_the_wall_says_so(fast: Session) -> None:
    from robomach_core.errors import ContactStopError

    _into_the_groove(fast)
    fast.robot.select(["x", "y", "z"], "base")
    with pytest.raises(ContactStopError, match=r"-y \(work-object frame\) stopped against"):
        fast.teach.jog("y", -0.005, frame="wobj", speed=0.01)
    assert np.linalg.norm(fast.robot.snapshot().wrench[:3]) > 3.0  # it stays there, in contact
    fast.teach.jog("y", 0.002, frame="wobj", speed=0.01)  # back out: no complaint


def test_a_touch_off_in_the_work_object_frame_names_that_frame(fast: Session) -> None:
    _into_the_groove(fast)
    with pytest.raises(NoContactError, match=r"along \+z \(work-object frame\)"):
        fast.teach.touch_off("z", 1, 10.0, 0.005, frame="wobj")


def test_the_gap_is_to_the_wall_at_the_tool_and_names_a_nearer_floor(fast: Session) -> None:
    view = fast.teach.tool_view()
    assert view.wall_gap_m is None  # at home, above everything
    _into_the_groove(fast)
    view = fast.teach.tool_view()
    assert view.wall_gap_m == pytest.approx(0.001, abs=3e-4)  # the gap set for teaching
    assert view.face == "wall"
    fast.robot.select(["x", "y", "z"], "base")
    fast.teach.touch_off("z", -1, 5.0, 0.01, frame="wobj")  # down onto the floor
    view = fast.teach.tool_view()
    assert view.face == "floor" and view.wall_gap_m == pytest.approx(0.001, abs=5e-4)


@pytest.mark.slow  # the example's 14 points and its run: 5 s idle
def test_the_example_after_hand_teaching_turns_in_steps_and_runs(fast: Session) -> None:
    fast.robot.select([], "tool")
    for _ in range(2):
        fast.teach.jog("rz", np.radians(40.0), frame="tool")  # 80 deg off: more than one jog step
    fast.teach.jog("z", -0.15, frame="base", speed=0.05)
    done(fast, fast.learning.start_example())
    assert len(fast.project().guide_points) == 14
