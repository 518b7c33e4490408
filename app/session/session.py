"""The workbench session: the one mutable state of a running ``robomach serve``.

PROBLEM   The viser GUI and the REST API act on the same simulated cell, from different
          threads, while long jobs (the example lead-through, path learning) run in the
          background; every change must be saved at once.
STRATEGY  The job itself is one frozen ``robomach_core.project.Project`` value (cell, guide
          points, recording, post-processing, CMRR and compensation settings, machining slot),
          replaced atomically under one ``threading.RLock``; its stages and writers are the
          core's (``learn``, ``process``, ``program_files``), the same the CLI calls. The
          session holds beside it only what is live: the cell and lead-through state, the
          compliance selection, jobs, listeners and the store. Long work (jobs, and
          post-processing) computes from a snapshot of the value outside the lock and swaps its
          result in only if its inputs did not change meanwhile. Listeners registered with
          ``subscribe`` hear a topic name after each change. The projects half (open, create,
          rename, delete, save) is ``projects.ProjectsMixin``, which the Session inherits.
SOLUTION  Public API (all thread-safe):

  Reading
    project() -> Project                    the job, as one value (with ``status()``)
    status() -> dict[stage, none|current|stale], stale_reasons() -> dict[stage, str]
    snapshot() -> RobotSnapshot             joints, TCP pose, measured wrench, contact, busy
    cell_settings() -> CellSettings         robot, tool radius, workpiece, seed
    cell / workpiece                        the Cell and its Workpiece (read only: never step)
    compliance -> ComplianceSelection
    guide_points() -> list[GuidePoint]
    recording() -> Recording | None         the last path-learning recording
    force_trace(max_points) -> ForceTrace   decimated force vs time: live while learning
    postprocess_settings() -> PostprocessSettings
    postprocess_outcome() -> ProcessedPath | None
    learning_settings() -> PathLearningSettings | None   of the last recording
    job(job_id) / jobs() -> JobInfo         status and progress of background jobs
    current_project() / projects() -> ProjectInfo
  Acting (each saves before returning)
    set_cell(robot=, tool_radius_m=, workpiece=) -> CellSettings   a change clears the guide
                                            points and leaves the results stale; no change
                                            keeps everything
    upload_workpiece(data, filename) -> CellSettings
    set_process_settings(cmrr=, compensation=) -> Project   what the exported program carries
    set_compliance(axes, frame) -> ComplianceSelection
    push(wrench6, duration_s) -> RobotSnapshot        wrench [N, N*m] at the TCP, base axes
    jog(axis, step, frame=, speed=) -> RobotSnapshot   step [m] or [rad], tool/base/wobj frame
    touch_off(axis, direction, force_N, max_travel_m, frame=) -> RobotSnapshot
    stop_motion()                           the person let go: the running motion ends
    tool_view() -> teach.ToolView           gap to the nearest wall, force, table clearance
    (pushes, jogs and touch-offs run at wall-clock speed: see ``teach.py``)
    go_home() -> RobotSnapshot
    record_guide_point() -> GuidePointEntry
    delete_guide_point(index) / clear_guide_points()
    start_example() -> job_id               scripted lead-through (replaces guide points)
    start_path_learning(force_N, speed_m_s, closed=True) -> job_id
    cancel_job(job_id) -> JobInfo
    run_postprocess(force_min_N=, force_max_N=, tolerance_m=) -> ProcessedPath
    rapid_module(module_name=, force_control=) / samples_csv() / targets_csv() /
    settings_json() -> str                  the core's writers; stale results are refused
    save_export(name) -> ExportInfo         all files into the store and <data>/exports/
    create_project(name) / open_project(id) / rename_project(id, name) / delete_project(id)
  Listening
    subscribe(callback) -> unsubscribe      callback(topic: Topic), called after the change
                                            from the thread that made it, lock released
  Lifecycle
    close()                                 cancel jobs, stop the worker, close the store

While a job moves the robot, pushes, jogs, recording and cell or project changes raise
``BusyError`` (409): the job owns the robot until it ends or is cancelled.
"""

from __future__ import annotations

import json
import re
import threading
from collections.abc import Callable, Iterable
from dataclasses import replace
from pathlib import Path
from typing import Any

import numpy as np

