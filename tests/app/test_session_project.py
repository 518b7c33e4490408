"""The Session over one ``Project`` value, in process: staleness in the GUI model, and
post-processing computed outside the session lock."""

from __future__ import annotations

import threading
import time
from collections.abc import Iterator
from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest

import robomach_core.project as core
from app.session import ConflictError, Session
from tests.api.server_process import free_port
from tests.jobs import done


def _push_to(session: Session, goal_mm: list[float]) -> None:
    """Admittance pushes (damping 500 N*s/m): f = D e / T, as the API tests do."""
    for _ in range(40):
        err = np.asarray(goal_mm) - session.robot.snapshot().position_m * 1e3
        if np.linalg.norm(err) < 1.0:
            return
        f = np.clip(500.0 * err * 1e-3 / 0.5, -25.0, 25.0)
        session.teach.push(np.r_[f, 0.0, 0.0, 0.0], 0.5)
    raise AssertionError(f"could not push the tool to {goal_mm}")


@pytest.fixture(scope="module")
def session() -> Iterator[Session]:
    """A session with two guide points on the block, a short recording and its targets
    (unpaced: the pushes are a script's, not a person's)."""
    s = _two_points_learned()
    yield s
    s.close()


def _two_points_learned() -> Session:
    s = Session(real_time=False)
    s.set_cell(workpiece="block")
    s.robot.select(["x", "y", "z"], "base")
    _push_to(s, [760.0, 120.0, 80.0])
    for x in (760.0, 840.0):
        s.robot.select(["x", "y", "z"], "base")
        _push_to(s, [x, 131.0, 30.0])
        s.robot.select(["x", "y"], "base")
        s.teach.push(np.array([0.0, 6.0, 0.0, 0.0, 0.0, 0.0]), 1.5)
        s.record_guide_point()
    s.robot.select(["x", "y", "z"], "base")
    done(s, s.learning.start_path_learning(10.0, 0.02, closed=False), 120)
    s.learning.run_postprocess(tolerance_m=5e-5)
    return s


def test_post_processing_after_the_guide_points_changed_judges_the_program_by_no_other_points():
    """A guide point recorded or deleted after path learning: post-processing the recording
    (out of date now) still runs and makes its program, and does not judge it by the taught
    wall of points it was not learned from; with the learned points back, the check is back.
    Post-processing after a point recorded past the learning failed with a 503 (the check
    paired 3 points with the recording's 2), found by a random walk over the API."""
    s = _two_points_learned()
    try:
        learned = s.project().guide_points
        assert s.learning.run_postprocess().taught_wall is not None
        s.record_guide_point()
        s.delete_guide_point(0)  # two points again, not the two learned from
        for _ in range(2):
            stale = s.learning.run_postprocess()
            assert s.project().status()["recording"] == "stale"
            assert stale.taught_wall is None and len(stale.result.targets) >= 2
            s.record_guide_point()
        s.clear_guide_points()
        assert s.project().learned_guides() is None
        assert core.with_guide_points(s.project(), learned).learned_guides() == learned
    finally:
        s.close()


