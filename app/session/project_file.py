"""Projects as files: import a ``project.npz`` (what ``robomach demo`` and ``robomach machine``
write) as a new project of the session, and export the open one the same way. The CLI and the
workbench then hold the same ``Project`` value and write the same program files."""

from __future__ import annotations

from typing import TYPE_CHECKING

from robomach_core import project as core

from .records import ProjectInfo

if TYPE_CHECKING:
    from .session import Session


def import_project(session: Session, data: bytes, name: str) -> ProjectInfo:
    """A new project named ``name`` holding the file's project, opened at once.

    Raises:
        ProjectFileError: not a robomach project file (422).
        ConflictError: the name is taken, or the robot is busy.
    """
    from .projects import Loaded, create_project
    from .robot import build_live_cell

    project = core.project_from_file_bytes(data)  # parse (and re-process) before touching
    built = build_live_cell(project.cell, project.mesh)
    info = create_project(session, name)
    # The machining result is not in the file (re-run it); a stale stamp is not carried.
    session.switch_to(Loaded(info.id, project, built), save=True)
    return session.current_project()


def export_project(session: Session) -> bytes:
    """The open project as ``project.npz`` bytes."""
    return core.project_file_bytes(session.project())
