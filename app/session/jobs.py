"""The session's background jobs: one worker (a ``concurrent.futures`` executor), progress,
cancel, ``wait``, a bounded history."""

from __future__ import annotations

import builtins
import threading
import time
import uuid
import weakref
from collections.abc import Callable, Iterable
from concurrent.futures import Future, ThreadPoolExecutor
from concurrent.futures import TimeoutError as FutureTimeout
from dataclasses import dataclass, field
from typing import Any

from robomach_core.errors import (
    CancelledError,
    RobomachError,
)

from .records import (
    ConflictError,
    JobInfo,
    JobStatus,
    NotFoundError,
    QueueFullError,
    log,
)

# Queued and running jobs at once: of one kind, and of all kinds. Each waits on the one worker,
# and the robot and the user wait behind them: 300 machining comparisons (3.3 h of work) were
# accepted at once (issue 19, R9). Robot jobs are one at a time anyway (BusyError).
MAX_ACTIVE_JOBS_PER_KIND = 3
MAX_ACTIVE_JOBS = 8
ENDED: tuple[JobStatus, ...] = ("done", "failed", "cancelled")


class JobContext:
    """What a job's work function sees: report progress, check for cancel."""

    def __init__(self, job: _Job) -> None:
        self._job = job

    @property
    def job_id(self) -> str:
        return self._job.id

    def progress(self, fraction: float) -> None:
        """Report progress in [0, 1] (clipped)."""
        self._job.progress = min(1.0, max(0.0, float(fraction)))
        self._job.runner._changed(self._job)

    def cancelled(self) -> bool:
        return self._job.cancel.is_set()

    def check_cancelled(self) -> None:
        """Raise ``CancelledError`` when the user asked to cancel."""
        if self._job.cancel.is_set():
            raise CancelledError(f"{self._job.kind.replace('_', ' ')} was cancelled")


@dataclass(eq=False)
class _Job:
    runner: JobRunner
    id: str
    kind: str
    work: Callable[[JobContext], Any]
    on_done: Callable[[Any], None] | None
    on_end: Callable[[JobInfo], None] | None
    status: JobStatus = "queued"
    progress: float = 0.0
    error: str | None = None
    created_s: float = field(default_factory=time.time)
    started_s: float | None = None
    finished_s: float | None = None
    cancel: threading.Event = field(default_factory=threading.Event)
    # Resolved with the final JobInfo once the job has ended and its on_end has run.
    ended: Future = field(default_factory=Future)

    def info(self) -> JobInfo:
        return JobInfo(
            self.id,
            self.kind,
            self.status,
            self.progress,
            self.error,
            self.created_s,
            self.started_s,
            self.finished_s,
        )


