"""A cap on queued jobs of every kind: one more is refused with 429 and a message (issue 19,
R9: 300 machining comparisons, 3.3 h of work, were accepted at once, the robot locked behind
them). In process: the session's job runner, and the machining route through ``TestClient``
on a project imported from a small synthetic recording."""

from __future__ import annotations

import threading
from collections.abc import Iterator
from dataclasses import replace

import pytest
from fastapi.testclient import TestClient

from app.session import JobRunner, QueueFullError
from app.session.jobs import MAX_ACTIVE_JOBS, MAX_ACTIVE_JOBS_PER_KIND
from robomach_core import project as core
from tests.conftest import app_client
from tests.core.project.test_project import learned_block_project


def test_the_runner_caps_jobs_per_kind_and_in_all() -> None:
    release = threading.Event()
    runner = JobRunner()
    try:
        held = [runner.submit("machining_compare", lambda ctx: release.wait(30))]
        held += [runner.submit("machining_compare", lambda ctx: None)
                 for _ in range(MAX_ACTIVE_JOBS_PER_KIND - 1)]  # fmt: skip
        with pytest.raises(QueueFullError, match="3 machining compare jobs are already queued"):
            runner.submit("machining_compare", lambda ctx: None)
        others = [f"kind_{i}" for i in range(MAX_ACTIVE_JOBS - len(held))]
        for kind in others:
            runner.submit(kind, lambda ctx: None)
        with pytest.raises(QueueFullError, match=f"{MAX_ACTIVE_JOBS} jobs are already queued"):
            runner.submit("cmrr", lambda ctx: None)
        runner.cancel(held[-1])  # cancelling one makes room again
        runner.submit("machining_compare", lambda ctx: None)
    finally:
        release.set()
        runner.close()


def test_wait_returns_each_ending_once_on_end_has_run() -> None:
    """``JobRunner.wait``: the final state of a job done, failed, cancelled while queued and
    cancelled while running, after its ``on_end``; a ``TimeoutError`` while it runs."""
    from robomach_core.errors import InvalidInputError

    release, ends = threading.Event(), []
    runner = JobRunner()
    try:

        def held(ctx) -> None:
            while not release.wait(0.01):
                ctx.check_cancelled()

        def bad(ctx) -> None:
            raise InvalidInputError("no such thing")

        running = runner.submit("a", held, on_end=ends.append)
        queued = runner.submit("b", lambda ctx: 1, on_end=ends.append)
        with pytest.raises(TimeoutError, match="had not ended after 0.05 s"):
            runner.wait(running, 0.05)
        assert runner.cancel(queued).status == "cancelled"
        assert runner.wait(queued, 5).status == "cancelled"
        runner.cancel(running)
        info = runner.wait(running, 5)
        assert info.status == "cancelled" and "a was cancelled" in info.error
        failed, ok = runner.submit("c", bad, on_end=ends.append), runner.submit("d", lambda c: 1)
        assert runner.wait(failed, 5).error == "no such thing"
        assert runner.wait(ok, 5).status == "done" and runner.get(ok).progress == 1.0
        assert [e.status for e in ends] == ["cancelled", "cancelled", "failed"]
    finally:
        release.set()
        runner.close()


@pytest.mark.slow  # a Python process of its own
def test_a_program_that_never_closes_its_runner_exits_while_a_job_runs() -> None:
    """The executor's worker is joined at interpreter exit: the runner cancels its jobs first,
    so the program ends now instead of when a 10-minute job would have."""
    import subprocess
    import sys

    script = (
        "import threading, time\n"
        "from app.session import JobRunner\n"
        "started = threading.Event()\n"
        "def work(ctx):\n"
        "    started.set()\n"
        "    end = time.monotonic() + 600\n"
        "    while time.monotonic() < end:\n"
        "        ctx.check_cancelled()\n"
        "        time.sleep(0.01)\n"
        "JobRunner().submit('long', work)\n"
        "started.wait(30)\n"
    )
    done = subprocess.run([sys.executable, "-c", script], timeout=120, capture_output=True)
    assert done.returncode == 0, done.stderr.decode()


def processed_project_bytes() -> bytes:
    """A project on the block with a short synthetic recording, post-processed on import."""
    project = learned_block_project()
    workpiece = core.build_workpiece(project.cell, None)
    processed = core.process(project.learned, project.post_settings, workpiece, 0.001)
    return core.project_file_bytes(replace(project, processed=processed))


@pytest.fixture(scope="module")
def queued() -> Iterator[TestClient]:
    """The app on a project imported from a small processed recording."""
    with app_client() as c:
        r = c.post(
            "/api/projects/import",
            params={"name": "queue"},
            files={"file": ("project.npz", processed_project_bytes())},
        )
        assert r.status_code == 201, r.text
        yield c


@pytest.mark.slow  # process pools of queued comparisons
def test_machining_comparisons_past_the_cap_get_429(queued: TestClient) -> None:
    started = []
    try:
        for _ in range(MAX_ACTIVE_JOBS_PER_KIND):
            r = queued.post("/api/machining/compare")
            assert r.status_code == 202, r.text
            started.append(r.json()["job_id"])
        r = queued.post("/api/machining/compare")
        assert r.status_code == 429, r.text
        assert "machining compare jobs are already queued or running" in r.json()["detail"]
        assert "/api/jobs" in r.json()["detail"]
    finally:
        for job_id in started:
            queued.post(f"/api/jobs/{job_id}/cancel")
