"""The session's projects: open, create, rename and delete them in the store; import and export
them as files.

Opening reads a stored project and builds its live cell outside the session lock (the slow
part: the mesh, the robot model, the post-processing recomputed from the recording), then
``Session.switch_to`` installs it under the lock only if nothing changed meanwhile.

``Projects(session)`` is the session's ``projects``: ``open_initial``, ``list_projects``,
``create_project``, ``open_project``, ``rename_project``, ``delete_project``, and projects as
files, ``import_project`` (a ``project.npz`` that ``robomach demo`` and ``robomach machine``
write, as a new project) and ``export_project``, so that the CLI and the workbench hold the
same ``Project`` value and write the same program files. ``read_project`` reads the store alone.
"""

from __future__ import annotations

import shutil
import threading
from dataclasses import asdict, dataclass, replace
from typing import TYPE_CHECKING, Any

from robomach_core import project as core
from robomach_core.cell import ComplianceSelection
from robomach_core.errors import RobomachError
from robomach_core.project import CellSettings, Project
from robomach_core.robots.custom import RobotFileError

from ..store import ProjectData, Store
from .persistence import cell_from_doc, project_from_data
from .records import (
    DEFAULT_PROJECT_NAME,
    ConflictError,
    NotFoundError,
    ProjectInfo,
    check_project_name,
    log,
)
from .robot import Built, build_live_cell, selection_document, selection_from_document

if TYPE_CHECKING:
    from .session import Session


@dataclass(frozen=True)
class Loaded:
    """A project (from the store or a file) with its live cell, ready for ``switch_to``."""

    project_id: int
    project: Project
    built: Built
    selection: ComplianceSelection | None = None
    pointing: dict[str, Any] | None = None  # the pointing settings saved with the robot
    notice: str = ""  # what the user must know: the stored arm was refused (``read_project``)
    calibration: dict[str, Any] | None = None  # the calibration's touches saved with it


class Projects:
    """The stored projects of a session: the session's ``projects`` (module docstring).

    Args:
        session: The session whose projects these are.
        lock: The session's lock (a name checked and taken, a project deleted while it is
            not the open one or no job runs, each at once with the session's changes).
    """

    def __init__(self, session: Session, lock: threading.RLock) -> None:
        self._session = session
        self._lock = lock

    def list_projects(self) -> list[ProjectInfo]:
        """Every stored project, most recently changed first."""
        open_id = self._session.project_id
        return [
            ProjectInfo(r.id, r.name, r.created_s, r.updated_s, r.id == open_id)
            for r in self._session.store.list_projects()
        ]

    def create_project(self, name: str) -> ProjectInfo:
        """A new project with the default cell, opened at once."""
        s, name = self._session, check_project_name(name)
        with self._lock:
            s.robot.require_idle()
            if s.store.find_project(name) is not None:
                raise ConflictError(f"a project named {name!r} already exists")
            row = s.store.create_project(name, asdict(CellSettings()), _robot_doc_default())
        s.switch_to(read_project(s.store, row.id))
        return s.current_project()

    def open_project(self, project_id: int) -> ProjectInfo:
        """Open a stored project (its cell, robot pose, guide points, recording, results)."""
        s = self._session
        with self._lock:
            s.robot.require_idle()
            if s.store.get_project(project_id) is None:
                raise NotFoundError(f"no project with id {project_id}")
            epoch = s.robot.epoch
        loaded = read_project(s.store, project_id)  # outside the lock: reads never wait
        s.switch_to(loaded, epoch=epoch)
        return s.current_project()

    def rename_project(self, project_id: int, name: str) -> ProjectInfo:
        s, store, name = self._session, self._session.store, check_project_name(name)
        with self._lock:
            row = store.get_project(project_id)
            if row is None:
                raise NotFoundError(f"no project with id {project_id}")
            other = store.find_project(name)
            if other is not None and other.id != project_id:
                raise ConflictError(f"a project named {name!r} already exists")
            store.rename_project(project_id, name)
            row = store.get_project(project_id)
            assert row is not None  # under the lock: nothing deleted it meanwhile
        s.notify("project")
        return ProjectInfo(row.id, row.name, row.created_s, row.updated_s, row.id == s.project_id)

    def delete_project(self, project_id: int) -> None:
        """Delete a project and its saved export files. Deleting the open one opens the most
        recently changed other project (or a new ``default`` project)."""
        s = self._session
        with self._lock:
            if s.store.get_project(project_id) is None:
                raise NotFoundError(f"no project with id {project_id}")
            is_open = project_id == s.project_id
            if is_open:
                s.robot.require_idle()
            s.store.delete_project(project_id)
            if s.data_dir is not None:
                shutil.rmtree(s.data_dir / "exports" / str(project_id), ignore_errors=True)
        if is_open:
            self.open_initial(prefer=None)
        else:
            s.notify("project")

    def open_initial(self, prefer: int | None = -1) -> None:
        """Open the last project (or the newest, or a new default one)."""
        store = self._session.store
        candidates = []
        if prefer == -1:
            last = store.last_project_id()
            if last is not None:
                candidates.append(last)
        candidates += [r.id for r in store.list_projects()]
        for project_id in candidates:
            if store.get_project(project_id) is None:
                continue
            try:
                loaded = read_project(store, project_id)
            except RobomachError as exc:  # e.g. a robot model no longer installed
                log.error("cannot open project %s: %s", project_id, exc)
                continue
            self._session.switch_to(loaded)
            return
        name, k = DEFAULT_PROJECT_NAME, 1
        while store.find_project(name) is not None:
            k, name = k + 1, f"{DEFAULT_PROJECT_NAME} {k + 1}"
        row = store.create_project(name, asdict(CellSettings()), _robot_doc_default())
        self._session.switch_to(read_project(store, row.id))

    def import_project(self, data: bytes, name: str) -> ProjectInfo:
        """A new project named ``name`` holding the file's project, opened at once.

        Raises:
            ProjectFileError: not a robomach project file (422).
            ConflictError: the name is taken, or the robot is busy.
        """
        project = core.project_from_file_bytes(data)  # parse (and re-process) before touching
        built = build_live_cell(project.cell, project.mesh)
        info = self.create_project(name)
        # The machining result is not in the file (re-run it); a stale stamp is not carried.
        self._session.switch_to(Loaded(info.id, project, built), save=True)
        return self._session.current_project()

    def export_project(self) -> bytes:
        """The open project as ``project.npz`` bytes."""
        return core.project_file_bytes(self._session.project())


