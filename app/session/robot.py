"""The workbench's robot: the simulated cell, the robot's state in it, the compliance
selection, and the jobs that move it.

PROBLEM   Teaching (pushes, jogs, touch-offs), pointing, the example and learning jobs and the
          readers (state, force trace, the tool's view) all act on one robot from several
          threads, and a job owns the robot until it ends.
STRATEGY  One ``LiveRobot`` holds the cell, its lead-through, the state and the compliance
          selection behind the session's lock, with an ``epoch`` that a new cell bumps: a
          motion starts from a ``Pose`` and ``settle``s where it ended only while the epoch is
          the same. Robot jobs go through ``submit``: they step the cell through a tap
          (``live.LiveFeed``), so the state shows while they run, and the robot stays where
          they left it, whatever their end.
SOLUTION  Read: ``pose()``, ``idle_pose()``, ``snapshot(wait=)``, ``busy()``, ``force_trace``,
          ``document()``. Act: ``install``, ``show``, ``settle``, ``place``, ``save``, ``keep``,
          ``record``, ``select``, ``submit``, ``tapped``; ``build_live_cell`` makes what
          ``install`` takes. The lock is the session's and stays private: what must happen
          under it is one of these methods (or the ``Session``'s).
"""

from __future__ import annotations

import threading
from collections.abc import Callable, Iterable
from dataclasses import dataclass, replace
from typing import Any

import numpy as np

from robomach_core import project as core
from robomach_core.cell import (
    AXES,
    Cell,
    CellState,
    ComplianceFrame,
    ComplianceSelection,
    GuidePoint,
    LeadThrough,
    LeadThroughState,
    forget_supervisor,
)
from robomach_core.errors import ConflictError, RobomachError
from robomach_core.learning.run import Recording
from robomach_core.part import Workpiece
from robomach_core.project import CellSettings, Project

from .jobs import JobContext, JobRunner
from .live import LiveFeed
from .records import BusyError, ForceTrace, JobInfo, RobotSnapshot, log

ROBOT_JOB_KINDS = ("example", "path_learning", "accept_proposal", "calibration")

Built = tuple[Cell, LeadThrough, LeadThroughState]


@dataclass(frozen=True)
class Pose:
    """What a motion starts from, taken together under the lock."""

    cell: Cell
    leadthrough: LeadThrough
    state: LeadThroughState
    selection: ComplianceSelection
    epoch: int


@dataclass(frozen=True)
class View:
    """The open project and the live cell it runs on, read together under the lock
    (``Session.view``)."""

    project: Project
    cell: Cell
    epoch: int
    project_id: int


def build_live_cell(
    settings: CellSettings,
    mesh: tuple[str, bytes] | None,
    joints: Any = None,
    *,
    parsed: Workpiece | None = None,
) -> Built:
    """The cell of ``settings`` (``project.build_cell``) and its lead-through, the robot at
    ``joints`` (home when None or not usable); ``parsed`` is ``mesh`` already read
    (``workpiece.mesh_from_bytes``)."""
    cell = core.build_cell(settings, mesh, parsed=parsed)
    initial = None
    if joints is not None:
        try:
            initial = cell.initial_state(np.asarray(joints, dtype=float))
        except RobomachError:
            log.info("stored joints not usable (limits or contact): starting at home")
    lt = LeadThrough(cell)
    return cell, lt, lt.start(initial if initial is not None else cell.initial_state())


