"""The session's projects: open, create, rename and delete them in the store, and save the open
one (``Session`` inherits this; see ``session.py`` for the public API).

Opening reads a stored project and builds its live cell outside the session lock (the slow
part: the mesh, the robot model, the post-processing recomputed from the recording), then
installs it under the lock only if nothing changed meanwhile.
"""

from __future__ import annotations

import shutil
import threading
from dataclasses import asdict, dataclass
from typing import Any

import numpy as np

from robomach_core import project as core
from robomach_core.cell import Cell, CellConfig
from robomach_core.errors import InvalidInputError, RobomachError
from robomach_core.leadthrough import ComplianceSelection, LeadThrough, LeadThroughState
from robomach_core.project import CellSettings, Project
from robomach_core.robot import ROBOT_URDFS
from robomach_core.workpiece import Workpiece

from ..store import Store
from .persistence import Part, project_from_data, save_kwargs
from .persistence import cell_from_doc as persistence_cell
from .records import (
    DEFAULT_PROJECT_NAME,
    ConflictError,
    NotFoundError,
    ProjectInfo,
    check_project_name,
    log,
)


class ProjectsMixin:
    """Projects in the store, and saving the open one. Each save is one store transaction.
    It uses the Session's ``_notify``, ``_notify_all`` and ``_require_idle``."""

    # The Session's state this half reads and replaces (set in ``Session.__init__``).
    _lock: threading.RLock
    store: Store
    data_dir: Any
    _project: Project
    _project_id: int
    _epoch: int
    _selection: ComplianceSelection
    _cell: Cell
    _lt: LeadThrough
    _lt_state: LeadThroughState

    def current_project(self) -> ProjectInfo:
        with self._lock:
            row = self.store.get_project(self._project_id)
            return ProjectInfo(row.id, row.name, row.created_s, row.updated_s, True)

    def projects(self) -> list[ProjectInfo]:
        """Every stored project, most recently changed first."""
        with self._lock:
            return [
                ProjectInfo(r.id, r.name, r.created_s, r.updated_s, r.id == self._project_id)
                for r in self.store.list_projects()
            ]

    def create_project(self, name: str) -> ProjectInfo:
        """A new project with the default cell, opened at once."""
        name = check_project_name(name)
        with self._lock:
            self._require_idle()
            if self.store.find_project(name) is not None:
                raise ConflictError(f"a project named {name!r} already exists")
            row = self.store.create_project(name, asdict(CellSettings()), self._robot_doc_default())
            self._load(row.id)
        self._notify_all()
        return self.current_project()

    def open_project(self, project_id: int) -> ProjectInfo:
        """Open a stored project (its cell, robot pose, guide points, recording, results)."""
        with self._lock:
            self._require_idle()
            if self.store.get_project(project_id) is None:
                raise NotFoundError(f"no project with id {project_id}")
            epoch = self._epoch
        loaded = self._read(project_id)  # outside the lock: reads never wait for it
        with self._lock:
            self._require_idle()
            if epoch != self._epoch:
                raise ConflictError("the cell or project changed while opening; open it again")
            self._apply(loaded)
            self.store.set_last_project(project_id)
        self._notify_all()
        return self.current_project()

    def rename_project(self, project_id: int, name: str) -> ProjectInfo:
        name = check_project_name(name)
        with self._lock:
            row = self.store.get_project(project_id)
            if row is None:
                raise NotFoundError(f"no project with id {project_id}")
            other = self.store.find_project(name)
            if other is not None and other.id != project_id:
                raise ConflictError(f"a project named {name!r} already exists")
            self.store.rename_project(project_id, name)
            row = self.store.get_project(project_id)
        self._notify("project")
        return ProjectInfo(
            row.id, row.name, row.created_s, row.updated_s, row.id == self._project_id
        )

    def delete_project(self, project_id: int) -> None:
        """Delete a project and its saved export files. Deleting the open one opens the most
        recently changed other project (or a new ``default`` project)."""
        with self._lock:
            if self.store.get_project(project_id) is None:
                raise NotFoundError(f"no project with id {project_id}")
            is_open = project_id == self._project_id
            if is_open:
                self._require_idle()
            self.store.delete_project(project_id)
            if self.data_dir is not None:
                shutil.rmtree(self.data_dir / "exports" / str(project_id), ignore_errors=True)
            if is_open:
                self._open_initial_project(prefer=None)
        if is_open:
            self._notify_all()
        else:
            self._notify("project")

    def _robot_doc_default(self) -> dict[str, Any]:
        sel = ComplianceSelection()
        return {
            "joints_rad": None,
            "compliance": {"axes": sorted(sel.axes), "frame": sel.frame},
        }

    def _open_initial_project(self, prefer: int | None = -1) -> None:
        """Open the last project (or the newest, or a new default one)."""
        candidates = []
        if prefer == -1:
            last = self.store.last_project_id()
            if last is not None:
                candidates.append(last)
        candidates += [r.id for r in self.store.list_projects()]
        for project_id in candidates:
            if self.store.get_project(project_id) is None:
                continue
            try:
                self._load(project_id)
            except RobomachError as exc:  # e.g. a robot model no longer installed
                log.error("cannot open project %s: %s", project_id, exc)
                continue
            self.store.set_last_project(project_id)
            return
        name, k = DEFAULT_PROJECT_NAME, 1
        while self.store.find_project(name) is not None:
            k, name = k + 1, f"{DEFAULT_PROJECT_NAME} {k + 1}"
        row = self.store.create_project(name, asdict(CellSettings()), self._robot_doc_default())
        self._load(row.id)

    def _load(self, project_id: int) -> None:
        self._apply(self._read(project_id))

    def _read(self, project_id: int) -> _Loaded:
        """A stored project and its live cell, built without touching the session (the slow
        part of opening: the mesh, the robot model, the post-processing)."""
        data = self.store.load_project(project_id)
        if data is None:
            raise NotFoundError(f"no project with id {project_id}")
        cell = persistence_cell(data.cell)
        mesh = data.mesh if not cell.workpiece_builtin else None
        built = _build_cell(cell, mesh, data.robot.get("joints_rad"))
        comp = data.robot.get("compliance") or {}
        try:
            selection = ComplianceSelection(
                frozenset(comp.get("axes", ("x", "y", "z"))), comp.get("frame", "base")
            )
        except RobomachError:
            selection = ComplianceSelection()
        return _Loaded(project_id, built, selection, project_from_data(data, built[0].workpiece))

    def _apply(self, loaded: _Loaded) -> None:
        self._cell, self._lt, self._lt_state = loaded.built
        self._epoch += 1
        self._selection = loaded.selection
        self._project_id = loaded.project_id
        self._project = loaded.project

    # Each save is one store transaction.

    def _robot_doc(self) -> dict[str, Any]:
        return {
            "joints_rad": self._lt_state.cell.q_motor.tolist(),
            "compliance": {
                "axes": sorted(self._selection.axes),
                "frame": self._selection.frame,
            },
        }

    def _save_robot(self) -> None:
        self.store.save(self._project_id, robot=self._robot_doc())

    def _save(self, *parts: Part, with_robot: bool = False) -> None:
        kwargs = save_kwargs(self._project, *parts)
        if with_robot:
            kwargs["robot"] = self._robot_doc()
        self.store.save(self._project_id, **kwargs)


