"""The session's machining survives a restart: settings, choice and the result's figures are in
the project's store (real SQLite); the traces are not, and the result stays current."""

from __future__ import annotations

import pytest

from app.session import Session
from app.session.machining import MachiningService
from app.store import Store
from tests.demo_project import block_demo_dir
from tests.jobs import done


@pytest.mark.slow  # the shared block demo run (tests/demo_project.py)
def test_settings_choice_and_result_survive_a_restart(tmp_path):
    db = tmp_path / "robomach.sqlite"
    session = Session(Store(db), data_dir=tmp_path)
    try:
        session.projects.import_project((block_demo_dir() / "project.npz").read_bytes(), "block")
        service = MachiningService(session)
        service.set_settings(process_gain_N=25.0, force_limit_N=180.0)
        service.choose("fuzzy", "offline")
        done(session, service.start("run"))
        rows = service.result().rows
        rapid = session.programs.rapid_module()
        assert "planned from rehearsals of the fuzzy cut" in rapid
    finally:
        session.close()

    reopened = Session(Store(db), data_dir=tmp_path)
    try:
        service = MachiningService(reopened)
        s = service.settings_document()
        assert (s["process_gain_N"], s["force_limit_N"]) == (25.0, 180.0)
        assert (s["controller"], s["compensation"]) == ("fuzzy", "offline")
        assert reopened.project().status()["machining"] == "current"
        result = service.result()
        assert [r["cycle_time_s"] for r in result.rows] == [r["cycle_time_s"] for r in rows]
        assert result.runs == ()  # traces are not stored
        assert reopened.programs.rapid_module() == rapid  # the corrected program came back with it
    finally:
        reopened.close()