class JobRunner:
    """Jobs run one at a time, in order, on a one-worker ``ThreadPoolExecutor``; progress,
    cancel, ``wait``, bounded history.

    ``submit(kind, work)`` queues ``work(ctx)``; its return value is handed to ``on_done``
    (still in the worker) before the job reads as done. A finished job keeps only its public
    state: its work, callbacks and result are let go (a comparison's result is about 10-90 MB,
    and the history remembers ``keep_finished`` jobs; issue 32). A
    ``CancelledError`` makes it cancelled, a ``RobomachError`` failed with its message, any
    other exception failed with ``describe_unexpected`` (logged with its traceback). ``on_end`` runs
    after every outcome; ``wait(job_id)`` returns once it has. The CMRR and stiffness studies
    plug in here the same way.

    Args:
        on_change: Called with the ``JobInfo`` after every status or progress change.
        keep_finished: Finished jobs remembered for ``get``.
        max_active_per_kind: Queued and running jobs of one kind; one more is refused with
            ``QueueFullError`` (429).
        max_active: Queued and running jobs of all kinds.
    """

    def __init__(
        self,
        *,
        on_change: Callable[[JobInfo], None] | None = None,
        keep_finished: int = 200,
        max_active_per_kind: int = MAX_ACTIVE_JOBS_PER_KIND,
        max_active: int = MAX_ACTIVE_JOBS,
    ) -> None:
        self._on_change = on_change
        self._keep = keep_finished
        self._max_per_kind = max_active_per_kind
        self._max_active = max_active
        self._jobs: dict[str, _Job] = {}
        self._lock = threading.Lock()
        self._closed = False
        self._executor = ThreadPoolExecutor(max_workers=1, thread_name_prefix="robomach-jobs")
        _RUNNERS.add(self)

    def submit(
        self,
        kind: str,
        work: Callable[[JobContext], Any],
        *,
        on_done: Callable[[Any], None] | None = None,
        on_end: Callable[[JobInfo], None] | None = None,
    ) -> str:
        """Queue a job; returns its id.

        Raises:
            QueueFullError: ``max_active_per_kind`` jobs of this kind, or ``max_active`` of all
                kinds, are already queued or running.
        """
        with self._lock:
            if self._closed:
                raise ConflictError("the server is shutting down")
            self._check_room(kind)
            job = _Job(self, uuid.uuid4().hex[:12], kind, work, on_done, on_end)
            self._jobs[job.id] = job
            self._forget_old()
            self._executor.submit(self._run, job)
        self._changed(job)
        return job.id

    def get(self, job_id: str) -> JobInfo:
        return self._job(job_id).info()

    def wait(self, job_id: str, timeout_s: float | None = None) -> JobInfo:
        """The job's final state once it has ended (and its ``on_end`` has run).

        Raises:
            TimeoutError: It had not ended after ``timeout_s``.
        """
        job = self._job(job_id)
        try:
            return job.ended.result(timeout_s)
        except FutureTimeout:
            raise TimeoutError(
                f"job {job_id} ({job.kind}) had not ended after {timeout_s:g} s: {job.info()}"
            ) from None

    def list(self) -> builtins.list[JobInfo]:
        with self._lock:
            return [j.info() for j in self._jobs.values()]

    def active(self, kinds: Iterable[str] | None = None) -> builtins.list[JobInfo]:
        """Queued and running jobs, optionally of some kinds only."""
        wanted = None if kinds is None else set(kinds)
        with self._lock:
            return [
                j.info()
                for j in self._jobs.values()
                if j.status not in ENDED and (wanted is None or j.kind in wanted)
            ]

    def cancel(self, job_id: str) -> JobInfo:
        """Cancel a queued job now, or ask a running one to stop at its next check."""
        job = self._job(job_id)
        with self._lock:
            if job.status in ENDED:
                raise ConflictError(f"job {job_id} has already ended ({job.status})")
            job.cancel.set()
            queued = job.status == "queued"
            if queued:  # the worker will pass it by (``_run``)
                self._end_queued(job, f"{job.kind.replace('_', ' ')} was cancelled")
        if queued:
            self._finish(job)
        return job.info()

    def close(self, timeout_s: float = 10.0) -> None:
        """Cancel every job and stop the worker (waiting up to ``timeout_s`` for a running
        job to notice)."""
        with self._lock:
            self._closed = True
            pending = [j for j in self._jobs.values() if j.status == "queued"]
            running = [j for j in self._jobs.values() if j.status == "running"]
            for job in self._jobs.values():
                job.cancel.set()
            for job in pending:
                self._end_queued(job, "the server stopped")
        for job in pending:
            self._finish(job)
        self._executor.shutdown(wait=False, cancel_futures=True)
        for job in running:
            try:
                job.ended.result(timeout_s)
            except FutureTimeout:
                log.warning("job %s (%s) still running at close", job.id, job.kind)

    def stop_everything(self) -> None:
        """Ask every job to stop and start no queued one, without waiting (interpreter exit)."""
        with self._lock:
            for job in self._jobs.values():
                job.cancel.set()
        self._executor.shutdown(wait=False, cancel_futures=True)

    @staticmethod
    def _end_queued(job: _Job, error: str) -> None:
        job.status, job.error, job.finished_s = "cancelled", error, time.time()

    def _job(self, job_id: str) -> _Job:
        with self._lock:
            job = self._jobs.get(job_id)
        if job is None:
            raise NotFoundError(f"no job with id {job_id!r}")
        return job

    def _check_room(self, kind: str) -> None:
        active = [j for j in self._jobs.values() if j.status not in ENDED]
        same = sum(1 for j in active if j.kind == kind)
        what = kind.replace("_", " ")
        if same >= self._max_per_kind:
            raise QueueFullError(
                f"{same} {what} jobs are already queued or running (at most "
                f"{self._max_per_kind}): wait for one to end or cancel one at /api/jobs"
            )
        if len(active) >= self._max_active:
            raise QueueFullError(
                f"{len(active)} jobs are already queued or running (at most {self._max_active}): "
                f"wait for one to end or cancel one at /api/jobs before starting a {what} job"
            )

    def _forget_old(self) -> None:
        ended = [j for j in self._jobs.values() if j.status in ENDED]
        for job in ended[: max(0, len(ended) - self._keep)]:
            del self._jobs[job.id]

    def _changed(self, job: _Job) -> None:
        if self._on_change is not None:
            try:
                self._on_change(job.info())
            except Exception:  # a listener must not break a job
                log.exception("job listener failed")

    def _finish(self, job: _Job) -> None:
        # What the work captured (a cell, a project, its result) goes, before on_end runs.
        on_end, job.work, job.on_done, job.on_end = job.on_end, _ended, None, None
        if on_end is not None:
            try:
                on_end(job.info())
            except Exception:
                log.exception("on_end of job %s failed", job.id)
        self._changed(job)
        job.ended.set_result(job.info())

    def _run(self, job: _Job) -> None:
        """Run one job to its end, in the worker (its result lives only in this frame)."""
        with self._lock:
            if job.status != "queued":  # cancelled while queued
                return
            job.status, job.started_s = "running", time.time()
        self._changed(job)
        try:
            result = job.work(JobContext(job))
            if job.on_done is not None:
                job.on_done(result)
            del result  # gone before on_end runs (it may give memory back)
        except CancelledError as exc:
            job.status, job.error = "cancelled", str(exc)
        except RobomachError as exc:
            job.status, job.error = "failed", str(exc)
        except Exception as exc:
            log.exception("job %s (%s) failed", job.id, job.kind)
            job.status = "failed"
            job.error = describe_unexpected(exc)
        else:
            job.status, job.progress = "done", 1.0
        job.finished_s = time.time()
        self._finish(job)