@dataclass(frozen=True)
class _Loaded:
    """A project read from the store with its live cell, ready to be installed."""

    project_id: int
    built: tuple[Cell, LeadThrough, LeadThroughState]
    selection: ComplianceSelection
    project: Project


def _build_cell(
    settings: CellSettings,
    mesh: tuple[str, bytes] | None,
    joints: Any,
    parsed: Workpiece | None = None,
) -> tuple[Cell, LeadThrough, LeadThroughState]:
    """The cell of ``settings`` and its lead-through, the robot at ``joints`` (home when None or
    not usable)."""
    if settings.robot not in ROBOT_URDFS:
        raise InvalidInputError(
            f"unknown robot {settings.robot!r}; choose one of {', '.join(sorted(ROBOT_URDFS))}"
        )
    if parsed is not None:
        from robomach_core.real_part import real_workpiece
        from robomach_core.workpiece import default_T_base_wobj

        # Placed as ``build_workpiece`` places it when the project is opened again.
        T = (
            core.wobj_transform(settings.wobj_mm_deg)
            if settings.wobj_mm_deg is not None
            else default_T_base_wobj(settings.robot)
        )
        workpiece = real_workpiece(parsed.placed(T), settings.part_deviation)
    else:
        workpiece = core.build_cell_workpiece(settings, mesh)
    cell = Cell(
        CellConfig(
            robot=settings.robot,
            tool=core.Project(cell=settings).tool(),
            workpiece=workpiece,
            seed=settings.seed,
        )
    )
    initial = None
    if joints is not None:
        try:
            initial = cell.initial_state(np.asarray(joints, dtype=float))
        except RobomachError:
            log.info("stored joints not usable (limits or contact): starting at home")
    if initial is None:
        initial = cell.initial_state()
    lt = LeadThrough(cell)
    return cell, lt, lt.start(initial)
