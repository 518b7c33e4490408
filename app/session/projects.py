"""The session's projects: open, create, rename and delete them in the store.

Opening reads a stored project and builds its live cell outside the session lock (the slow
part: the mesh, the robot model, the post-processing recomputed from the recording), then
``Session.switch_to`` installs it under the lock only if nothing changed meanwhile.

Functions over a ``Session``: ``open_initial``, ``list_projects``, ``create_project``,
``open_project``, ``rename_project``, ``delete_project``, ``read_project``.
"""

from __future__ import annotations

from dataclasses import asdict, dataclass, replace
from typing import TYPE_CHECKING, Any

from robomach_core.cell import ComplianceSelection
from robomach_core.errors import RobomachError
from robomach_core.project import CellSettings, Project
from robomach_core.robots.custom import RobotFileError

from ..store import ProjectData, Store
from .persistence import cell_from_doc, project_from_data
from .records import (
    DEFAULT_PROJECT_NAME,
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


def list_projects(session: Session) -> list[ProjectInfo]:
    """Every stored project, most recently changed first."""
    open_id = session.project_id
    return [
        ProjectInfo(r.id, r.name, r.created_s, r.updated_s, r.id == open_id)
        for r in session.store.list_projects()
    ]


def create_project(session: Session, name: str) -> ProjectInfo:
    """A new project with the default cell, opened at once."""
    project_id = session.new_project_row(check_project_name(name), _robot_doc_default())
    session.switch_to(read_project(session.store, project_id))
    return session.current_project()


def open_project(session: Session, project_id: int) -> ProjectInfo:
    """Open a stored project (its cell, robot pose, guide points, recording, results)."""
    session.robot.require_idle()  # early: ``switch_to`` checks it again, with the epoch
    if session.store.get_project(project_id) is None:
        raise NotFoundError(f"no project with id {project_id}")
    epoch = session.robot.epoch
    loaded = read_project(session.store, project_id)  # reads never wait for the slow part
    session.switch_to(loaded, epoch=epoch)
    return session.current_project()


def rename_project(session: Session, project_id: int, name: str) -> ProjectInfo:
    return session.rename_project_row(project_id, check_project_name(name))


def delete_project(session: Session, project_id: int) -> None:
    """Delete a project and its saved export files. Deleting the open one opens the most
    recently changed other project (or a new ``default`` project)."""
    if session.delete_project_row(project_id):
        open_initial(session, prefer=None)
    else:
        session.notify("project")


def _robot_doc_default() -> dict[str, Any]:
    return {"joints_rad": None, "compliance": selection_document(ComplianceSelection())}


def open_initial(session: Session, prefer: int | None = -1) -> None:
    """Open the last project (or the newest, or a new default one)."""
    store = session.store
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
        session.switch_to(loaded)
        return
    name, k = DEFAULT_PROJECT_NAME, 1
    while store.find_project(name) is not None:
        k, name = k + 1, f"{DEFAULT_PROJECT_NAME} {k + 1}"
    row = store.create_project(name, asdict(CellSettings()), _robot_doc_default())
    session.switch_to(read_project(store, row.id))


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
