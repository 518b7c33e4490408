"""A change whose save fails is not applied (issue 32, point 4): with the project database
locked by another program, a change answers 503 "try again" and the session, the database
and what a restart opens all keep the state before it; a client that retries once the lock
is gone records the change once.

A real SQLite file: a second connection holds its write lock (``BEGIN EXCLUSIVE``) as another
program would; the store's busy timeout runs out and the save raises. The store waits 5 s for a
lock; here, while the lock is held, 0.2 s (the same refusal, without 15 s of waiting for it).
"""

from __future__ import annotations

import sqlite3
from collections.abc import Iterator
from contextlib import contextmanager
from pathlib import Path

import pytest

from app.store import DB_FILENAME, Store
from tests.api.in_process import InProcessServer
from tests.api.server_process import Api

GP = "/api/guide-points"
LOCKED_BUSY_TIMEOUT_MS = 200


@contextmanager
def database_locked(data_dir: Path, store: Store) -> Iterator[None]:
    """Another program holds the database's write lock (and keeps readers of the WAL out of
    nothing: reads go on); ``store`` waits ``LOCKED_BUSY_TIMEOUT_MS`` for it meanwhile."""
    other = sqlite3.connect(data_dir / DB_FILENAME, isolation_level=None, timeout=0.1)
    try:
        other.execute("BEGIN EXCLUSIVE")
        usual_ms = store.wait_for_lock(LOCKED_BUSY_TIMEOUT_MS)
        try:
            yield
        finally:
            store.wait_for_lock(usual_ms)
        other.execute("ROLLBACK")
    finally:
        other.close()


def _stored_guide_points(data_dir: Path, project_id: int) -> int:
    with sqlite3.connect(data_dir / DB_FILENAME) as db:
        return db.execute(
            "SELECT COUNT(*) FROM guide_points WHERE project_id = ?", (project_id,)
        ).fetchone()[0]


@pytest.mark.slow  # each refused save waits out the store's busy timeout
def test_a_locked_database_leaves_the_guide_points_and_the_cell_unchanged(
    api: Api, app_server: InProcessServer
) -> None:
    project_id = api.ok("GET", "/api/projects/current")["id"]
    api.ok("POST", GP, 201)
    before = api.ok("GET", GP)
    compliance = api.ok("GET", "/api/leadthrough/compliance")
    cell = api.ok("GET", "/api/cell")
    with database_locked(app_server.data_dir, app_server.session.store):
        r = api.post(GP)
        assert r.status_code == 503 and "try again" in r.json()["detail"], r.text
        assert api.ok("GET", GP) == before  # not in the session either
        r = api.put("/api/leadthrough/compliance", json={"axes": ["z"], "frame": "tool"})
        assert r.status_code == 503, r.text
        assert api.ok("GET", "/api/leadthrough/compliance") == compliance
        r = api.put("/api/cell", json={"workpiece": "block"})
        assert r.status_code == 503, r.text
        assert api.ok("GET", "/api/cell") == cell
    assert _stored_guide_points(app_server.data_dir, project_id) == len(before)
    # The client retries once the lock is gone: the point is recorded once.
    api.ok("POST", GP, 201)
    assert len(api.ok("GET", GP)) == len(before) + 1
    assert _stored_guide_points(app_server.data_dir, project_id) == len(before) + 1