from robomach_core import limits, mesh_query
from robomach_core import project as core
from robomach_core.cell import Cell, CellState
from robomach_core.errors import (
    InvalidInputError,
    NotEnoughGuidePointsError,
    SupervisionError,
)
from robomach_core.leadthrough import (
    AXES,
    ComplianceSelection,
    GuidePoint,
    LeadThrough,
    LeadThroughState,
)
from robomach_core.path_learning import PathLearningSettings, Recording
from robomach_core.postprocess import PostprocessSettings
from robomach_core.project import CellSettings, ProcessedPath, Project, StageStatus
from robomach_core.workpiece import (
    MAX_MESH_BYTES,
    MAX_MESH_TRIANGLES,
    MESH_SUFFIXES,
    WORKPIECE_NAMES,
    Workpiece,
    mesh_from_bytes,
)

from ..store import Store
from . import exports
from .exports import check_export_name, rapid_identifier_or
from .jobs import (
    JobContext,
    JobRunner,
)
from .live import LiveFeed
from .pointing import Pointing
from .projects import ProjectsMixin, _build_cell
from .records import (
    MAX_GUIDE_POINTS,
    BusyError,
    ConflictError,
    ExportInfo,
    ForceTrace,
    GuidePointEntry,
    JobInfo,
    NotFoundError,
    RobotSnapshot,
    Topic,
    log,
)
from .teach import JogFrame, Teach, ToolView

# --- the session ---------------------------------------------------------------------------

EXAMPLE_CLEARANCE_M = 0.008  # the example operator lifts the tool this far above the part


def _example_intents(cell: Cell, seed: int) -> list | None:
    """The example operator's points: its own plan (None), or, on a part that is not where its
    mesh is, the same entered in each groove's middle (``guide_proposal.robust_intents``)."""
    if cell.workpiece.nominal is None:
        return None
    from robomach_core.demo_operator import guide_plan
    from robomach_core.guide_proposal import robust_intents

    plan = guide_plan(cell.workpiece.cad(), cell.tool.radius_m, np.random.default_rng(seed))
    return robust_intents(plan, cell.workpiece, cell.tool.radius_m)


def _squared(lt: LeadThrough, state: LeadThroughState, cad: Workpiece) -> LeadThroughState:
    """The tool lifted clear of the part (when below its top) and turned square to it (tool
    axis down, as the example operator holds it), by supervised jogs of at most 45 degrees."""
    from robomach_core.demo_operator import TOOL_DOWN
    from robomach_core.teach_motion import move_by, turn_to

    top = float(cad.mesh_in_base().bounds[1, 2]) + EXAMPLE_CLEARANCE_M
    z = float(state.cell.T_base_tcp[2, 3])
    if z < top:
        state = move_by(lt, state, np.array([0.0, 0.0, top - z]), 0.05)
    return turn_to(lt, state, TOOL_DOWN)


ROBOT_JOB_KINDS = ("example", "path_learning", "accept_proposal")
_KEEP: Any = object()  # set_cell: leave this setting as it is
# What a change of the project's inputs makes stale, for the listeners to redraw.
DOWNSTREAM_TOPICS: tuple[Topic, ...] = ("recording", "postprocess")