def test_changing_guide_points_marks_results_out_of_date_in_the_gui(session: Session) -> None:
    import viser

    from app.gui.panels.export import ExportPanel
    from app.gui.panels.path_learning import PathLearningPanel
    from app.gui.panels.postprocess import OUT_OF_DATE, PostprocessPanel
    from app.gui.scene import CellScene

    server = viser.ViserServer(host="127.0.0.1", port=free_port(), verbose=False)
    try:
        scene = CellScene(server)
        post = PostprocessPanel(server, session, scene)
        export = ExportPanel(server, session, session.studies)
        learning = PathLearningPanel(server, session)
        learning.show_job(None)
        assert session.project().status()["postprocess"] == "current"
        assert OUT_OF_DATE not in post.summary.content
        assert export.preview.content.startswith("**RAPID preview**")
        assert OUT_OF_DATE not in learning.status.content
        assert scene.paths.stale_label is not None and not scene.paths.stale_label.visible

        # The machining slot follows the same rule (the lead wires its results).
        project = session.project()
        machined = replace(
            project, machining="a run", machining_inputs=core.machining_inputs_key(project)
        )
        assert machined.status()["machining"] == "current"

        guides = list(session.project().guide_points)
        session.delete_guide_point(1)
        try:
            assert session.project().status()["postprocess"] == "stale"
            assert replace(machined, guide_points=tuple(guides[:1])).status()["machining"] == (
                "stale"
            )
            post.refresh()
            export.refresh()
            learning.show_job(None)
            assert OUT_OF_DATE in post.summary.content
            assert OUT_OF_DATE in export.preview.content
            assert OUT_OF_DATE in learning.status.content
            assert scene.paths.stale_label.visible  # the scene's path says so too
        finally:  # put the point back: the results are current again (same fingerprint)
            session.commit(lambda p: core.with_guide_points(p, guides), "guides")
        assert session.project().status()["postprocess"] == "current"
        post.refresh()
        assert OUT_OF_DATE not in post.summary.content
        assert not scene.paths.stale_label.visible
    finally:
        server.stop()


def test_the_export_panel_shows_what_the_program_carries(session: Session) -> None:
    import viser

    from app.gui.panels.export import ExportPanel
    from robomach_core.cmrr import build_scenario, cmrr_settings_for, settings_for

    server = viser.ViserServer(host="127.0.0.1", port=free_port(), verbose=False)
    try:
        export = ExportPanel(server, session, session.studies)
        # Nothing chosen: a constant feed, as the files are written (no FC SpeedChange).
        assert "feed control **constant**, compensation **off**" in export.process.content
        assert "FCSpdChgAct" not in export.file_text("program.mod")
        cmrr = cmrr_settings_for(build_scenario("deburr-burrs"), settings_for("two-stage"))
        session.programs.set_process_settings(cmrr=cmrr)
        export.refresh()
        assert "feed control **two-stage**" in export.process.content
        assert "CMRR: two-stage" in export.preview.content
        assert "FCSpdChgAct" in export.file_text("program.mod")
        assert "FCSpdChgAct" not in export.file_text("program_fc.mod")
    finally:
        session.programs.set_process_settings()
        server.stop()


@pytest.fixture
def gated_process(monkeypatch: pytest.MonkeyPatch) -> Iterator[tuple[threading.Event, ...]]:
    """``project.process`` (the real one) held until the test opens the gate."""
    entered, gate = threading.Event(), threading.Event()
    real = core.process

    def held(*args, **kwargs):
        entered.set()
        assert gate.wait(30), "the test never opened the gate"
        return real(*args, **kwargs)

    monkeypatch.setattr(core, "process", held)
    yield entered, gate
    gate.set()


def _lock_is_free(session: Session, timeout_s: float = 2.0) -> bool:
    """A change that takes the session's lock (an empty ``commit``) ends within ``timeout_s``."""
    worker = threading.Thread(target=session.commit, args=(lambda p: p,), daemon=True)
    worker.start()
    worker.join(timeout_s)
    return not worker.is_alive()


def test_post_processing_runs_outside_the_session_lock(session: Session, gated_process) -> None:
    entered, gate = gated_process
    out: dict = {}
    worker = threading.Thread(
        target=lambda: out.setdefault("r", session.learning.run_postprocess(tolerance_m=1e-4))
    )
    worker.start()
    assert entered.wait(30)
    # While it computes, the lock is free: state reads and the robot answer at once.
    assert _lock_is_free(session)
    session.robot.snapshot()
    assert session.project().post_settings.tolerance_m == pytest.approx(5e-5)  # not swapped yet
    gate.set()
    worker.join(30)
    assert out["r"].settings.tolerance_m == pytest.approx(1e-4)
    assert session.project().processed is out["r"]
    session.learning.run_postprocess(tolerance_m=5e-5)