def _robot_doc_default() -> dict[str, Any]:
    return {"joints_rad": None, "compliance": selection_document(ComplianceSelection())}


def read_project(store: Store, project_id: int) -> Loaded:
    """A stored project and its live cell, built without touching the session (the slow
    part of opening: the mesh, the robot model, the post-processing)."""
    data = store.load_project(project_id)
    if data is None:
        raise NotFoundError(f"no project with id {project_id}")
    notice = ""
    try:
        cell = cell_from_doc(data.cell)
    except RobotFileError as exc:
        data, notice = _without_refused_arm(data, exc)
        log.warning("project %s (%s): %s", project_id, data.row.name, notice)
        cell = cell_from_doc(data.cell)
    mesh = data.mesh if not cell.workpiece_builtin else None
    built = build_live_cell(cell, mesh, data.robot.get("joints_rad"))
    selection = selection_from_document(data.robot.get("compliance"))
    project = project_from_data(data, built[0].workpiece)
    return Loaded(
        project_id, project, built, selection, data.robot.get("pointing"), notice,
        data.robot.get("calibration"),
    )  # fmt: skip


def _without_refused_arm(data: ProjectData, exc: RobotFileError) -> tuple[ProjectData, str]:
    """The stored project on the default arm, without what belongs to the arm it was saved on
    (its guide points, recording and results, the robot's joints), and the message saying so.

    A saved arm is checked as an upload is; one this version refuses (a mesh reference outside
    its zip, issue 32) must not keep the project from opening, nor the server from starting
    (it reopened the last project at every start). The database keeps the project as it was
    until the user changes it (``Session`` then saves it whole)."""
    stored = data.cell.get("robot_urdf") or ["the arm file"]
    default = CellSettings().robot
    dropped = ("robot_urdf", "wobj_mm_deg", "registration")
    cell = {k: v for k, v in data.cell.items() if k not in dropped}
    cell["robot"] = default
    robot = {k: v for k, v in data.robot.items() if k != "joints_rad"}
    post = {k: v for k, v in data.post.items() if k == "settings"}
    notice = (
        f"the project's arm ({stored[0]}) is refused: {exc}. It opened on the "
        f"{default.upper()} without that arm's guide points, recording and results; the "
        "database keeps them until you change this project"
    )
    return (
        replace(data, cell=cell, robot=robot, post=post, guide_points=[], recording_info=None,
                recording_arrays={}),
        notice,
    )  # fmt: skip
