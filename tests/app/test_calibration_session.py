"""Work-object calibration in the session (``app/session/calibration.py``), on a real SQLite
store: the example operator's touches, a person's touches, the fit, accepting it, a restart,
and a cell change that drops what belonged to the old part. A fresh realistic part each run
(``ROBOMACH_SEED`` replays one)."""

from __future__ import annotations

import numpy as np
import pytest

from app.session import NotFoundError, Session
from app.store import Store
from robomach_core.errors import InvalidInputError, NoContactError
from robomach_core.part import PartDeviation
from robomach_core.part.real_part import fixture_error
from robomach_core.teaching import CalibrationError
from tests.envelope import replay, run_seed
from tests.jobs import finished

SEED = run_seed()
TOP_WOBJ_M = np.array([0.09, 0.06, 0.020])  # the pump's rim, 10 mm inside its corner


def _errors_m(session: Session, deviation: PartDeviation) -> float:
    """The farthest a vertex of the CAD the session shows stands from the real part's."""
    part = session.robot.workpiece
    cad = part.cad()
    truth = part.unregistered.T_base_wobj if part.unregistered is not None else cad.T_base_wobj
    truth = truth @ fixture_error(deviation).transform
    V = np.asarray(cad.mesh.vertices)
    a = V @ cad.T_base_wobj[:3, :3].T + cad.T_base_wobj[:3, 3]
    b = V @ truth[:3, :3].T + truth[:3, 3]
    return float(np.linalg.norm(a - b, axis=1).max())


@pytest.mark.slow
def test_the_example_operator_calibrates_and_the_accepted_fit_survives_a_restart(tmp_path):
    deviation = PartDeviation.realistic(SEED % 2**31)
    db = tmp_path / "robomach.sqlite"
    session = Session(Store(db), real_time=False)
    try:
        session.set_cell(part_deviation=deviation)
        before = _errors_m(session, deviation)
        assert before > 2e-3, replay(SEED)  # the CAD as placed: millimetres off
        plan = session.calibration.plan()
        assert [t.feature for t in plan.touches].count("top") == 4 and len(plan.touches) == 9
        info = finished(session, session.calibration.start_auto(force_N=12.0))
        assert info.status == "done", info.error
        state = session.calibration.state()
        assert len(state.touches) == 9 and state.fit is not None, state.fit_error
        assert state.force_N == 12.0 and state.registration is None
        joints = session.robot.snapshot().joints_rad
        cell = session.calibration.accept()
        assert cell.registration is not None and len(cell.registration.touches) == 9
        np.testing.assert_allclose(session.robot.snapshot().joints_rad, joints, atol=1e-9)
        after = _errors_m(session, deviation)
        said = f"{replay(SEED)}: {after * 1e3:.3f} mm after, {state.fit.describe()}"
        assert after <= 0.6e-3, said
        assert session.robot.workpiece.unregistered is not None
    finally:
        session.close()
    reopened = Session(Store(db), real_time=False)
    try:
        assert reopened.project().cell.registration == cell.registration
        assert _errors_m(reopened, deviation) == pytest.approx(after, abs=1e-9)
        assert len(reopened.calibration.state().touches) == 9  # kept with the robot
        reopened.calibration.remove()
        assert reopened.project().cell.registration is None
        assert _errors_m(reopened, deviation) == pytest.approx(before, abs=1e-9)
        assert len(reopened.calibration.state().touches) == 9  # the touches stay
    finally:
        reopened.close()


def test_a_person_touches_picked_faces_and_from_where_the_tool_stands():
    session = Session(real_time=False)
    try:
        touch = session.calibration.touch(at_wobj_m=TOP_WOBJ_M, force_N=8.0)
        assert touch.feature == "top" and touch.direction == pytest.approx((0, 0, -1))
        assert touch.force_N == pytest.approx(8.0, abs=1.5)
        # The ball pressed F/k into the top face: its centre r - F/k above it.
        top = 0.020 + 0.001 - touch.force_N / 100e3
        assert touch.tcp_m[2] == pytest.approx(top, abs=0.02e-3)
        # Backed off to where the touch started (8 mm above the face), free.
        snap = session.robot.snapshot()
        assert snap.position_m[2] == pytest.approx(0.029, abs=0.2e-3) and not snap.in_contact
        # From where the tool stands, down in the work object's frame.
        again = session.calibration.touch(direction=np.array([0, 0, -5.0]), frame="wobj")
        assert again.tcp_m == pytest.approx(touch.tcp_m, abs=0.05e-3)
        state = session.calibration.state()
        assert len(state.touches) == 2 and state.fit is None
        assert "2 of at least 6" in state.fit_error
        with pytest.raises(CalibrationError, match="2 of at least 6"):
            session.calibration.fit()
        with pytest.raises(CalibrationError, match="2 of at least 6"):
            session.calibration.accept()
        assert session.calibration.undo().tcp_m == again.tcp_m
        session.calibration.delete(0)
        with pytest.raises(NotFoundError):
            session.calibration.undo()
        # Upwards from above the part: nothing to touch; the robot stays where it searched.
        with pytest.raises(NoContactError, match="no contact within 5.0 mm"):
            session.calibration.touch(direction=np.array([0, 0, 1.0]), max_travel_m=0.005)
        with pytest.raises(InvalidInputError, match="direction"):
            session.calibration.touch()
        with pytest.raises(InvalidInputError, match="from the part"):
            session.calibration.touch(at_wobj_m=np.array([0.0, 0.0, 0.2]))
    finally:
        session.close()


def test_another_part_or_placement_drops_the_touches_and_the_calibration_a_tool_keeps_them():
    session = Session(real_time=False)
    try:
        session.set_cell(workpiece="block")
        info = finished(session, session.calibration.start_auto())
        assert info.status == "done", info.error
        session.calibration.accept()
        assert session.project().cell.registration is not None
        session.set_cell(tool_radius_m=0.002)  # the same part, where it is: both stay
        assert session.project().cell.registration is not None
        assert len(session.calibration.state().touches) == 9
        session.set_cell(wobj_mm_deg=(780.0, 150.0, 0.0, 10.0))  # the part moved
        assert session.project().cell.registration is None
        assert session.calibration.state().touches == ()
        assert session.project().cell.wobj_mm_deg == (780.0, 150.0, 0.0, 10.0)
        np.testing.assert_allclose(session.robot.workpiece.cad().T_base_wobj[:3, 3],
                                   [0.78, 0.15, 0.0])  # fmt: skip
        with pytest.raises(InvalidInputError, match="work-object rz"):
            session.set_cell(wobj_mm_deg=(780.0, 150.0, 0.0, 400.0))
        with pytest.raises(InvalidInputError, match="x,y,z"):
            session.set_cell(wobj_mm_deg=(780.0, 150.0))
        assert session.project().cell.wobj_mm_deg == (780.0, 150.0, 0.0, 10.0)
        session.set_cell(wobj_mm_deg=None)
        np.testing.assert_allclose(session.robot.workpiece.cad().T_base_wobj[:3, 3],
                                   [0.80, 0.16, 0.0])  # fmt: skip
    finally:
        session.close()
