"""The session against its real SQLite store when projects come and go (issue 32, point 7),
and the pointing settings that now live with a project.

Opening a project that another request deletes meanwhile answered 503 (8 of 20,585 fuzzed
requests): the project opened after its row was gone, and every later read of it failed.
The pointing settings (gap, height, click mode) were lost on restart.
"""

from __future__ import annotations

from pathlib import Path

import pytest

from app.session import NotFoundError, Session, projects
from app.store import Store


def test_a_project_deleted_while_it_opens_does_not_open(tmp_path: Path) -> None:
    session = Session(Store(tmp_path / "robomach.sqlite"), real_time=False)
    try:
        first = session.projects.create_project("first")
        other = session.projects.create_project("other")
        session.projects.open_project(first.id)
        loaded = projects.read_project(session.store, other.id)  # the slow part, unlocked
        session.store.delete_project(other.id)  # another request deletes it meanwhile
        with pytest.raises(NotFoundError, match="deleted while it opened"):
            session.switch_to(loaded, epoch=session.robot.epoch)
        assert session.current_project().id == first.id  # still open, and readable
        session.record_guide_point()
        assert len(session.project().guide_points) == 1
    finally:
        session.close()


def test_the_pointing_settings_come_back_with_their_project(tmp_path: Path) -> None:
    db = tmp_path / "robomach.sqlite"
    session = Session(Store(db), real_time=False)
    try:
        mine = session.projects.create_project("mine")
        session.pointing.set_settings(gap_m=0.0025, height_above_floor_m=0.005, click_mode="teach")
        session.projects.create_project("fresh")  # another project: the defaults
        assert session.pointing.settings.gap_m == pytest.approx(0.001)
        assert session.pointing.click_mode == "propose"
    finally:
        session.close()
    reopened = Session(Store(db), real_time=False)
    try:
        reopened.projects.open_project(mine.id)
        assert reopened.pointing.settings.gap_m == pytest.approx(0.0025)
        assert reopened.pointing.settings.height_above_floor_m == pytest.approx(0.005)
        assert reopened.pointing.click_mode == "teach"
    finally:
        reopened.close()