class Session(ProjectsMixin):
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
        self._lock = threading.RLock()
        self._last_snapshot: RobotSnapshot | None = None  # snapshot(wait=False) while locked
        self._listeners: list[Callable[[Topic], None]] = []
        self._listeners_lock = threading.Lock()
        self.store = store or Store(":memory:")
        self.data_dir = Path(data_dir).resolve() if data_dir is not None else None
        self.jobs = JobRunner(on_change=lambda info: self._notify("job"))
        self._project = Project()
        self._epoch = 0  # bumped when the cell or project changes; stale job results are dropped
        self._live = LiveFeed(on_move=lambda: self._notify("robot"))
        self._project_id = 0
        self._closed = False
        self.teach = Teach(self, real_time=real_time)
        self.pointing = Pointing(self)
        self._open_initial_project()

    # --- listeners ---------------------------------------------------------------------------

    def subscribe(self, callback: Callable[[Topic], None]) -> Callable[[], None]:
        """Call ``callback(topic)`` after every change; returns a function that unsubscribes.

        Topics: robot, compliance, cell, guide_points, recording, postprocess, job, project,
        exports. The callback runs in the thread that made the change (an API worker, the job
        thread, a GUI callback) with the session lock released; keep it short, and read what it
        needs back from the session. Exceptions in it are logged and ignored.
        """
        with self._listeners_lock:
            self._listeners.append(callback)

        def unsubscribe() -> None:
            with self._listeners_lock:
                if callback in self._listeners:
                    self._listeners.remove(callback)

        return unsubscribe

    def _notify(self, *topics: Topic) -> None:
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

    def status(self) -> dict[str, StageStatus]:
        """Per stage (guide_points, recording, postprocess, machining): none, current, stale."""
        return self._project.status()

    def stale_reasons(self) -> dict[str, str]:
        """Why each stale stage is out of date."""
        return self._project.stale_reasons()

    @property
    def cell(self) -> Cell:
        """The simulated cell (read its robot, tool and workpiece; never step it)."""
        return self._cell

    @property
    def workpiece(self) -> Workpiece:
        """The part the cell's tool meets (the real part when it deviates from its mesh:
        programs are scored against it)."""
        return self._cell.workpiece

    @property
    def cad_workpiece(self) -> Workpiece:
        """The part as its mesh: what the user sees, teaches on and is checked against."""
        return self._cell.workpiece.cad()

    @property
    def compliance(self) -> ComplianceSelection:
        return self._selection

    def busy(self) -> bool:
        """True while a job owns the robot."""
        return bool(self.jobs.active(ROBOT_JOB_KINDS))

    def snapshot(self, *, wait: bool = True) -> RobotSnapshot:
        """The robot now (live during a job).

        ``wait=False`` never waits for the session lock: while a change holds it, the answer is
        the last snapshot taken, the state just before that change (``GET /api/state`` answers
        on the server's event loop, which must never block)."""
        if not self._lock.acquire(blocking=wait):
            last = self._last_snapshot
            if last is not None:
                # busy from the job runner (its own lock): a job that just ended while its
                # end still holds the session lock must not read as running
                return replace(last, busy=self.busy())
            self._lock.acquire()
        try:
            busy = self.busy()
            live = self._live.cell_state
            cs = live if (busy and live is not None) else self._lt_state.cell
            wrench = self._lt.measured_wrench(cs)
            snap = RobotSnapshot(
                float(cs.time_s),
                cs.q_motor.copy(),
                cs.T_base_tcp.copy(),
                wrench,
                bool(cs.in_contact),
                busy,
            )
            self._last_snapshot = snap
            return snap
        finally:
            self._lock.release()

    def cell_settings(self) -> CellSettings:
        return self._project.cell

    def guide_points(self) -> list[GuidePoint]:
        return list(self._project.guide_points)

    def recording(self) -> Recording | None:
        learned = self._project.learned
        return None if learned is None else learned.recording

    def learning_settings(self) -> PathLearningSettings | None:
        """The settings of the last recording."""
        learned = self._project.learned
        return None if learned is None else learned.settings

    def postprocess_settings(self) -> PostprocessSettings:
        return self._project.post_settings

    def postprocess_outcome(self) -> ProcessedPath | None:
        return self._project.processed

    def job(self, job_id: str) -> JobInfo:
        return self.jobs.get(job_id)

    def force_trace(self, max_points: int = 2000) -> ForceTrace:
        """Force vs time, at most ``max_points`` (>= 2) by stride: live during a job."""
        with self._lock:
            return self._live.force_trace(self.recording(), self.busy(), max_points)

    # --- cell --------------------------------------------------------------------------------

    def set_cell(
        self,
        *,
        robot: str | None = None,
        tool_radius_m: float | None = None,
        workpiece: str | None = None,
        part_deviation: Any = _KEEP,
    ) -> CellSettings:
        """Change the cell; None keeps a setting (``part_deviation``: a
        ``real_part.PartDeviation``, None for a part that is its mesh; omitted keeps it). A
        request that changes nothing keeps all work (the robot stays where it is). A change
        puts the robot home and clears the guide points (poses of the old cell); the
        recording and results stay, marked stale."""
        with self._lock:
            self._require_idle()
            cur, mesh = self._project.cell, self._project.mesh
            new = replace(
                cur,
                robot=cur.robot if robot is None else robot.lower(),
                tool_radius_m=cur.tool_radius_m if tool_radius_m is None else float(tool_radius_m),
                part_deviation=cur.part_deviation if part_deviation is _KEEP else part_deviation,
            )
            if workpiece in WORKPIECE_NAMES:
                new, mesh = replace(new, workpiece=workpiece, workpiece_builtin=True), None
            elif workpiece is not None and not (mesh is not None and workpiece == cur.workpiece):
                uploaded = f", or {cur.workpiece!r} (uploaded)" if mesh is not None else ""
                raise InvalidInputError(
                    f"unknown workpiece {workpiece!r}; use one of {', '.join(WORKPIECE_NAMES)}"
                    f"{uploaded}, or upload a mesh file"
                )
            if new == cur and mesh == self._project.mesh:
                return cur
            self._change_cell(new, mesh)
        self._notify("cell", "robot", "guide_points", *DOWNSTREAM_TOPICS)
        return new

    def upload_workpiece(self, data: bytes, filename: str) -> CellSettings:
        """Use a mesh file (STL/OBJ/PLY, mm) as the workpiece, within ``max_upload_bytes`` and
        ``max_triangles``. Clears the guide points like a ``set_cell`` change."""
        suffix = Path(filename).suffix.lower()
        if suffix not in MESH_SUFFIXES:
            raise InvalidInputError(
                f"{filename!r}: unsupported mesh type; upload one of {', '.join(MESH_SUFFIXES)}"
            )
        if len(data) > self.max_upload_bytes:
            raise InvalidInputError(
                f"{filename}: {len(data) / 1e6:.1f} MB exceeds the "
                f"{self.max_upload_bytes / 1e6:g} MB limit"
            )
        stem = re.sub(r"[^A-Za-z0-9_-]", "_", Path(filename).stem)[:40] or "uploaded"
        # Parse outside the lock: a big mesh takes a while and must not stall the robot.
        parsed = mesh_from_bytes(data, suffix, name=stem, max_triangles=self.max_triangles)
        with self._lock:
            self._require_idle()
            new = replace(self._project.cell, workpiece=stem, workpiece_builtin=False)
            self._change_cell(new, (stem + suffix, data), parsed=parsed)
        self._notify("cell", "robot", "guide_points", *DOWNSTREAM_TOPICS)
        return new

    def _change_cell(
        self, settings: CellSettings, mesh: tuple[str, bytes] | None, *, parsed: Any = None
    ) -> None:
        from robomach_core.robots.custom import is_custom

        self._install_cell(settings, mesh, joints=None, parsed=parsed)
        self._project = replace(self._project, cell=settings, mesh=mesh, guide_points=())
        if self._project.robot_urdf is not None and not is_custom(settings.robot):
            self._project = replace(self._project, robot_urdf=None)  # back to a built-in arm
        self._save("cell", "guides", with_robot=True)

    def set_process_settings(self, *, cmrr: Any = None, compensation: Any = None) -> Project:
        """Choose the CMRR controller settings (``cmrr.CmrrSettings``) and the compensation
        settings (``stiffness.CompensationSettings``) the exported program carries; None
        removes one. Compensation identified on another robot is refused."""
        with self._lock:
            if compensation is not None and compensation.robot != self._project.cell.robot:
                raise InvalidInputError(
                    f"the compensation settings were identified on {compensation.robot}, "
                    f"the cell has {self._project.cell.robot}"
                )
            self._project = replace(self._project, cmrr=cmrr, compensation=compensation)
            self._save("post")
            project = self._project
        self._notify("postprocess")
        return project

    # --- lead-through ------------------------------------------------------------------------

    def set_compliance(self, axes: Iterable[str], frame: str) -> ComplianceSelection:
        """Select the compliant axes (any of x y z rx ry rz) in the "tool" or "base" frame."""
        axes = frozenset(axes)
        selection = ComplianceSelection(axes, frame)  # validates
        with self._lock:
            self._selection = selection
            self._save_robot()
        self._notify("compliance")
        return selection

    def push(self, wrench: np.ndarray, duration_s: float) -> RobotSnapshot:
        """Push the tool with a constant wrench (6,) [N, N*m] at the TCP, base axes, for
        ``duration_s`` under admittance control on the compliant axes; the force's and the
        torque's magnitudes and the duration within ``limits.PUSH_FORCE_N``,
        ``PUSH_TORQUE_NM`` and ``PUSH_DURATION_S``."""
        w = np.asarray(wrench, dtype=float)
        if w.shape != (6,) or not np.all(np.isfinite(w)):
            raise InvalidInputError("a push is 6 finite values: force [N] and torque [N*m]")
        limits.PUSH_FORCE_N.check(float(np.linalg.norm(w[:3])), "push force magnitude [N]")
        limits.PUSH_TORQUE_NM.check(float(np.linalg.norm(w[3:])), "push torque magnitude [N*m]")
        limits.PUSH_DURATION_S.check(duration_s, "push duration [s]")
        self.teach.push(w, duration_s)
        return self.snapshot()

    def jog(
        self, axis: str, step: float, *, frame: JogFrame = "tool", speed: float | None = None
    ) -> RobotSnapshot:
        """Force-control jogging: move ``step`` [m] along, or [rad] about, an axis of ``frame``
        (tool, base or wobj) at ``speed`` [m/s or rad/s]; the compliant axes keep answering to
        the contact force."""
        self.teach.jog(axis, float(step), frame=frame, speed=speed)
        return self.snapshot()

    def touch_off(
        self,
        axis: str,
        direction: int,
        force_N: float,
        max_travel_m: float,
        *,
        frame: JogFrame = "base",
    ) -> RobotSnapshot:
        """Guarded move along an axis until contact at ``force_N`` (``teach.Teach.touch_off``)."""
        self.teach.touch_off(axis, direction, force_N, max_travel_m, frame=frame)  # type: ignore[arg-type]
        return self.snapshot()

    def stop_motion(self) -> None:
        """The person let go: the running push, jog or touch-off ends within a period."""
        self.teach.stop()

    def tool_view(self) -> ToolView:
        return self.teach.tool_view()

    def go_home(self) -> RobotSnapshot:
        """Put the robot back at its home pose (a reset of the simulation, not a move)."""
        with self._lock:
            self._require_idle()
            self._install_cell(self._project.cell, self._project.mesh, joints=None)
            self._save_robot()
        self._notify("robot")
        return self.snapshot()

    # --- guide points ------------------------------------------------------------------------

    def record_guide_point(self) -> GuidePointEntry:
        """Record the current pose as the next guide point."""
        with self._lock:
            self._require_idle()
            guides = self._project.guide_points
            if len(guides) >= MAX_GUIDE_POINTS:
                raise ConflictError(f"a project holds at most {MAX_GUIDE_POINTS} guide points")
            point = self._lt.record(self._lt_state)
            self._set_guides((*guides, point))
            entry = GuidePointEntry(len(guides), point)
        self._notify("guide_points", *DOWNSTREAM_TOPICS)
        return entry

    def delete_guide_point(self, index: int) -> None:
        """Delete the guide point at ``index``; later points move down by one."""
        with self._lock:
            guides = self._project.guide_points
            if not (0 <= index < len(guides)):
                raise NotFoundError(
                    f"no guide point {index}; there are {len(guides)} (indexes from 0)"
                )
            self._set_guides(guides[:index] + guides[index + 1 :])
        self._notify("guide_points", *DOWNSTREAM_TOPICS)

    def clear_guide_points(self) -> None:
        with self._lock:
            self._set_guides(())
        self._notify("guide_points", *DOWNSTREAM_TOPICS)

    def _set_guides(self, guides: tuple[GuidePoint, ...], *, with_robot: bool = False) -> None:
        """New guide points; the recording and its results become stale (by fingerprint)."""
        self._project = replace(self._project, guide_points=tuple(guides))
        self._save("guides", with_robot=with_robot)

    # --- jobs --------------------------------------------------------------------------------

    def start_example(self) -> str:
        """Job: the scripted operator leads the robot by pushes to the example guide points of
        the built-in workpiece; on success they replace the guide points. Returns the job id."""
        from robomach_core.demo_operator import scripted_leadthrough

        with self._lock:
            self._require_idle()
            if self._cell.workpiece.wall is None:
                raise InvalidInputError(
                    f"the example lead-through needs a built-in workpiece, not "
                    f"{self._cell.workpiece.name!r}; click its wall to propose guide points, "
                    "or lead the robot by pushes"
                )
            epoch, cell, estimator = self._epoch, self._cell, self._lt.estimator
            start, seed = self._lt_state, self._project.cell.seed

            def work(ctx: JobContext) -> tuple[LeadThroughState, list[GuidePoint]]:
                lt = LeadThrough(self._live.tapped(cell, estimator, ctx), estimator=estimator)
                try:
                    # Hand teaching may have left the tool turned and in the part: the operator
                    # first lifts it clear and turns it square in steps (a jog turns 45 deg at
                    # most), as a person would.
                    state = _squared(lt, start, cell.workpiece.cad())
                    return scripted_leadthrough(
                        lt,
                        state,
                        cell.workpiece.cad(),  # the operator plans on the mesh they see
                        np.random.default_rng(seed),
                        intents=_example_intents(cell, seed),
                        progress=ctx.progress,
                    )
                except SupervisionError as exc:
                    raise exc.with_note(
                        f"the part may be beyond the {cell.robot.name} arm's reach: choose a "
                        "larger arm, or press Home first"
                    ) from None

            def done(result: tuple[LeadThroughState, list[GuidePoint]]) -> None:
                state, guides = result
                with self._lock:
                    if epoch != self._epoch:
                        raise ConflictError("the cell changed while the example ran")
                    self._lt_state = replace(state, velocity=np.zeros(6))
                    self._set_guides(tuple(guides), with_robot=True)
                self._notify("robot", "guide_points", *DOWNSTREAM_TOPICS)

            return self._submit_robot_job("example", work, done, epoch)

    def start_path_learning(
        self,
        force_N: float,
        speed_m_s: float,
        *,
        closed: bool = True,
        wall_side: str = "auto",
        floor_clearance_m: float | None = None,
    ) -> str:
        """Job: learn the path through the guide points at ``force_N`` and ``speed_m_s``
        (``project.learn``) along the wall on ``wall_side``; on success the recording replaces
        the last one, and the last post-processing stays, marked stale. A force filter band
        that would not keep samples at ``force_N`` moves to 0.5-1.5 x ``force_N``
        (``PostprocessSettings.holds_force``). "auto" takes the side of guide points taught
        by pointing at the wall (``pointing.learning_side``) when they are still those.
        Returns the job id.

        Raises:
            WallSideError: "auto" and the guide points do not tell the side (before any job).
        """
        if wall_side == "auto":
            wall_side = self.pointing.learning_side() or "auto"
        settings = PathLearningSettings(
            force_N=float(force_N),
            speed_m_s=float(speed_m_s),
            closed=bool(closed),
            wall_side=wall_side,
            **({} if floor_clearance_m is None else {"floor_clearance_m": floor_clearance_m}),
        )
        with self._lock:
            self._require_idle()
            project = self._project
            if len(project.guide_points) < 2:
                raise NotEnoughGuidePointsError(
                    f"path learning needs at least 2 guide points, got {len(project.guide_points)}"
                )
            epoch, cell, estimator = self._epoch, self._cell, self._lt.estimator
            start = self._lt_state.cell
            from robomach_core.wall_side import resolve_wall_side

            with mesh_query.LOCK:
                resolve_wall_side(  # refuse now, with the cause, not as a failed job
                    project.guide_points,
                    settings.wall_side,
                    closed=settings.closed,
                    workpiece=cell.workpiece.cad(),  # the mesh the user sees
                    tool_radius_m=project.cell.tool_radius_m,
                )

            def work(ctx: JobContext) -> tuple[core.LearnedPath, CellState]:
                path_m = np.array([g.position_m for g in project.guide_points])
                return core.learn(
                    project,
                    self._live.tapped(cell, estimator, ctx, path_m=path_m, closed=closed),
                    start,
                    settings,
                    estimator,
                    progress=ctx.progress,
                    cancelled=ctx.cancelled,
                )

            def done(result: tuple[core.LearnedPath, CellState]) -> None:
                learned, end = result
                with self._lock:
                    if epoch != self._epoch:
                        raise ConflictError("the cell changed while path learning ran")
                    self._lt_state = LeadThroughState(end, end.T_base_tcp.copy(), np.zeros(6))
                    post = self._project.post_settings
                    if not post.holds_force(force_N):  # learned at a force outside the band
                        post = post.with_band_for(force_N)
                    self._project = replace(self._project, learned=learned, post_settings=post)
                    self._save("recording", "post", with_robot=True)
                self._notify("robot", *DOWNSTREAM_TOPICS)

            return self._submit_robot_job("path_learning", work, done, epoch)

    def cancel_job(self, job_id: str) -> JobInfo:
        """Cancel a job (a running one stops within a few milliseconds of compute)."""
        return self.jobs.cancel(job_id)

    def _submit_robot_job(
        self,
        kind: str,
        work: Callable[[JobContext], Any],
        done: Callable[[Any], None],
        epoch: int,
    ) -> str:
        self._live.start(self._lt_state.cell)

        def end(info: JobInfo) -> None:
            # Cancelled or failed: the robot stays where the job left it (nothing teleports).
            with self._lock:
                live = self._live.stop()
                if info.status != "done" and live is not None and epoch == self._epoch:
                    self._lt_state = LeadThroughState(live, live.T_base_tcp.copy(), np.zeros(6))
                    self._save_robot()
            self._notify("robot")

        return self.jobs.submit(kind, work, on_done=done, on_end=end)

    # --- post-processing and exports ---------------------------------------------------------

    def run_postprocess(
        self,
        *,
        force_min_N: float | None = None,
        force_max_N: float | None = None,
        tolerance_m: float | None = None,
        arcs: bool | None = None,
        arc_tolerance_m: float | None = None,
    ) -> ProcessedPath:
        """Filter, reduce and score the last recording (``project.process``); None keeps a
        setting. It computes outside the lock from a snapshot of the project, so reads never
        wait for it, and swaps the result in only if the recording and cell did not change."""
        with self._lock:
            project, epoch, workpiece = self._project, self._epoch, self._cell.workpiece
        cur = project.post_settings
        settings = replace(
            cur,
            force_min_N=cur.force_min_N if force_min_N is None else float(force_min_N),
            force_max_N=cur.force_max_N if force_max_N is None else float(force_max_N),
            tolerance_m=cur.tolerance_m if tolerance_m is None else float(tolerance_m),
            arcs=cur.arcs if arcs is None else bool(arcs),
            arc_tolerance_m=cur.arc_tolerance_m if arc_tolerance_m is None else arc_tolerance_m,
        )
        if project.learned is None:
            raise ConflictError("nothing to post-process yet: run path learning first")
        with mesh_query.LOCK:  # the scores query the mesh's trees, one thread at a time
            outcome = core.process(
                project.learned,
                settings,
                workpiece,
                project.cell.tool_radius_m,
                guides=project.guide_points,
            )
        with self._lock:
            if self._project.learned is not project.learned or epoch != self._epoch:
                raise ConflictError(
                    "the recording or the cell changed while post-processing ran; run it again"
                )
            self._project = replace(self._project, post_settings=settings, processed=outcome)
            self._save("post")
        self._notify("postprocess")
        return outcome

    def rapid_module(
        self, *, module_name: str = core.DEFAULT_MODULE_NAME, force_control: bool = False
    ) -> str:
        """The RAPID module of the project (``project.rapid_text``): the FC SpeedChange block
        with a CMRR controller, compensated targets in the offline compensation modes, or the
        FC pressure variant. Refused on an arm whose controller does not run RAPID."""
        files = self.program_texts("rapid", module_name=module_name, force_control=force_control)
        return next(iter(files.values()))

    def urscript_program(self, *, force_control: bool = False) -> str:
        """The project's program as URScript (``project.urscript_text``)."""
        files = self.program_texts("urscript", force_control=force_control)
        return next(iter(files.values()))

    def program_texts(
        self,
        language: str,
        *,
        force_control: bool = False,
        module_name: str = core.DEFAULT_MODULE_NAME,
    ) -> dict[str, str]:
        """The project's program in a registered language the arm's controller runs
        (``project.program_texts``): file name -> text."""
        from robomach_core.export.languages import resolve_languages

        with self._lock:
            project, workpiece, robot = self._project, self._cell.workpiece, self._cell.robot
        (lang,) = resolve_languages(robot, language)
        return core.program_texts(
            project,
            workpiece,
            robot,
            lang.name,
            module_name=module_name,
            force_control=force_control,
        )

    def program_languages(self) -> tuple[str, ...]:
        """The languages the cell's arm is offered (``export.languages.languages_for``)."""
        from robomach_core.export.languages import languages_for

        return tuple(lang.name for lang in languages_for(self._cell.robot))

    def guide_findings(
        self, force_N: float = 10.0, *, closed: bool = True, wall_side: str = "auto"
    ) -> tuple:
        """What the operator check finds in the guide points (``guide_check``)."""
        from robomach_core.path_learning import PathLearningSettings

        with self._lock:
            project, robot = self._project, self._cell.robot
            workpiece = self._cell.workpiece.cad()  # checks use the mesh the user sees
        settings = PathLearningSettings(force_N=force_N, closed=closed, wall_side=wall_side)
        with mesh_query.LOCK:  # the mesh's nearest-point tree answers one thread at a time
            return self._guide_findings(project, settings, workpiece, robot)

    @staticmethod
    def _guide_findings(project, settings, workpiece, robot) -> tuple:
        from robomach_core.guide_check import guide_point_warnings

        return guide_point_warnings(
            project.guide_points,
            settings,
            workpiece=workpiece,
            tool_radius_m=project.cell.tool_radius_m,
            robot=robot,
        )

    def taught_wall_preview(
        self, wall_side: str = "auto", *, closed: bool = True
    ) -> tuple[list, str]:
        """The wall the next run would follow: its point at each guide point (base frame, None
        where none is near) and one line saying which side and why, or why it cannot tell."""
        from robomach_core.errors import WallSideError
        from robomach_core.wall_side import resolve_wall_side, taught_wall_points

        with self._lock:
            project, workpiece = self._project, self._cell.workpiece.cad()
        guides, radius = project.guide_points, project.cell.tool_radius_m
        if len(guides) < 2:
            return [], ""
        if wall_side == "auto":  # as start_path_learning decides it
            wall_side = self.pointing.learning_side() or "auto"
        try:
            with mesh_query.LOCK:
                decision = resolve_wall_side(
                    guides, wall_side, closed=closed, workpiece=workpiece, tool_radius_m=radius
                )
                points = taught_wall_points(
                    guides, decision.side, closed=closed, workpiece=workpiece, tool_radius_m=radius
                )
        except WallSideError as exc:
            return [], f"wall side: {exc}"
        return points, f"follows the wall on the {decision.side}: {decision.detail}"

    def guide_warnings(
        self, force_N: float, *, closed: bool = True, wall_side: str = "auto"
    ) -> list[str]:
        """The operator check's findings (``guide_findings``) as messages."""
        found = self.guide_findings(force_N, closed=closed, wall_side=wall_side)
        return [w.message for w in found]

    def upload_robot(self, data: bytes, filename: str, *, family: str = "auto") -> CellSettings:
        """Use a user's serial 6-axis URDF (a .urdf, or a .zip with its meshes) as the arm
        (``robots.custom``; ``family`` names its controller, ``auto`` recognises a built-in
        arm's kinematics); kept in the project like an uploaded mesh. Clears the guide points
        like a ``set_cell`` change."""
        from robomach_core.robots.custom import register_urdf

        name = register_urdf(filename, data, family)
        with self._lock:
            self._require_idle()
            self._project = replace(self._project, robot_urdf=(filename, data))
            new = replace(self._project.cell, robot=name)
            self._change_cell(new, self._project.mesh)
        self._notify("cell", "robot", "guide_points", *DOWNSTREAM_TOPICS)
        return new

    def samples_csv(self) -> str:
        """Every recorded sample with the force filter's verdict (mm, N, degrees); the
        recording is the raw data, so it is given even when it is stale."""
        from robomach_core.export.tables import samples_csv

        project = self._project
        if project.learned is None:
            raise ConflictError("no recording yet: run path learning first")
        processed, keep = project.processed, None
        if processed is not None and processed.inputs == core.processed_inputs_key(
            project.learned, processed.settings
        ):
            keep = processed.result.keep_mask
        return samples_csv(project.learned.recording, keep)

    def targets_csv(self) -> str:
        """The post-processed targets (mm, degrees, mm/s; ``project.targets_text``)."""
        with self._lock:
            project, robot = self._project, self._cell.robot
        return core.targets_text(project, robot)

    def settings_json(self) -> str:
        """``project.settings_document`` with the project name and compliance selection."""
        with self._lock:
            doc = core.settings_document(
                self._project,
                self._cell.workpiece,
                project_name=self.current_project().name,
                compliance=self._compliance_doc(),
            )
        return json.dumps(doc, indent=2) + "\n"

    def _compliance_doc(self) -> dict[str, Any]:
        return {
            "axes": [a for a in AXES if a in self._selection.axes],
            "frame": self._selection.frame,
        }

    def save_export(self, name: str) -> ExportInfo:
        """Save ``project.program_files`` (program.mod, program_fc.mod, samples.csv,
        targets.csv, settings.json) under ``name`` (letters, digits, ``_ . -``; 1-64
        characters) in the store and in ``<data_dir>/exports/<project id>/<name>/``; the same
        name replaces the files. A stale post-processing is refused."""
        check_export_name(name)
        with self._lock:
            files = core.program_files(
                self._project,
                self._cell.workpiece,
                self._cell.robot,
                module_name=rapid_identifier_or(name),
                project_name=self.current_project().name,
                compliance=self._compliance_doc(),
            )
            info = exports.save_export(self.store, self.data_dir, self._project_id, name, files)
        self._notify("exports")
        return info

    def exports(self) -> list[ExportInfo]:
        """The current project's saved exports, newest first."""
        with self._lock:
            return exports.list_exports(self.store, self.data_dir, self._project_id)

    def export_file(self, name: str, filename: str) -> str:
        """The text of one file of a saved export."""
        with self._lock:
            return exports.export_file(self.store, self._project_id, name, filename)

    # --- lifecycle ---------------------------------------------------------------------------

    def close(self) -> None:
        """Cancel jobs, stop the worker and close the store (a second call does nothing)."""
        with self._lock:
            if self._closed:
                return
            self._closed = True
        self.jobs.close()
        with self._lock:
            self.store.close()

    # --- internals ---------------------------------------------------------------------------

    def _require_idle(self) -> None:
        active = self.jobs.active(ROBOT_JOB_KINDS)
        if active:
            job = active[0]
            raise BusyError(
                f"the robot is busy with the {job.kind.replace('_', ' ')} job {job.id} "
                f"({job.progress:.0%}); wait for it or cancel it first"
            )

    def _notify_all(self) -> None:
        self._notify(
            "project",
            "cell",
            "robot",
            "compliance",
            "guide_points",
            "recording",
            "postprocess",
            "exports",
        )

    def _install_cell(
        self,
        settings: CellSettings,
        mesh: tuple[str, bytes] | None,
        joints: np.ndarray | None,
        *,
        parsed: Workpiece | None = None,
    ) -> None:
        """Build the cell and put the robot at ``joints`` (home when None or not usable)."""
        self._cell, self._lt, self._lt_state = _build_cell(settings, mesh, joints, parsed)
        self._epoch += 1
