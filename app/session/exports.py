"""Saved exports of a project: their names, the store rows and the files under the data folder.

A saved export is the files of ``robomach_core.project.program_files`` kept under a name, in the
store (so a project carries them) and, when the session has a data folder, in
``<data_dir>/exports/<project id>/<name>/`` (written atomically, never outside that folder).
"""

from __future__ import annotations

import os
import tempfile
from pathlib import Path

from robomach_core.errors import InvalidInputError

from ..store import Store
from .records import EXPORT_NAME_RE, ExportInfo, NotFoundError


def check_export_name(name: object) -> str:
    """``name`` when it is a valid export name (1-64 letters, digits, ``_ . -``)."""
    if not isinstance(name, str) or not EXPORT_NAME_RE.match(name) or ".." in name:
        raise InvalidInputError(
            "an export name is 1-64 letters, digits, '_', '.' or '-', starting with a letter "
            f"or digit and without '..'; got {name!r}"
        )
    return name


def rapid_identifier_or(name: str) -> str:
    """A RAPID module name from an export name (``LearnedPath`` when it has no letter)."""
    from robomach_core.export.rapid import rapid_identifier

    try:
        return rapid_identifier(name, prefix="m")
    except InvalidInputError:
        return "LearnedPath"


def export_folder(
    data_dir: Path | None, project_id: int, name: str, *, create: bool = True
) -> Path | None:
    """The folder of a saved export (None without a data folder)."""
    if data_dir is None:
        return None
    root = (data_dir / "exports").resolve()
    folder = (root / str(project_id) / name).resolve()
    if not folder.is_relative_to(root) or folder == root:  # belt and braces after the regex
        raise InvalidInputError(f"export name {name!r} would leave the data folder")
    if create:
        folder.mkdir(parents=True, exist_ok=True)
    return folder


def save_export(
    store: Store, data_dir: Path | None, project_id: int, name: str, files: dict[str, str]
) -> ExportInfo:
    """Keep ``files`` under ``name`` in the store and the data folder (the same name replaces)."""
    created = store.save_export(project_id, name, files)
    folder = export_folder(data_dir, project_id, name)
    if folder is not None:
        for filename, text in files.items():
            write_atomic(folder / filename, text)
    return ExportInfo(name, created, sorted(files), folder)


def list_exports(store: Store, data_dir: Path | None, project_id: int) -> list[ExportInfo]:
    """A project's saved exports, newest first."""
    return [
        ExportInfo(n, t, files, export_folder(data_dir, project_id, n, create=False))
        for n, t, files in store.list_exports(project_id)
    ]


def export_file(store: Store, project_id: int, name: str, filename: str) -> str:
    """The text of one file of a saved export."""
    files = store.get_export(project_id, name)
    if files is None:
        raise NotFoundError(f"no export named {name!r} in this project")
    if filename not in files:
        raise NotFoundError(f"export {name!r} has no file {filename!r}; it has {sorted(files)}")
    return files[filename]


def write_atomic(path: Path, text: str) -> None:
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
