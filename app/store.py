"""SQLite persistence of projects: cell settings, robot pose, guide points, recordings, exports.

PROBLEM   The workbench must save after every change and survive being killed at any moment
          without corrupting its file, while the API and the GUI act on it from several threads.
STRATEGY  One SQLite file in WAL mode with ``synchronous=FULL``: a committed transaction is on
          disk before ``commit`` returns, and an interrupted one is rolled back on the next open.
          Every save is one transaction (``BEGIN IMMEDIATE ... COMMIT``), so a project is never
          half written. Numpy arrays are stored as ``.npy`` bytes (exact dtype and shape).
SOLUTION  ``Store``: small typed read/write methods per part of a project. It validates
          nothing and raises nothing a user can cause (the session does that); a missing row
          reads as ``None``.
"""

from __future__ import annotations

import enum
import io
import json
import sqlite3
import threading
import time
from collections.abc import Iterator
from contextlib import contextmanager
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

DB_FILENAME = "robomach.sqlite"
SCHEMA_VERSION = 1
LOCK_WAIT_MS = 5000  # how long a save waits for another program's lock on the file

_SCHEMA = """
CREATE TABLE IF NOT EXISTS meta (
    key   TEXT PRIMARY KEY,
    value TEXT NOT NULL
);
CREATE TABLE IF NOT EXISTS projects (
    id          INTEGER PRIMARY KEY AUTOINCREMENT,
    name        TEXT NOT NULL UNIQUE,
    created_s   REAL NOT NULL,
    updated_s   REAL NOT NULL,
    cell_json   TEXT NOT NULL,
    robot_json  TEXT NOT NULL DEFAULT '{}',
    post_json   TEXT NOT NULL DEFAULT '{}'
);
CREATE TABLE IF NOT EXISTS meshes (
    project_id INTEGER PRIMARY KEY REFERENCES projects(id) ON DELETE CASCADE,
    filename   TEXT NOT NULL,
    data       BLOB NOT NULL
);
CREATE TABLE IF NOT EXISTS guide_points (
    project_id INTEGER NOT NULL REFERENCES projects(id) ON DELETE CASCADE,
    idx        INTEGER NOT NULL,
    T_base_tcp BLOB NOT NULL,
    joints_rad BLOB NOT NULL,
    time_s     REAL NOT NULL,
    force_N    BLOB NOT NULL,
    PRIMARY KEY (project_id, idx)
);
CREATE TABLE IF NOT EXISTS recordings (
    project_id INTEGER PRIMARY KEY REFERENCES projects(id) ON DELETE CASCADE,
    info_json  TEXT NOT NULL
);
CREATE TABLE IF NOT EXISTS recording_arrays (
    project_id INTEGER NOT NULL REFERENCES projects(id) ON DELETE CASCADE,
    name       TEXT NOT NULL,
    data       BLOB NOT NULL,
    PRIMARY KEY (project_id, name)
);
CREATE TABLE IF NOT EXISTS exports (
    project_id INTEGER NOT NULL REFERENCES projects(id) ON DELETE CASCADE,
    name       TEXT NOT NULL,
    created_s  REAL NOT NULL,
    files_json TEXT NOT NULL,
    PRIMARY KEY (project_id, name)
);
"""


class _Keep(enum.Enum):
    """Marks a part of a project that a save leaves as it is (an enum of one member, so that
    ``part is not KEEP`` narrows the part's type for a type checker)."""

    KEEP = "KEEP"

    def __repr__(self) -> str:
        return "KEEP"


KEEP = _Keep.KEEP


def array_to_bytes(a: np.ndarray) -> bytes:
    """``.npy`` bytes of an array (no pickling)."""
    buf = io.BytesIO()
    np.save(buf, np.asarray(a), allow_pickle=False)
    return buf.getvalue()


def array_from_bytes(data: bytes) -> np.ndarray:
    """The array of ``.npy`` bytes (no pickling)."""
    return np.load(io.BytesIO(data), allow_pickle=False)


@dataclass(frozen=True)
class ProjectRow:
    """One project's header row."""

    id: int
    name: str
    created_s: float
    updated_s: float