# Every live runner, so that a program exiting without closing its sessions cancels their jobs:
# the executor's worker is not a daemon thread, and the interpreter joins it at exit.
_RUNNERS: weakref.WeakSet[JobRunner] = weakref.WeakSet()


def _cancel_at_exit() -> None:
    for runner in list(_RUNNERS):
        runner.stop_everything()


# Called before concurrent.futures joins its workers (registered later, so called first): the
# hook concurrent.futures itself uses for that join (private: typeshed's stubs leave it out).
threading._register_atexit(_cancel_at_exit)  # type: ignore[attr-defined]


def _ended(ctx: JobContext) -> None:
    """The work of a job that has ended (its own was let go)."""


def describe_unexpected(exc: BaseException) -> str:
    """A user-facing sentence for an error no check foresaw, saying what kind of limit it met
    (the class and message follow, for the report)."""
    what = f"{exc.__class__.__name__}: {exc}"[:500]
    if isinstance(exc, MemoryError):
        return f"not enough memory for this work: use a smaller input or fewer samples ({what})"
    if isinstance(exc, (OverflowError, FloatingPointError, ZeroDivisionError)):
        return (
            "a number in this work went outside what the simulation can compute: check that "
            f"every value is within its documented range ({what})"
        )
    if isinstance(exc, RecursionError):
        return f"the input is nested too deeply to process ({what})"
    return f"the server could not do this ({what})"


# --- the tapped cell: live pose and cancel during a job ----------------------------------