class LiveRobot:
    """The robot of one session (module docstring).

    Args:
        lock: The session's lock, which guards the robot and the project together.
        jobs: The session's job runner (robot jobs and who else waits on it).
        save: Saves a robot document, ``document()`` when None (called with the lock held).
        notify: Tells the session's listeners (called with the lock released).
    """

    def __init__(
        self,
        lock: threading.RLock,
        jobs: JobRunner,
        *,
        save: Callable[..., None],
        notify: Callable[..., None],
    ) -> None:
        self._lock = lock
        self.jobs = jobs
        self._save = save
        self.notify = notify  # the session's listeners (call with the lock released)
        self.live = LiveFeed(on_move=lambda: notify("robot"))
        self.epoch = 0  # bumped by every new cell: motions and jobs of the old one are dropped
        self.closed = False
        self._built: Built | None = None
        self._selection = ComplianceSelection()
        self._last_snapshot: RobotSnapshot | None = None  # snapshot(wait=False) while locked
        # More of what the store keeps with the robot (the session adds the pointing settings).
        self.extras: Callable[[], dict[str, Any]] = dict

    # --- reading -----------------------------------------------------------------------------

    @property
    def cell(self) -> Cell:
        """The simulated cell (read its robot, tool and workpiece; never step it)."""
        return self._parts()[0]

    @property
    def workpiece(self) -> Workpiece:
        """The part the tool meets (the real part when it deviates from its mesh)."""
        return self.cell.workpiece

    @property
    def selection(self) -> ComplianceSelection:
        return self._selection

    def pose(self) -> Pose:
        """The cell, the lead-through, the state, the selection and the epoch, together."""
        with self._lock:
            cell, lt, state = self._parts()
            return Pose(cell, lt, state, self._selection, self.epoch)

    def idle_pose(self) -> Pose:
        """``pose()`` for a motion or job about to start: ``BusyError`` while a job owns the
        robot (checked with the pose, under the lock)."""
        with self._lock:
            self.require_idle()
            return self.pose()

    def busy(self) -> bool:
        """True while a job owns the robot."""
        return bool(self.jobs.active(ROBOT_JOB_KINDS))

    def require_idle(self) -> None:
        """``BusyError`` while a job owns the robot."""
        active = self.jobs.active(ROBOT_JOB_KINDS)
        if active:
            job = active[0]
            raise BusyError(
                f"the robot is busy with the {job.kind.replace('_', ' ')} job {job.id} "
                f"({job.progress:.0%}); wait for it or cancel it first"
            )

    def snapshot(self, *, wait: bool = True) -> RobotSnapshot:
        """The robot now (live during a job). ``wait=False`` never waits for the lock: while
        a change holds it, the answer is the last snapshot taken (``GET /api/state`` answers
        on the server's event loop, which must never block)."""
        if not self._lock.acquire(blocking=wait):
            last = self._last_snapshot
            if last is not None:  # busy from the job runner: a job that just ended reads so
                return replace(last, busy=self.busy())
            self._lock.acquire()
        try:
            return self._take_snapshot()
        finally:
            self._lock.release()

    def _take_snapshot(self) -> RobotSnapshot:
        """The robot now, kept as the answer for readers that find the lock held (lock held)."""
        busy = self.busy()
        _, lt, state = self._parts()
        live = self.live.cell_state
        cs = live if (busy and live is not None) else state.cell
        snap = RobotSnapshot(
            float(cs.time_s),
            cs.q_motor.copy(),
            cs.T_base_tcp.copy(),
            lt.measured_wrench(cs),
            bool(cs.in_contact),
            busy,
        )
        self._last_snapshot = snap
        return snap

    def _put(self, built: Built) -> None:
        """The robot is now ``built`` (lock held). The kept snapshot follows at once, so a
        reader that finds the lock held never sees the robot from before this change. A
        robot replaced lets go of its supervisor (``forget_supervisor``): the two hold each
        other, and a server's frozen startup heap kept the first cell's for good."""
        old, self._built = self._built, built
        self._take_snapshot()
        if old is not None and old[0].robot is not built[0].robot:
            forget_supervisor(old[0].robot)

    def force_trace(self, recording: Recording | None, max_points: int = 2000) -> ForceTrace:
        """Force vs time, at most ``max_points`` (>= 2): live during a job, else ``recording``'s."""
        with self._lock:
            return self.live.force_trace(recording, self.busy(), max_points)

    def document(
        self, built: Built | None = None, selection: ComplianceSelection | None = None
    ) -> dict[str, Any]:
        """What the store keeps of the robot: its joints and the compliance selection (of
        ``built`` and ``selection`` when given: a cell or selection saved before it is taken
        on)."""
        with self._lock:
            built = self._built if built is None else built
            return {
                "joints_rad": None if built is None else built[2].cell.q_motor.tolist(),
                "compliance": selection_document(selection or self._selection),
                **self.extras(),
            }

    # --- acting ------------------------------------------------------------------------------

    def install(self, built: Built, selection: ComplianceSelection | None = None) -> None:
        """A new cell (and the robot in it): motions and jobs of the old one are dropped."""
        with self._lock:
            if selection is not None:
                self._selection = selection
            self.epoch += 1
            self._put(built)

    def show(self, state: CellState, epoch: int) -> None:
        """Where a running motion is (not saved), while the cell is still ``epoch``'s."""
        with self._lock:
            if epoch == self.epoch and self._built is not None:
                cell, lt, _ = self._built
                moving = LeadThroughState(state, state.T_base_tcp.copy(), np.zeros(6))
                self._put((cell, lt, moving))

    def settle(self, state: LeadThroughState, epoch: int) -> None:
        """A motion ended at ``state``: the robot stays there (saved, told).

        Raises:
            ConflictError: the cell changed while it moved (the motion is dropped).
        """
        with self._lock:
            if epoch != self.epoch or self._built is None:
                raise ConflictError(
                    "the cell or the project changed while the robot moved; the motion was stopped"
                )
            cell, lt, _ = self._built
            self._put((cell, lt, replace(state, velocity=np.zeros(6))))
            self._save()
        self.notify("robot")

    def place(
        self, state: LeadThroughState, epoch: int, what: str = "the job", *, save: bool = False
    ) -> None:
        """A job ended at ``state``: the robot stays there; ``save``: saved at once, else the
        caller saves it with the job's result (``Session.commit(with_robot=True)``, whose
        transition calls this under the same lock).

        Raises:
            ConflictError: the cell changed while ``what`` ran (its result is dropped).
        """
        with self._lock:
            if epoch != self.epoch or self._built is None:
                raise ConflictError(f"the cell changed while {what} ran")
            cell, lt, _ = self._built
            self._put((cell, lt, replace(state, velocity=np.zeros(6))))
            if save:
                self._save()

    def save(self, document: dict[str, Any] | None = None) -> None:
        """Save the robot's joints and compliance selection now (``document`` in their
        place: what is about to apply, saved first)."""
        with self._lock:
            self._save(document)

    def keep(self, extra: dict[str, Any], apply: Callable[[], None]) -> None:
        """Save the robot's document with ``extra`` over its parts (what the session keeps
        with the robot: the pointing settings, the calibration's touches), then ``apply`` the
        change, both under the lock: a save that fails (a locked database: 503) applies
        nothing, and no other save of the robot comes between them with the old parts."""
        with self._lock:
            self._save({**self.document(), **extra})
            apply()

    def record(self) -> GuidePoint:
        """The current pose as a guide point (not yet in the project)."""
        with self._lock:
            self.require_idle()
            _, lt, state = self._parts()
            return lt.record(state)

    def select(self, axes: Iterable[str], frame: ComplianceFrame) -> ComplianceSelection:
        """Make the axes (any of x y z rx ry rz) in the "tool" or "base" frame compliant."""
        selection = ComplianceSelection(frozenset(axes), frame)  # validates
        with self._lock:
            self._save(self.document(selection=selection))  # saved first: a 503 changes nothing
            self._selection = selection
        self.notify("compliance")
        return selection

    def tapped(
        self, ctx: JobContext, cell: Cell, *, path_m: np.ndarray | None = None, closed: bool = False
    ) -> Cell:
        """``cell`` seen through the live feed of the running job ``ctx`` (``LiveFeed.tapped``)."""
        return self.live.tapped(cell, self._parts()[1].estimator, ctx, path_m=path_m, closed=closed)

    def submit(
        self,
        kind: str,
        work: Callable[[JobContext], Any],
        done: Callable[[Any], None],
        epoch: int,
    ) -> str:
        """A job that owns the robot (``kind`` of ``ROBOT_JOB_KINDS``); cancelled or failed,
        the robot stays where it left it (nothing teleports)."""
        assert kind in ROBOT_JOB_KINDS, kind
        with self._lock:
            self.require_idle()
            self.live.start(self._parts()[2].cell)

        def end(info: JobInfo) -> None:
            with self._lock:
                live = self.live.stop()
                if info.status != "done" and live is not None and epoch == self.epoch:
                    cell, lt, _ = self._parts()
                    state = LeadThroughState(live, live.T_base_tcp.copy(), np.zeros(6))
                    self._put((cell, lt, state))
                    self._save()
            self.notify("robot")

        return self.jobs.submit(kind, work, on_done=done, on_end=end)

    def close(self) -> None:
        """Motions stop at their next period; the session is closing."""
        self.closed = True

    def _parts(self) -> Built:
        if self._built is None:
            raise ConflictError("no cell is open yet")
        return self._built


def selection_document(selection: ComplianceSelection) -> dict[str, Any]:
    """The compliance selection as stored and exported (axes in ``AXES`` order)."""
    return {"axes": [a for a in AXES if a in selection.axes], "frame": selection.frame}


def selection_from_document(doc: dict[str, Any] | None) -> ComplianceSelection:
    """The stored selection (the default when missing or unreadable)."""
    doc = doc or {}
    try:
        return ComplianceSelection(
            frozenset(doc.get("axes", ("x", "y", "z"))), doc.get("frame", "base")
        )
    except RobomachError:
        return ComplianceSelection()