@dataclass(frozen=True)
class GuidePointRow:
    """A stored guide point (SI units)."""

    T_base_tcp: np.ndarray
    joints_rad: np.ndarray
    time_s: float
    force_N: np.ndarray


@dataclass(frozen=True)
class ProjectData:
    """Everything stored for one project, as plain JSON-able dicts and arrays."""

    row: ProjectRow
    cell: dict[str, Any]
    robot: dict[str, Any]
    post: dict[str, Any]
    mesh: tuple[str, bytes] | None
    guide_points: list[GuidePointRow]
    recording_info: dict[str, Any] | None
    recording_arrays: dict[str, np.ndarray]


class Store:
    """The project database. Thread-safe: one connection behind a lock.

    Args:
        path: The SQLite file (created with its folder), or ``":memory:"`` for a throwaway
            store (tests, GUI development).
    """

    def __init__(self, path: str | Path) -> None:
        self.path = str(path)
        if self.path != ":memory:":
            Path(self.path).parent.mkdir(parents=True, exist_ok=True)
        # isolation_level=None: no implicit transactions; every write opens its own below.
        self._conn = sqlite3.connect(self.path, check_same_thread=False, isolation_level=None)
        self._lock = threading.RLock()
        with self._lock:
            if self.path != ":memory:":
                self._conn.execute("PRAGMA journal_mode=WAL")
            self._conn.execute("PRAGMA synchronous=FULL")
            self._conn.execute("PRAGMA foreign_keys=ON")
            self._conn.execute(f"PRAGMA busy_timeout={LOCK_WAIT_MS}")
            with self._transaction() as c:
                for statement in _SCHEMA.split(";"):
                    if statement.strip():
                        c.execute(statement)
                c.execute(
                    "INSERT OR IGNORE INTO meta(key, value) VALUES ('schema_version', ?)",
                    (str(SCHEMA_VERSION),),
                )

    @classmethod
    def in_data_dir(cls, data_dir: str | Path) -> Store:
        """The store of a data folder (``<data_dir>/robomach.sqlite``)."""
        return cls(Path(data_dir) / DB_FILENAME)

    def close(self) -> None:
        """Close the connection (a WAL checkpoint folds the log back into the file)."""
        with self._lock:
            try:
                self._conn.execute("PRAGMA wal_checkpoint(TRUNCATE)")
            except sqlite3.Error:
                pass
            self._conn.close()

    def wait_for_lock(self, ms: int) -> int:
        """Wait up to ``ms`` (0-60000) for another program's lock on the file before a save is
        refused (``LOCK_WAIT_MS`` from the start); returns the wait this replaces."""
        if not 0 <= ms <= 60_000:
            raise ValueError(f"a lock wait of {ms} ms is outside 0-60000 ms")
        with self._lock:
            before = int(self._conn.execute("PRAGMA busy_timeout").fetchone()[0])
            self._conn.execute(f"PRAGMA busy_timeout={int(ms)}")
            return before

    @contextmanager
    def _transaction(self) -> Iterator[_Tx]:
        with self._lock:
            self._conn.execute("BEGIN IMMEDIATE")
            try:
                yield _Tx(self._conn)
            except BaseException:
                self._conn.execute("ROLLBACK")
                raise
            else:
                self._conn.execute("COMMIT")

    def _query(self, sql: str, args: tuple = ()) -> list[tuple]:
        with self._lock:
            return self._conn.execute(sql, args).fetchall()

    # --- meta -------------------------------------------------------------------------------

    def last_project_id(self) -> int | None:
        rows = self._query("SELECT value FROM meta WHERE key = 'last_project'")
        return int(rows[0][0]) if rows else None

    def set_last_project(self, project_id: int) -> None:
        with self._transaction() as c:
            c.execute(
                "INSERT INTO meta(key, value) VALUES ('last_project', ?) "
                "ON CONFLICT(key) DO UPDATE SET value = excluded.value",
                (str(project_id),),
            )

    # --- projects ---------------------------------------------------------------------------

    def list_projects(self) -> list[ProjectRow]:
        """Every project, most recently changed first."""
        rows = self._query(
            "SELECT id, name, created_s, updated_s FROM projects ORDER BY updated_s DESC, id DESC"
        )
        return [ProjectRow(*r) for r in rows]

    def get_project(self, project_id: int) -> ProjectRow | None:
        rows = self._query(
            "SELECT id, name, created_s, updated_s FROM projects WHERE id = ?", (project_id,)
        )
        return ProjectRow(*rows[0]) if rows else None

    def find_project(self, name: str) -> ProjectRow | None:
        rows = self._query(
            "SELECT id, name, created_s, updated_s FROM projects WHERE name = ?", (name,)
        )
        return ProjectRow(*rows[0]) if rows else None

    def create_project(
        self, name: str, cell: dict[str, Any], robot: dict[str, Any] | None = None
    ) -> ProjectRow:
        """A new project (the name must be free), made the last opened one."""
        now = time.time()
        with self._transaction() as c:
            cur = c.execute(
                "INSERT INTO projects(name, created_s, updated_s, cell_json, robot_json) "
                "VALUES (?, ?, ?, ?, ?)",
                (name, now, now, json.dumps(cell), json.dumps(robot or {})),
            )
            project_id = cur.lastrowid
            assert project_id is not None  # an INSERT sets it
            c.execute(
                "INSERT INTO meta(key, value) VALUES ('last_project', ?) "
                "ON CONFLICT(key) DO UPDATE SET value = excluded.value",
                (str(project_id),),
            )
        return ProjectRow(project_id, name, now, now)

    def rename_project(self, project_id: int, name: str) -> None:
        with self._transaction() as c:
            c.execute(
                "UPDATE projects SET name = ?, updated_s = ? WHERE id = ?",
                (name, time.time(), project_id),
            )

    def delete_project(self, project_id: int) -> None:
        with self._transaction() as c:
            c.execute("DELETE FROM projects WHERE id = ?", (project_id,))

    def load_project(self, project_id: int) -> ProjectData | None:
        """Everything stored for a project, or None when it does not exist."""
        with self._lock:
            row = self.get_project(project_id)
            if row is None:
                return None
            cell_json, robot_json, post_json = self._query(
                "SELECT cell_json, robot_json, post_json FROM projects WHERE id = ?", (project_id,)
            )[0]
            mesh_rows = self._query(
                "SELECT filename, data FROM meshes WHERE project_id = ?", (project_id,)
            )
            guides = [
                GuidePointRow(
                    array_from_bytes(T), array_from_bytes(q), float(t), array_from_bytes(f)
                )
                for T, q, t, f in self._query(
                    "SELECT T_base_tcp, joints_rad, time_s, force_N FROM guide_points "
                    "WHERE project_id = ? ORDER BY idx",
                    (project_id,),
                )
            ]
            rec_rows = self._query(
                "SELECT info_json FROM recordings WHERE project_id = ?", (project_id,)
            )
            arrays = {
                name: array_from_bytes(data)
                for name, data in self._query(
                    "SELECT name, data FROM recording_arrays WHERE project_id = ?", (project_id,)
                )
            }
        return ProjectData(
            row=row,
            cell=json.loads(cell_json),
            robot=json.loads(robot_json),
            post=json.loads(post_json),
            mesh=(mesh_rows[0][0], bytes(mesh_rows[0][1])) if mesh_rows else None,
            guide_points=guides,
            recording_info=json.loads(rec_rows[0][0]) if rec_rows else None,
            recording_arrays=arrays,
        )

    # --- parts of a project: every save is one transaction ---------------------------------

    def save(
        self,
        project_id: int,
        *,
        cell: dict[str, Any] | _Keep = KEEP,
        mesh: tuple[str, bytes] | None | _Keep = KEEP,
        robot: dict[str, Any] | _Keep = KEEP,
        post: dict[str, Any] | _Keep = KEEP,
        guide_points: list[GuidePointRow] | _Keep = KEEP,
        recording: tuple[dict[str, Any], dict[str, np.ndarray]] | None | _Keep = KEEP,
    ) -> None:
        """Write the given parts of a project in one transaction; parts left out are kept.

        Args:
            cell: Cell settings (JSON-able).
            mesh: (file name, bytes) of an uploaded workpiece; None for a built-in one.
            robot: Robot joints and compliance selection (JSON-able).
            post: Post-processing settings and whether they were applied (JSON-able).
            guide_points: Replaces every guide point.
            recording: (info, arrays) of the last recording; None deletes it.
        """
        with self._transaction() as c:
            for column, doc in (("cell_json", cell), ("robot_json", robot), ("post_json", post)):
                if doc is not KEEP:
                    c.execute(
                        f"UPDATE projects SET {column} = ? WHERE id = ?",
                        (json.dumps(doc), project_id),
                    )
            if mesh is not KEEP:
                c.execute("DELETE FROM meshes WHERE project_id = ?", (project_id,))
                if mesh is not None:
                    c.execute(
                        "INSERT INTO meshes(project_id, filename, data) VALUES (?, ?, ?)",
                        (project_id, mesh[0], mesh[1]),
                    )
            if guide_points is not KEEP:
                _write_guide_points(c, project_id, guide_points)
            if recording is not KEEP:
                c.execute("DELETE FROM recordings WHERE project_id = ?", (project_id,))
                c.execute("DELETE FROM recording_arrays WHERE project_id = ?", (project_id,))
                if recording is not None:
                    info, arrays = recording
                    c.execute(
                        "INSERT INTO recordings(project_id, info_json) VALUES (?, ?)",
                        (project_id, json.dumps(info)),
                    )
                    c.executemany(
                        "INSERT INTO recording_arrays(project_id, name, data) VALUES (?, ?, ?)",
                        [(project_id, k, array_to_bytes(v)) for k, v in arrays.items()],
                    )
            c.touch(project_id)

    # --- exports ----------------------------------------------------------------------------

    def save_export(self, project_id: int, name: str, files: dict[str, str]) -> float:
        """Store (or replace) a named export: file name -> text. Returns its time."""
        now = time.time()
        with self._transaction() as c:
            c.execute(
                "INSERT INTO exports(project_id, name, created_s, files_json) VALUES (?, ?, ?, ?) "
                "ON CONFLICT(project_id, name) DO UPDATE SET created_s = excluded.created_s, "
                "files_json = excluded.files_json",
                (project_id, name, now, json.dumps(files)),
            )
            c.touch(project_id)
        return now

    def list_exports(self, project_id: int) -> list[tuple[str, float, list[str]]]:
        """(name, created_s, file names) of the project's exports, newest first."""
        rows = self._query(
            "SELECT name, created_s, files_json FROM exports WHERE project_id = ? "
            "ORDER BY created_s DESC",
            (project_id,),
        )
        return [(n, float(t), sorted(json.loads(f))) for n, t, f in rows]

    def get_export(self, project_id: int, name: str) -> dict[str, str] | None:
        rows = self._query(
            "SELECT files_json FROM exports WHERE project_id = ? AND name = ?", (project_id, name)
        )
        return json.loads(rows[0][0]) if rows else None


class _Tx:
    """The cursor-like handle of one open transaction."""

    def __init__(self, conn: sqlite3.Connection) -> None:
        self._conn = conn

    def execute(self, sql: str, args: tuple = ()) -> sqlite3.Cursor:
        return self._conn.execute(sql, args)

    def executemany(self, sql: str, rows: list[tuple]) -> sqlite3.Cursor:
        return self._conn.executemany(sql, rows)

    def touch(self, project_id: int) -> None:
        self._conn.execute(
            "UPDATE projects SET updated_s = ? WHERE id = ?", (time.time(), project_id)
        )


def _write_guide_points(c: _Tx, project_id: int, points: list[GuidePointRow]) -> None:
    c.execute("DELETE FROM guide_points WHERE project_id = ?", (project_id,))
    c.executemany(
        "INSERT INTO guide_points(project_id, idx, T_base_tcp, joints_rad, time_s, force_N) "
        "VALUES (?, ?, ?, ?, ?, ?)",
        [
            (
                project_id,
                i,
                array_to_bytes(p.T_base_tcp),
                array_to_bytes(p.joints_rad),
                float(p.time_s),
                array_to_bytes(p.force_N),
            )
            for i, p in enumerate(points)
        ],
    )
