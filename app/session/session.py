"""The workbench session: the open project and the live robot of a running ``robomach serve``.

PROBLEM   The viser GUI and the REST API act on one simulated cell and one project from
          different threads while long jobs run; every change must be saved at once and heard
          by both GUIs, and a result must never be swapped in over inputs that changed.
STRATEGY  The job is one frozen ``robomach_core.project.Project``, changed only by the core's
          pure transitions (``project.with_cell``, ``with_guide_points``, ``with_learned`` ...,
          the same the CLI applies) through ``commit``: under one ``threading.RLock`` the
          transition runs, the value is replaced and the changed parts are saved in one store
          transaction; listeners then hear the topics. The robot is a ``LiveRobot`` beside it
          under the same lock, which stays private (what needs it is a method here or of a part
          built with it: ``LiveRobot``, ``Projects``). The session holds nothing else: it builds
          each service once, and they work through its public interface; long work computes
          from a ``view()`` outside the lock and commits a transition that refuses a result
          whose inputs changed meanwhile.
SOLUTION  Public API (thread-safe):

  Reading   project() -> Project; view() -> View (project, cell, epoch, project id, at once);
            idle_start() -> (Project, Pose) for a motion or job about to start (busy: 409);
            current_project() -> ProjectInfo; cell_note() (what a cell change cleared)
  Services  robot, teach (push, jog, touch_off ...), pointing, calibration, learning (the robot
            jobs, post-processing), jobs, preview (a placement tried), programs (and saved
            exports), projects (open, create ..., files), studies (``app.studies``), machining
  Changing  commit(change, *parts, topics=, idle=, with_robot=) -> Project
            change_cell(change, parsed=) -> Project   a transition that rebuilds the live cell
            set_cell(robot=, tool_radius_m=, workpiece=, part_deviation=, wobj_mm_deg=)
                -> CellSettings
            upload_workpiece(data, filename) / upload_robot(data, filename, family=)
            record_guide_point() -> GuidePointEntry; delete_guide_point(i); clear_guide_points()
            switch_to(loaded, epoch=, save=)          another project (``projects``)
  Listening subscribe(callback) -> unsubscribe; notify(*topics)
            callback(topic) runs in the thread that made the change, the lock released
  Lifecycle close()                                   cancel jobs, stop the worker, close the store

While a job moves the robot, motions, recording and cell or project changes raise ``BusyError``
(409): the job owns the robot until it ends or is cancelled.
"""

from __future__ import annotations

import threading
from collections.abc import Callable
from pathlib import Path
from typing import Any

from robomach_core import project as core
from robomach_core.errors import InvalidInputError
from robomach_core.part import MAX_MESH_BYTES, MAX_MESH_TRIANGLES, Workpiece
from robomach_core.project import CellSettings, Project

from ..memory import give_back
from ..store import Store
from .calibration import Calibration
from .jobs import JobRunner
from .learning import Learning
from .machining import MachiningService
from .persistence import Part, save_kwargs
from .pointing import Pointing, pointing_document, pointing_from_document
from .preview import PlacementPreview
from .programs import Programs
from .projects import Loaded, Projects
from .records import ConflictError, GuidePointEntry, NotFoundError, ProjectInfo, Topic, log
from .robot import ROBOT_JOB_KINDS as ROBOT_JOB_KINDS
from .robot import LiveRobot, Pose, View, build_live_cell
from .teach import Teach

# What a change of the project's inputs makes stale, for the listeners to redraw.
DOWNSTREAM_TOPICS: tuple[Topic, ...] = ("recording", "postprocess")
CELL_TOPICS: tuple[Topic, ...] = ("cell", "robot", "guide_points", *DOWNSTREAM_TOPICS)
ALL_TOPICS: tuple[Topic, ...] = ("project", "compliance", "exports", *CELL_TOPICS)
ALL_PARTS: tuple[Part, ...] = ("cell", "guides", "recording", "post")


