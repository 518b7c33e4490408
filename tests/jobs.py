"""The one job wait of the tests: the runner's own ``wait`` (``JobRunner.wait``)."""

from __future__ import annotations

from app.session import Session
from app.session.records import JobInfo


def finished(session: Session, job_id: str, timeout_s: float = 300.0) -> JobInfo:
    """The job's final state; ``TimeoutError`` if it had not ended after ``timeout_s``."""
    return session.jobs.wait(job_id, timeout_s)


def done(session: Session, job_id: str, timeout_s: float = 300.0) -> JobInfo:
    """The job's final state, asserted done (its error otherwise)."""
    info = finished(session, job_id, timeout_s)
    assert info.status == "done", info
    return info
