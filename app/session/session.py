"""The workbench session: the one mutable state of a running ``robomach serve``.

PROBLEM   The viser GUI and the REST API act on the same simulated cell, from different
          threads, while long jobs (the example lead-through, path learning) run in the
          background; every change must be saved at once.
STRATEGY  One ``Session`` per process owns the cell, the lead-through state, the compliance
          selection, the guide points, the last recording and the post-processing result,
          behind one ``threading.RLock``. Public methods take and return SI units and plain
          dataclasses; they validate and raise ``RobomachError`` subclasses (the API maps them
          to 4xx). Long work runs on the ``JobRunner``'s worker thread, outside the lock, on
          the cell seen through a tap that publishes the live robot pose and checks for cancel.
          Listeners registered with ``subscribe`` hear a topic name after each change.
SOLUTION  Public API (all thread-safe):

  Reading
    snapshot() -> RobotSnapshot             joints, TCP pose, measured wrench, contact, busy
    cell_settings() -> CellSettings         robot, tool radius, workpiece, seed
    cell / workpiece                        the Cell and its Workpiece (read only: never step)
    compliance -> ComplianceSelection
    guide_points() -> list[GuidePoint]
    recording() -> Recording | None         the last path-learning recording
    force_trace(max_points) -> ForceTrace   decimated force vs time: live while learning
    postprocess_settings() -> PostprocessSettings
    postprocess_outcome() -> PostprocessOutcome | None
    learning_settings() -> PathLearningSettings | None   of the last recording
    job(job_id) / jobs() -> JobInfo         status and progress of background jobs
    current_project() / projects() -> ProjectInfo
  Acting (each saves before returning)
    set_cell(robot=, tool_radius_m=, workpiece=) -> CellSettings   resets robot and downstream
    upload_workpiece(data, filename) -> CellSettings
    set_compliance(axes, frame) -> ComplianceSelection
    push(wrench6, duration_s) -> RobotSnapshot        wrench [N, N*m] at the TCP, base axes
    jog(axis, step) -> RobotSnapshot                   step [m] or [rad], tool frame
    go_home() -> RobotSnapshot
    record_guide_point() -> GuidePointEntry
    delete_guide_point(index) / clear_guide_points()
    start_example() -> job_id               scripted lead-through (replaces guide points)
    start_path_learning(force_N, speed_m_s, closed=True) -> job_id
    cancel_job(job_id) -> JobInfo
    run_postprocess(force_min_N=, force_max_N=, tolerance_m=) -> PostprocessOutcome
    rapid_module(module_name=, force_control=) / samples_csv() / targets_csv() /
    settings_json() -> str
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
import math
import os
import re
import shutil
import tempfile
import threading
import time
from collections.abc import Callable, Iterable
from dataclasses import asdict, replace
from pathlib import Path
from typing import Any

import numpy as np

from robomach_core.cell import CONTROL_PERIOD_S, Cell, CellConfig, CellState
from robomach_core.errors import (
    InvalidInputError,
    NotEnoughGuidePointsError,
    RobomachError,
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
from robomach_core.robot import ROBOT_URDFS
from robomach_core.sensor import ForceEstimator
from robomach_core.tool import Tool
from robomach_core.workpiece import (
    MAX_MESH_BYTES,
    MAX_MESH_TRIANGLES,
    MESH_SUFFIXES,
    WORKPIECE_NAMES,
    Workpiece,
    mesh_from_bytes,
)

from ..store import GuidePointRow, ProjectData, Store
from .jobs import (
    JobContext,
    JobRunner,
)
from .records import (
    DEFAULT_PROJECT_NAME,
    EXPORT_NAME_RE,
    LIVE_NOTIFY_S,
    LIVE_TRACE_EVERY,
    LIVE_TRACE_MAX,
    MAX_GUIDE_POINTS,
    PROJECT_NAME_MAX,
    RECORDING_ARRAYS,
    BusyError,
    CellSettings,
    ConflictError,
    ExportInfo,
    ForceTrace,
    GuidePointEntry,
    JobInfo,
    NotFoundError,
    PostprocessOutcome,
    ProjectInfo,
    RobotSnapshot,
    Topic,
    log,
)


class _TappedCell:
    """A ``Cell`` whose ``step`` also calls ``tap(state)``; every other attribute is the cell's.

    Jobs drive core functions (``learn_path``, ``scripted_leadthrough``) that own their loop;
    stepping through this proxy lets the session show the robot moving, plot the live force
    and stop the loop on cancel (``tap`` raises ``CancelledError``) without changing the core.
    """

    def __init__(self, cell: Cell, tap: Callable[[CellState], None]) -> None:
        self._cell = cell
        self._tap = tap

    def step(
        self, state: CellState, q_motor_cmd: np.ndarray, dt: float = CONTROL_PERIOD_S
    ) -> CellState:
        new = self._cell.step(state, q_motor_cmd, dt)
        self._tap(new)
        return new

    def __getattr__(self, name: str) -> Any:
        return getattr(self._cell, name)


# --- the session ---------------------------------------------------------------------------

ROBOT_JOB_KINDS = ("example", "path_learning")


class Session:
    """The workbench state shared by the GUI and the API (see the module docstring).

    Args:
        store: The project database; a throwaway in-memory one when None.
        data_dir: Folder that saved exports are written under (``<data_dir>/exports``); exports
            are kept only in the store when None.
        max_upload_bytes: Largest mesh file ``upload_workpiece`` takes.
        max_triangles: Most triangles of an uploaded mesh.
    """

    def __init__(
        self,
        store: Store | None = None,
        *,
        data_dir: str | Path | None = None,
        max_upload_bytes: int = MAX_MESH_BYTES,
        max_triangles: int = MAX_MESH_TRIANGLES,
    ) -> None:
        self.max_upload_bytes = min(max_upload_bytes, MAX_MESH_BYTES)
        self.max_triangles = min(max_triangles, MAX_MESH_TRIANGLES)
        self._lock = threading.RLock()
        self._listeners: list[Callable[[Topic], None]] = []
        self._listeners_lock = threading.Lock()
        self.store = store or Store(":memory:")
        self.data_dir = Path(data_dir).resolve() if data_dir is not None else None
        self.jobs = JobRunner(on_change=lambda info: self._notify("job"))
        self._epoch = 0  # bumped when the cell or project changes; stale job results are dropped
        self._live_cell: CellState | None = None
        self._live_trace: list[tuple[float, float]] = []
        self._live_t0 = 0.0
        self._last_live_notify = 0.0
        self._project_id = 0
        self._closed = False
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

    @property
    def cell(self) -> Cell:
        """The simulated cell (read its robot, tool and workpiece; never step it)."""
        return self._cell

    @property
    def workpiece(self) -> Workpiece:
        return self._cell.workpiece

    @property
    def compliance(self) -> ComplianceSelection:
        return self._selection

    def busy(self) -> bool:
        """True while a job owns the robot."""
        return bool(self.jobs.active(ROBOT_JOB_KINDS))

    def snapshot(self) -> RobotSnapshot:
        """The robot now (live during a job)."""
        with self._lock:
            busy = self.busy()
            cs = self._live_cell if (busy and self._live_cell is not None) else self._lt_state.cell
            wrench = self._lt.measured_wrench(cs)
        return RobotSnapshot(
            float(cs.time_s),
            cs.q_motor.copy(),
            cs.T_base_tcp.copy(),
            wrench,
            bool(cs.in_contact),
            busy,
        )

    def cell_settings(self) -> CellSettings:
        return self._cell_settings

    def guide_points(self) -> list[GuidePoint]:
        with self._lock:
            return list(self._guides)

    def recording(self) -> Recording | None:
        return self._recording

    def learning_settings(self) -> PathLearningSettings | None:
        """The settings of the last recording."""
        return self._learning

    def postprocess_settings(self) -> PostprocessSettings:
        return self._post_settings

    def postprocess_outcome(self) -> PostprocessOutcome | None:
        return self._post

    def job(self, job_id: str) -> JobInfo:
        return self.jobs.get(job_id)

    def force_trace(self, max_points: int = 2000) -> ForceTrace:
        """Force vs time, at most ``max_points`` (>= 2) by stride: live during a job."""
        if max_points < 2:
            raise InvalidInputError("max_points must be at least 2")
        with self._lock:
            live = list(self._live_trace)
            if self.busy() and live:
                data = np.array(live)
                t, f = data[:, 0], data[:, 1]
                ref = np.full(len(t), np.nan)
                source = "live"
            elif self._recording is not None:
                rec = self._recording
                t, f, ref = rec.time_s, rec.force_normal_N, rec.force_reference_N
                source = "recording"
            else:
                empty = np.zeros(0)
                return ForceTrace("none", empty, empty, empty, 0)
        n = len(t)
        stride = max(1, math.ceil(n / max_points))
        idx = np.arange(0, n, stride)
        if n and idx[-1] != n - 1:
            idx = np.append(idx, n - 1)
        return ForceTrace(source, t[idx], f[idx], ref[idx], n)

    # --- cell --------------------------------------------------------------------------------

    def set_cell(
        self,
        *,
        robot: str | None = None,
        tool_radius_m: float | None = None,
        workpiece: str | None = None,
    ) -> CellSettings:
        """Change the cell; None keeps a setting. The robot goes home and the guide points,
        recording and post-processing result are cleared (they belong to the old cell)."""
        with self._lock:
            self._require_idle()
            cur = self._cell_settings
            new = replace(
                cur,
                robot=cur.robot if robot is None else robot.lower(),
                tool_radius_m=cur.tool_radius_m if tool_radius_m is None else float(tool_radius_m),
            )
            mesh = self._mesh
            if workpiece in WORKPIECE_NAMES:
                new, mesh = (
                    replace(new, workpiece=workpiece, workpiece_builtin=True),
                    None,
                )
            elif workpiece is not None and not (mesh is not None and workpiece == cur.workpiece):
                uploaded = f", or {cur.workpiece!r} (uploaded)" if mesh is not None else ""
                raise InvalidInputError(
                    f"unknown workpiece {workpiece!r}; use one of {', '.join(WORKPIECE_NAMES)}"
                    f"{uploaded}, or upload a mesh file"
                )
            self._install_cell(new, mesh, joints=None)
            self._clear_downstream()
            self._save_cell()
        self._notify("cell", "robot", "guide_points", "recording", "postprocess")
        return new

    def upload_workpiece(self, data: bytes, filename: str) -> CellSettings:
        """Use a mesh file (STL/OBJ/PLY, mm) as the workpiece, within ``max_upload_bytes`` and
        ``max_triangles``. Clears downstream data like ``set_cell``."""
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
            new = replace(self._cell_settings, workpiece=stem, workpiece_builtin=False)
            self._install_cell(new, (stem + suffix, data), joints=None, parsed=parsed)
            self._clear_downstream()
            self._save_cell()
        self._notify("cell", "robot", "guide_points", "recording", "postprocess")
        return new

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
        ``duration_s`` (0-60 s) under admittance control on the compliant axes."""
        w = np.asarray(wrench, dtype=float)
        if w.shape != (6,) or not np.all(np.isfinite(w)):
            raise InvalidInputError("a push is 6 finite values: force [N] and torque [N*m]")
        if not (math.isfinite(duration_s) and 0 <= duration_s <= 60):
            raise InvalidInputError(f"push duration {duration_s:g} s is outside 0-60 s")
        with self._lock:
            self._require_idle()
            self._lt_state = self._lt.push(self._lt_state, w, self._selection, duration_s)
            self._save_robot()
        self._notify("robot")
        return self.snapshot()

    def jog(self, axis: str, step: float) -> RobotSnapshot:
        """Force-control jogging: move ``step`` [m] along, or [rad] about, a tool axis; the
        compliant axes keep answering to the contact force."""
        if axis not in AXES:
            raise InvalidInputError(f"jog axis must be one of {', '.join(AXES)}, not {axis!r}")
        with self._lock:
            self._require_idle()
            self._lt_state = self._lt.jog(self._lt_state, axis, float(step), self._selection)
            self._save_robot()
        self._notify("robot")
        return self.snapshot()

    def go_home(self) -> RobotSnapshot:
        """Put the robot back at its home pose (a reset of the simulation, not a move)."""
        with self._lock:
            self._require_idle()
            self._install_cell(self._cell_settings, self._mesh, joints=None)
            self._save_robot()
        self._notify("robot")
        return self.snapshot()

    # --- guide points ------------------------------------------------------------------------

    def record_guide_point(self) -> GuidePointEntry:
        """Record the current pose as the next guide point."""
        with self._lock:
            self._require_idle()
            if len(self._guides) >= MAX_GUIDE_POINTS:
                raise ConflictError(f"a project holds at most {MAX_GUIDE_POINTS} guide points")
            point = self._lt.record(self._lt_state)
            self._guides.append(point)
            entry = GuidePointEntry(len(self._guides) - 1, point)
            self._save_guides()
        self._notify("guide_points")
        return entry

    def delete_guide_point(self, index: int) -> None:
        """Delete the guide point at ``index``; later points move down by one."""
        with self._lock:
            if not (0 <= index < len(self._guides)):
                raise NotFoundError(
                    f"no guide point {index}; there are {len(self._guides)} (indexes from 0)"
                )
            del self._guides[index]
            self._save_guides()
        self._notify("guide_points")

    def clear_guide_points(self) -> None:
        with self._lock:
            self._guides.clear()
            self._save_guides()
        self._notify("guide_points")

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
                    f"{self._cell.workpiece.name!r}; lead the robot by pushes instead"
                )
            epoch, cell, estimator = self._epoch, self._cell, self._lt.estimator
            start, seed = self._lt_state, self._cell_settings.seed

            def work(ctx: JobContext) -> tuple[LeadThroughState, list[GuidePoint]]:
                lt = LeadThrough(self._tapped(cell, estimator, ctx), estimator=estimator)
                return scripted_leadthrough(
                    lt,
                    start,
                    cell.workpiece,
                    np.random.default_rng(seed),
                    progress=ctx.progress,
                )

            def done(result: tuple[LeadThroughState, list[GuidePoint]]) -> None:
                state, guides = result
                with self._lock:
                    if epoch != self._epoch:
                        raise ConflictError("the cell changed while the example ran")
                    self._lt_state = replace(state, velocity=np.zeros(6))
                    self._guides = list(guides)
                    self._save_guides(with_robot=True)
                self._notify("robot", "guide_points")

            return self._submit_robot_job("example", work, done, epoch)

    def start_path_learning(self, force_N: float, speed_m_s: float, *, closed: bool = True) -> str:
        """Job: learn the path through the guide points at ``force_N`` and ``speed_m_s``;
        on success the recording replaces the last one. Returns the job id."""
        from robomach_core.path_learning import learn_path

        settings = PathLearningSettings(
            force_N=float(force_N), speed_m_s=float(speed_m_s), closed=bool(closed)
        )
        with self._lock:
            self._require_idle()
            if len(self._guides) < 2:
                raise NotEnoughGuidePointsError(
                    f"path learning needs at least 2 guide points, got {len(self._guides)}"
                )
            epoch, cell, estimator = self._epoch, self._cell, self._lt.estimator
            start, guides = self._lt_state.cell, list(self._guides)

            def work(ctx: JobContext) -> tuple[Recording, CellState]:
                return learn_path(
                    self._tapped(cell, estimator, ctx),
                    start,
                    guides,
                    settings,
                    estimator,
                    progress=ctx.progress,
                    cancelled=ctx.cancelled,
                )

            def done(result: tuple[Recording, CellState]) -> None:
                recording, end = result
                with self._lock:
                    if epoch != self._epoch:
                        raise ConflictError("the cell changed while path learning ran")
                    self._lt_state = LeadThroughState(end, end.T_base_tcp.copy(), np.zeros(6))
                    self._recording = recording
                    self._recording_guides_q = np.array([g.quaternion_wxyz for g in guides])
                    self._learning = settings
                    self._post = None
                    self._save_recording()
                self._notify("robot", "recording", "postprocess")

            return self._submit_robot_job("path_learning", work, done, epoch)

    def cancel_job(self, job_id: str) -> JobInfo:
        """Cancel a job (a running one stops within a few milliseconds of compute)."""
        return self.jobs.cancel(job_id)

    def _tapped(self, cell: Cell, estimator: ForceEstimator, ctx: JobContext) -> _TappedCell:
        count = 0

        def tap(state: CellState) -> None:
            nonlocal count
            count += 1
            if count % LIVE_TRACE_EVERY:
                return
            ctx.check_cancelled()
            self._live_cell = state
            if len(self._live_trace) < LIVE_TRACE_MAX:
                force = estimator.contact_wrench_tcp_base(
                    state.ft_reading, cell.flange_rotation(state.T_base_tcp)
                )[:3]
                self._live_trace.append(
                    (state.time_s - self._live_t0, float(np.sqrt(force @ force)))
                )
            now = time.monotonic()
            if now - self._last_live_notify >= LIVE_NOTIFY_S:
                self._last_live_notify = now
                self._notify("robot")

        return _TappedCell(cell, tap)

    def _submit_robot_job(
        self,
        kind: str,
        work: Callable[[JobContext], Any],
        done: Callable[[Any], None],
        epoch: int,
    ) -> str:
        self._live_cell = self._lt_state.cell
        self._live_t0 = float(self._lt_state.cell.time_s)
        self._live_trace = []

        def end(info: JobInfo) -> None:
            # Cancelled or failed: the robot stays where the job left it (nothing teleports).
            with self._lock:
                live = self._live_cell
                self._live_cell = None
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
    ) -> PostprocessOutcome:
        """Filter and reduce the last recording; None keeps a setting. Saves the settings."""
        with self._lock:
            cur = self._post_settings
            settings = replace(
                cur,
                force_min_N=cur.force_min_N if force_min_N is None else float(force_min_N),
                force_max_N=cur.force_max_N if force_max_N is None else float(force_max_N),
                tolerance_m=cur.tolerance_m if tolerance_m is None else float(tolerance_m),
            )
            if self._recording is None:
                raise ConflictError("nothing to post-process yet: run path learning first")
            outcome = self._postprocess(settings)
            self._post_settings, self._post = settings, outcome
            self._save_post()
        self._notify("postprocess")
        return outcome

    def _postprocess(self, settings: PostprocessSettings) -> PostprocessOutcome:
        from robomach_core.postprocess import postprocess
        from robomach_core.scoring import score_path

        rec = self._recording
        result = postprocess(
            rec,
            self._recording_guides_q,
            settings,
            closed=self._learning.closed if self._learning else True,
        )
        score = None
        if self._cell.workpiece.wall is not None and len(result.targets) >= 2:
            score = score_path(
                self._cell.workpiece,
                self._cell.tool.radius_m,
                result.targets.position_m,
            )
        return PostprocessOutcome(settings, result, len(rec), score)

    def rapid_module(self, *, module_name: str = "LearnedPath", force_control: bool = False) -> str:
        """The RAPID module of the post-processed targets (optionally the FC pressure variant)."""
        from robomach_core.export.program import rapid_program
        from robomach_core.export.rapid import rapid_module

        with self._lock:
            post = self._require_post()
            s = self._cell_settings
            learn = self._learning
            header = (
                f"robomach workbench: {s.robot}, {self._cell.workpiece.name}, tool radius "
                f"{s.tool_radius_m * 1e3:g} mm",
                f"{len(post.result.targets)} targets from {post.samples_raw} samples "
                f"({post.result.samples_filtered} kept by the force filter), tolerance "
                f"{post.settings.tolerance_m * 1e3:g} mm",
            )
            program = rapid_program(
                post.result.targets,
                self._cell.tool,
                self._cell.workpiece,
                module_name=module_name,
                force_control_N=(learn.force_N if (force_control and learn) else None),
                comment=header,
            )
        return rapid_module(program)

    def samples_csv(self) -> str:
        """Every recorded sample with the force filter's verdict (mm, N, degrees)."""
        from robomach_core.export.tables import samples_csv

        with self._lock:
            if self._recording is None:
                raise ConflictError("no recording yet: run path learning first")
            keep = self._post.result.keep_mask if self._post is not None else None
            return samples_csv(self._recording, keep)

    def targets_csv(self) -> str:
        """The post-processed targets (mm, degrees, mm/s)."""
        from robomach_core.export.tables import targets_csv

        with self._lock:
            return targets_csv(self._require_post().result.targets)

    def settings_json(self) -> str:
        """Cell, compliance, learning and post-processing settings (mm, N, s, degrees)."""
        with self._lock:
            s, p, learn = self._cell_settings, self._post_settings, self._learning
            doc = {
                "project": self.current_project().name,
                "cell": {
                    "robot": s.robot,
                    "tool_radius_mm": s.tool_radius_m * 1e3,
                    "workpiece": s.workpiece,
                    "workpiece_builtin": s.workpiece_builtin,
                    "seed": s.seed,
                },
                "compliance": {
                    "axes": [a for a in AXES if a in self._selection.axes],
                    "frame": self._selection.frame,
                },
                "guide_points": len(self._guides),
                "path_learning": None
                if learn is None
                else {
                    "force_N": learn.force_N,
                    "speed_mm_s": learn.speed_m_s * 1e3,
                    "closed": learn.closed,
                    "force_limit_N": learn.force_limit_N,
                },
                "postprocess": {
                    "force_min_N": p.force_min_N,
                    "force_max_N": p.force_max_N,
                    "tolerance_mm": p.tolerance_m * 1e3,
                    "speed_mean_mm_s": p.speed_mean_m_s * 1e3,
                    "speed_min_mm_s": p.speed_min_m_s * 1e3,
                    "contact_stiffness_N_mm": p.contact_stiffness_N_m * 1e-3,
                },
            }
            post = self._post
            if post is not None:
                doc["result"] = {
                    "samples_raw": post.samples_raw,
                    "samples_filtered": post.result.samples_filtered,
                    "targets": len(post.result.targets),
                    "max_deviation_mm": None if post.score is None else post.score.max_m * 1e3,
                    "rms_deviation_mm": None if post.score is None else post.score.rms_m * 1e3,
                }
        return json.dumps(doc, indent=2) + "\n"

    def save_export(self, name: str) -> ExportInfo:
        """Save program.mod, program_fc.mod, samples.csv, targets.csv and settings.json under
        ``name`` (letters, digits, ``_ . -``; 1-64 characters) in the store and in
        ``<data_dir>/exports/<project id>/<name>/``; the same name replaces the files."""
        if not isinstance(name, str) or not EXPORT_NAME_RE.match(name) or ".." in name:
            raise InvalidInputError(
                "an export name is 1-64 letters, digits, '_', '.' or '-', starting with a letter "
                f"or digit and without '..'; got {name!r}"
            )
        with self._lock:
            module = rapid_identifier_or(name)
            files = {
                "program.mod": self.rapid_module(module_name=module),
                "samples.csv": self.samples_csv(),
                "targets.csv": self.targets_csv(),
                "settings.json": self.settings_json(),
            }
            if self._learning is not None:
                files["program_fc.mod"] = self.rapid_module(
                    module_name=module[:29] + "_FC", force_control=True
                )
            pid = self._project_id
            created = self.store.save_export(pid, name, files)
            folder = None
            if self.data_dir is not None:
                folder = self._export_folder(pid, name)
                for filename, text in files.items():
                    _write_atomic(folder / filename, text)
        self._notify("exports")
        return ExportInfo(name, created, sorted(files), folder)

    def exports(self) -> list[ExportInfo]:
        """The current project's saved exports, newest first."""
        with self._lock:
            pid = self._project_id
            return [
                ExportInfo(n, t, files, self._export_folder(pid, n, create=False))
                for n, t, files in self.store.list_exports(pid)
            ]

    def export_file(self, name: str, filename: str) -> str:
        """The text of one file of a saved export."""
        with self._lock:
            files = self.store.get_export(self._project_id, name)
        if files is None:
            raise NotFoundError(f"no export named {name!r} in this project")
        if filename not in files:
            raise NotFoundError(f"export {name!r} has no file {filename!r}; it has {sorted(files)}")
        return files[filename]

    def _export_folder(self, project_id: int, name: str, *, create: bool = True) -> Path | None:
        if self.data_dir is None:
            return None
        root = (self.data_dir / "exports").resolve()
        folder = (root / str(project_id) / name).resolve()
        if not folder.is_relative_to(root) or folder == root:  # belt and braces after the regex
            raise InvalidInputError(f"export name {name!r} would leave the data folder")
        if create:
            folder.mkdir(parents=True, exist_ok=True)
        return folder

    # --- projects ----------------------------------------------------------------------------

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
        name = _project_name(name)
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
            self._load(project_id)
            self.store.set_last_project(project_id)
        self._notify_all()
        return self.current_project()

    def rename_project(self, project_id: int, name: str) -> ProjectInfo:
        name = _project_name(name)
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

    def _require_post(self) -> PostprocessOutcome:
        if self._recording is None:
            raise ConflictError("no recording yet: run path learning, then post-processing")
        if self._post is None:
            raise ConflictError("the recording is not post-processed yet: run post-processing")
        return self._post

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
        if settings.robot not in ROBOT_URDFS:
            raise InvalidInputError(
                f"unknown robot {settings.robot!r}; choose one of {', '.join(sorted(ROBOT_URDFS))}"
            )
        tool = Tool(radius_m=settings.tool_radius_m)
        if parsed is not None:
            workpiece: str | Workpiece = parsed
        elif mesh is not None:
            filename, data = mesh
            workpiece = mesh_from_bytes(
                data,
                Path(filename).suffix,
                name=Path(filename).stem,
                max_triangles=MAX_MESH_TRIANGLES,
            )
        else:
            workpiece = settings.workpiece
        cell = Cell(
            CellConfig(robot=settings.robot, tool=tool, workpiece=workpiece, seed=settings.seed)
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
        self._cell, self._lt, self._mesh = cell, lt, mesh
        self._cell_settings = settings
        self._lt_state = lt.start(initial)
        self._epoch += 1

    def _clear_downstream(self) -> None:
        self._guides = []
        self._recording = None
        self._recording_guides_q = np.zeros((0, 4))
        self._learning = None
        self._post = None

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
        name = DEFAULT_PROJECT_NAME
        k = 1
        while self.store.find_project(name) is not None:
            k += 1
            name = f"{DEFAULT_PROJECT_NAME} {k}"
        row = self.store.create_project(name, asdict(CellSettings()), self._robot_doc_default())
        self._load(row.id)

    def _load(self, project_id: int) -> None:
        data: ProjectData = self.store.load_project(project_id)
        known = set(CellSettings.__dataclass_fields__)
        settings = CellSettings(**{k: v for k, v in data.cell.items() if k in known})
        joints = data.robot.get("joints_rad")
        self._install_cell(settings, data.mesh, joints)
        comp = data.robot.get("compliance") or {}
        try:
            self._selection = ComplianceSelection(
                frozenset(comp.get("axes", ("x", "y", "z"))), comp.get("frame", "base")
            )
        except RobomachError:
            self._selection = ComplianceSelection()
        self._project_id = project_id
        self._guides = [
            GuidePoint(g.T_base_tcp, g.joints_rad, g.time_s, g.force_N) for g in data.guide_points
        ]
        self._recording, self._learning, self._post = None, None, None
        self._recording_guides_q = np.zeros((0, 4))
        info = data.recording_info
        if info is not None:
            arrays = data.recording_arrays
            try:
                self._recording = Recording(
                    **{k: arrays[k] for k in RECORDING_ARRAYS},
                    stop_reason=str(info["stop_reason"]),
                    completed=bool(info["completed"]),
                )
                self._recording_guides_q = arrays["guide_quaternions_wxyz"]
                self._learning = PathLearningSettings(**info["learning"])
            except (
                KeyError,
                TypeError,
                ValueError,
            ) as exc:  # written by another version
                log.error(
                    "project %s: cannot read its recording (%s); dropped",
                    project_id,
                    exc,
                )
                self._recording, self._learning = None, None
        post = data.post or {}
        try:
            self._post_settings = PostprocessSettings(**post.get("settings", {}))
        except (TypeError, ValueError) as exc:
            log.error("project %s: post-processing settings unreadable (%s)", project_id, exc)
            self._post_settings = PostprocessSettings()
        if post.get("applied") and self._recording is not None:
            try:
                self._post = self._postprocess(self._post_settings)
            except RobomachError as exc:
                log.warning("stored post-processing no longer applies: %s", exc)

    # Each save is one store transaction.

    def _robot_doc(self) -> dict[str, Any]:
        return {
            "joints_rad": self._lt_state.cell.q_motor.tolist(),
            "compliance": {
                "axes": sorted(self._selection.axes),
                "frame": self._selection.frame,
            },
        }

    def _post_doc(self) -> dict[str, Any]:
        return {
            "settings": asdict(self._post_settings),
            "applied": self._post is not None,
        }

    def _guide_rows(self) -> list[GuidePointRow]:
        return [
            GuidePointRow(g.T_base_tcp, g.joints_rad, g.time_s, g.force_N) for g in self._guides
        ]

    def _recording_doc(self) -> tuple[dict[str, Any], dict[str, np.ndarray]] | None:
        if self._recording is None:
            return None
        info = {
            "stop_reason": self._recording.stop_reason,
            "completed": self._recording.completed,
            "learning": asdict(self._learning),
        }
        arrays = {k: getattr(self._recording, k) for k in RECORDING_ARRAYS}
        arrays["guide_quaternions_wxyz"] = self._recording_guides_q
        return info, arrays

    def _save_robot(self) -> None:
        self.store.save(self._project_id, robot=self._robot_doc())

    def _save_cell(self) -> None:
        """The cell and everything it reset."""
        self.store.save(
            self._project_id,
            cell=asdict(self._cell_settings),
            mesh=self._mesh,
            robot=self._robot_doc(),
            post=self._post_doc(),
            guide_points=self._guide_rows(),
            recording=self._recording_doc(),
        )

    def _save_guides(self, *, with_robot: bool = False) -> None:
        if with_robot:
            self.store.save(
                self._project_id,
                guide_points=self._guide_rows(),
                robot=self._robot_doc(),
            )
        else:
            self.store.save(self._project_id, guide_points=self._guide_rows())

    def _save_post(self) -> None:
        self.store.save(self._project_id, post=self._post_doc())

    def _save_recording(self) -> None:
        self.store.save(
            self._project_id,
            recording=self._recording_doc(),
            post=self._post_doc(),
            robot=self._robot_doc(),
        )


def _project_name(name: str) -> str:
    if not isinstance(name, str) or not name.strip():
        raise InvalidInputError("a project name must not be empty")
    name = name.strip()
    if len(name) > PROJECT_NAME_MAX:
        raise InvalidInputError(f"a project name is at most {PROJECT_NAME_MAX} characters")
    if any(ord(ch) < 32 for ch in name):
        raise InvalidInputError("a project name must not contain control characters")
    return name


def rapid_identifier_or(name: str) -> str:
    """A RAPID module name from an export name (``LearnedPath`` when it has no letter)."""
    from robomach_core.export.rapid import rapid_identifier

    try:
        return rapid_identifier(name, prefix="m")
    except InvalidInputError:
        return "LearnedPath"


def _write_atomic(path: Path, text: str) -> None:
    """Write a file so that a crash leaves either the old or the new content."""
    fd, tmp = tempfile.mkstemp(dir=path.parent, prefix=f".{path.name}.", suffix=".tmp")
    try:
        with os.fdopen(fd, "w", encoding="utf-8") as f:
            f.write(text)
            f.flush()
            os.fsync(f.fileno())
        os.replace(tmp, path)
    except BaseException:
        Path(tmp).unlink(missing_ok=True)
        raise