class Session:
    """The workbench state shared by the GUI and the API (see the module docstring).

    Args:
        store: The project database; a throwaway in-memory one when None.
        data_dir: Folder that saved exports are written under (``<data_dir>/exports``); exports
            are kept only in the store when None.
        max_upload_bytes: Largest mesh file ``upload_workpiece`` takes.
        max_triangles: Most triangles of an uploaded mesh.
        real_time: Pace a person's pushes and jogs to the wall clock (``teach.Teach``).
    """

    def __init__(
        self,
        store: Store | None = None,
        *,
        data_dir: str | Path | None = None,
        max_upload_bytes: int = MAX_MESH_BYTES,
        max_triangles: int = MAX_MESH_TRIANGLES,
        real_time: bool = True,
    ) -> None:
        self.max_upload_bytes = min(max_upload_bytes, MAX_MESH_BYTES)
        self.max_triangles = min(max_triangles, MAX_MESH_TRIANGLES)
        self.store = store or Store(":memory:")
        self.data_dir = Path(data_dir).resolve() if data_dir is not None else None
        self._lock = threading.RLock()
        self._listeners: list[Callable[[Topic], None]] = []
        self._listeners_lock = threading.Lock()
        self._project = Project()
        self._project_id = 0
        self._notice = ""  # about the open project: its stored arm was refused (``projects``)
        self._cell_note: tuple[int, str] = (0, "")  # what the last cell change cleared
        self._closed = False
        self.jobs = JobRunner(on_change=lambda info: self.notify("job"))
        self.robot = LiveRobot(self._lock, self.jobs, save=self._save_robot, notify=self.notify)
        self.teach = Teach(self.robot, real_time=real_time)
        self.pointing = Pointing(self)
        self.preview = PlacementPreview(self)  # a placement being tried (``preview``)
        self.calibration = Calibration(self)
        self.robot.extras = lambda: {
            "pointing": self.pointing.document(),
            "calibration": self.calibration.document(),
        }
        self.learning = Learning(self)
        self.programs = Programs(self)  # the open project's programs, tables, saved exports
        self.projects = Projects(self, self._lock)  # the stored projects (open, files ...)
        self.projects.open_initial()
        from ..studies import StudyService  # (app.studies imports this package)

        self.machining = MachiningService(self)
        self.studies = StudyService(self)  # reads the open project

    # --- listeners ---------------------------------------------------------------------------

    def subscribe(self, callback: Callable[[Topic], None]) -> Callable[[], None]:
        """Call ``callback(topic)`` after every change; returns a function that unsubscribes.

        Topics: robot, compliance, cell, guide_points, recording, postprocess, job, project,
        exports, machining, placement. The callback runs in the thread that made the change (an
        API worker, the job thread, a GUI callback) with the session lock released; keep it
        short, and read what it needs back from the session. Exceptions in it are logged and
        ignored.
        """
        with self._listeners_lock:
            self._listeners.append(callback)

        def unsubscribe() -> None:
            with self._listeners_lock:
                if callback in self._listeners:
                    self._listeners.remove(callback)

        return unsubscribe

    def notify(self, *topics: Topic) -> None:
        """Tell every listener about ``topics`` (call it with the lock released)."""
        with self._listeners_lock:
            listeners = list(self._listeners)
        for topic in topics:
            for callback in listeners:
                try:
                    callback(topic)
                except Exception:
                    log.exception("session listener failed on %r", topic)

    # --- reading -----------------------------------------------------------------------------

    def project(self) -> Project:
        """The open project's job as one value (a snapshot: later changes replace it)."""
        return self._project

    @property
    def project_id(self) -> int:
        return self._project_id

    def view(self) -> View:
        """The project, the live cell, its epoch and the project's id, read together."""
        with self._lock:
            return View(self._project, self.robot.cell, self.robot.epoch, self._project_id)

    def idle_start(self) -> tuple[Project, Pose]:
        """The project and the robot's pose, read together; ``BusyError`` while a job runs."""
        with self._lock:
            return self._project, self.robot.idle_pose()

    def cell_note(self) -> str:
        """What the last cell change cleared and why (a machining choice the new controller
        cannot run), while that cell is the one in use; "" otherwise."""
        epoch, note = self._cell_note
        return note if epoch == self.robot.epoch else ""

    def current_project(self) -> ProjectInfo:
        with self._lock:
            row = self.store.get_project(self._project_id)
            if row is None:
                raise NotFoundError("the open project is no longer in the database")
            return ProjectInfo(row.id, row.name, row.created_s, row.updated_s, True, self._notice)

    # --- changing the project ----------------------------------------------------------------

    def commit(
        self,
        change: Callable[[Project], Project],
        *parts: Part,
        topics: tuple[Topic, ...] = (),
        idle: bool = False,
        with_robot: bool = False,
    ) -> Project:
        """Apply the transition ``change`` to the open project under the lock and save
        ``parts`` of the result (and the robot's pose, ``with_robot``) in one transaction;
        then tell the listeners ``topics``. ``idle``: refused while a job owns the robot. A
        transition that raises changes nothing; one that returns the project as it was saves
        nothing."""
        with self._lock:
            if idle:
                self.robot.require_idle()
            new = change(self._project)
            if new is not self._project:
                # Saved first: a save that fails (a locked database: 503) leaves the session
                # as it was, so a client that retries does not apply the change twice.
                self._save(new, *parts, with_robot=with_robot)
                self._project = new
        self.notify(*topics)
        return new

    def change_cell(
        self,
        change: Callable[[Project], Project],
        *,
        parsed: Workpiece | None = None,
        joints: Any = None,
    ) -> Project:
        """``commit`` a transition that changes the cell: the live cell is rebuilt from the
        new project (``parsed``: its uploaded mesh, already read) and the robot goes home (or
        stays at ``joints``, when they are usable in the new cell: a calibration accepted).
        No change keeps everything (the robot stays where it is)."""
        with self._lock:
            self.robot.require_idle()
            new = change(self._project)
            if new is self._project:
                return new
            # A machining choice the new cell's controller cannot run is cleared, with a note.
            new, note = core.with_runnable_choice(new)
            built = build_live_cell(new.cell, new.mesh, joints, parsed=parsed)
            parts: tuple[Part, ...] = ("cell", "guides", "post") if note else ("cell", "guides")
            self._save(new, *parts, robot=self.robot.document(built))
            self.robot.install(built)
            self._project = new
            self._cell_note = (self.robot.epoch, note)
            del built
        self.notify(*CELL_TOPICS, *(("machining",) if note else ()))
        give_back()  # the old cell (its part's mesh, trees, supervisor) goes back to the OS
        return new

    def set_cell(
        self,
        *,
        robot: str | None = None,
        tool_radius_m: float | None = None,
        workpiece: str | None = None,
        part_deviation: Any = core.KEEP,
        wobj_mm_deg: Any = core.KEEP,
    ) -> CellSettings:
        """Change the cell (``project.with_cell``; None keeps a setting; ``part_deviation``
        and ``wobj_mm_deg``, the work-object placement x, y, z [mm] with an optional rz or
        rx, ry, rz [deg], None for the built-in one: ``core.KEEP`` keeps them): a change puts
        the robot home and clears the guide points (and, moving the part, its calibration);
        no change keeps everything."""

        def change(p: Project) -> Project:
            return core.with_cell(
                p,
                robot=robot,
                tool_radius_m=tool_radius_m,
                workpiece=workpiece,
                part_deviation=part_deviation,
                wobj_mm_deg=wobj_mm_deg,
            )

        return self.change_cell(change).cell

    def upload_workpiece(self, data: bytes, filename: str) -> CellSettings:
        """Use a mesh file (STL/OBJ/PLY, mm) as the workpiece, within ``max_upload_bytes`` and
        ``max_triangles``. Clears the guide points like a ``set_cell`` change."""
        from robomach_core.part import mesh_from_bytes

        if len(data) > self.max_upload_bytes:
            raise InvalidInputError(
                f"{filename}: {len(data) / 1e6:.1f} MB exceeds the "
                f"{self.max_upload_bytes / 1e6:g} MB limit"
            )
        name = core.mesh_file_name(filename)  # a type the workbench reads
        # Parse outside the lock: a big mesh takes a while and must not stall the robot.
        parsed = mesh_from_bytes(
            data, Path(name).suffix, name=Path(name).stem, max_triangles=self.max_triangles
        )
        change = lambda p: core.with_uploaded_mesh(p, filename, data)  # noqa: E731
        return self.change_cell(change, parsed=parsed).cell

    def upload_robot(self, data: bytes, filename: str, *, family: str = "auto") -> CellSettings:
        """Use a user's serial 6-axis URDF (a .urdf, or a .zip with its meshes) as the arm
        (``robots.custom``; ``family`` names its controller, ``auto`` recognises a built-in
        arm's kinematics); kept in the project, so that it opens again anywhere."""
        from robomach_core.robots.custom import register_urdf

        name = register_urdf(filename, data, family)
        change = lambda p: core.with_robot_file(p, filename, data, name)  # noqa: E731
        return self.change_cell(change).cell

    def record_guide_point(self) -> GuidePointEntry:
        """Record the current pose as the next guide point."""
        project = self.commit(
            lambda p: core.with_guide_point_added(p, self.robot.record()),
            "guides",
            topics=("guide_points", *DOWNSTREAM_TOPICS),
            idle=True,
        )
        return GuidePointEntry(len(project.guide_points) - 1, project.guide_points[-1])

    def delete_guide_point(self, index: int) -> None:
        """Delete the guide point at ``index``; later points move down by one."""
        change = lambda p: core.without_guide_point(p, index)  # noqa: E731
        self.commit(change, "guides", topics=("guide_points", *DOWNSTREAM_TOPICS))

    def clear_guide_points(self) -> None:
        change = lambda p: core.with_guide_points(p, ())  # noqa: E731
        self.commit(change, "guides", topics=("guide_points", *DOWNSTREAM_TOPICS))

    def switch_to(self, loaded: Loaded, *, epoch: int | None = None, save: bool = False) -> None:
        """Make ``loaded`` the open project (``projects``); ``epoch``: refused when the cell
        changed since it was read; ``save``: store it whole (an imported file).

        Raises:
            ConflictError: the cell or project changed since ``epoch``.
        """
        with self._lock:
            self.robot.require_idle()
            if epoch is not None and epoch != self.robot.epoch:
                raise ConflictError("the cell or project changed while opening; open it again")
            if self.store.get_project(loaded.project_id) is None:
                # Deleted while it was read (outside the lock): nothing opens. It opened, and
                # every later read of it answered 503 (issue 32).
                raise NotFoundError(f"project {loaded.project_id} was deleted while it opened")
            pointing = pointing_from_document(loaded.pointing)
            if save:
                robot = self.robot.document(loaded.built, loaded.selection)
                robot["pointing"] = pointing_document(*pointing)
                robot["calibration"] = loaded.calibration
                self._save(loaded.project, *ALL_PARTS, robot=robot, project_id=loaded.project_id)
            self.store.set_last_project(loaded.project_id)
            self.robot.install(loaded.built, loaded.selection)
            self.pointing.settings, self.pointing.click_mode = pointing
            self.calibration.restore(loaded.calibration, loaded.project)
            self._project_id, self._project = loaded.project_id, loaded.project
            self._notice = loaded.notice
        self.notify(*ALL_TOPICS)
        give_back()  # the project and the cell it replaced

    # --- lifecycle ---------------------------------------------------------------------------

    def close(self) -> None:
        """Cancel jobs, stop the worker and close the store (a second call does nothing)."""
        with self._lock:
            if self._closed:
                return
            self._closed = True
            self.robot.close()
        self.jobs.close()
        with self._lock:
            self.store.close()

    # --- internals ---------------------------------------------------------------------------

    def _save(
        self,
        project: Project,
        *parts: Part,
        with_robot: bool = False,
        robot: dict[str, Any] | None = None,
        project_id: int | None = None,
    ) -> None:
        """Store ``parts`` of ``project`` (and the robot: its document now, ``with_robot``, or
        the given ``robot``) in one transaction, before the session takes them on."""
        project_id = self._project_id if project_id is None else project_id
        whole = bool(self._notice) and project_id == self._project_id
        if whole:  # opened without its refused arm: the first change saves it as it is now
            parts, with_robot = ALL_PARTS, with_robot or robot is None
        kwargs = save_kwargs(project, *parts)
        if with_robot:
            kwargs["robot"] = self.robot.document()
        if robot is not None:
            kwargs["robot"] = robot
        self.store.save(project_id, **kwargs)
        if whole:
            self._notice = ""

    def _save_robot(self, document: dict[str, Any] | None = None) -> None:
        self.store.save(self._project_id, robot=document or self.robot.document())