def test_opening_a_project_post_processes_outside_the_lock(session: Session, gated_process) -> None:
    entered, gate = gated_process
    original = session.current_project().id
    targets = len(session.project().processed.result.targets)
    session.projects.create_project(f"other-{time.monotonic_ns()}")
    assert session.project().recording is None
    worker = threading.Thread(target=session.projects.open_project, args=(original,))
    worker.start()
    assert entered.wait(30)  # re-running the stored post-processing
    assert _lock_is_free(session)
    assert session.project().recording is None  # still the other project until it is ready
    gate.set()
    worker.join(60)
    assert session.current_project().id == original
    assert len(session.project().processed.result.targets) == targets
    assert session.project().status()["postprocess"] == "current"


def test_a_project_saved_before_fingerprints_opens_as_current(
    session: Session, tmp_path: Path
) -> None:
    from app.session.persistence import save_kwargs
    from app.store import Store

    project = session.project()
    store = Store(tmp_path / "old.sqlite")
    kwargs = save_kwargs(project, "cell", "guides", "recording", "post")
    # The previous version's documents: no fingerprints, no process settings, no wobj.
    info, arrays = kwargs["recording"]
    kwargs["recording"] = ({k: v for k, v in info.items() if k != "inputs"}, arrays)
    kwargs["post"] = {"settings": kwargs["post"]["settings"], "applied": True}
    kwargs["cell"] = {k: v for k, v in kwargs["cell"].items() if k != "wobj_mm_deg"}
    row = store.create_project("old", kwargs["cell"])
    store.save(row.id, **kwargs)
    store.close()
    reopened = Session(Store(tmp_path / "old.sqlite"))
    try:
        assert reopened.project().status() == project.status()
        assert reopened.project().status()["postprocess"] == "current"
        assert reopened.programs.rapid_module() == session.programs.rapid_module()
    finally:
        reopened.close()


def test_post_processing_result_is_dropped_when_its_inputs_changed(
    session: Session, gated_process
) -> None:
    entered, gate = gated_process
    before = session.project().processed
    errors: list[Exception] = []

    def run() -> None:
        try:
            session.learning.run_postprocess(tolerance_m=1e-4)
        except ConflictError as exc:
            errors.append(exc)

    worker = threading.Thread(target=run)
    worker.start()
    assert entered.wait(30)
    cell = session.project().cell
    session.set_cell(tool_radius_m=cell.tool_radius_m * 2)  # a new cell while it computes
    gate.set()
    worker.join(30)
    assert errors and "changed while post-processing ran" in str(errors[0])
    assert session.project().processed is before
    assert session.project().status()["postprocess"] == "stale"


@pytest.mark.slow  # the example and two path-learning runs around the water pump
def test_learning_at_20_N_moves_the_force_filter_band_with_it() -> None:
    """The chapter's 20 N on the water pump: the run completes, and the filter band (5-15 N,
    made for 10 N, which would keep almost none of it) follows to 10-30 N; post-processing
    then keeps nearly every sample."""
    s = Session(real_time=False)
    try:
        done(s, s.learning.start_example())
        done(s, s.learning.start_path_learning(20.0, 0.010))
        assert s.project().recording.completed, s.project().recording.stop_reason
        post = s.project().post_settings
        assert (post.force_min_N, post.force_max_N) == (10.0, 30.0)
        outcome = s.learning.run_postprocess()
        assert outcome.result.samples_filtered > 0.98 * len(s.project().recording)
        assert outcome.score.max_m < 0.25e-3
        # A band the user chose that holds the force stays as it is.
        s.learning.run_postprocess(force_min_N=12.0, force_max_N=40.0)
        done(s, s.learning.start_path_learning(15.0, 0.010))
        post = s.project().post_settings
        assert (post.force_min_N, post.force_max_N) == (12.0, 40.0)
    finally:
        s.close()
