"""Bad command-line input exits 2 with one line, as every other refusal does (issue 32, point
7): ``serve`` with ``--data`` naming a file or a folder whose database is not one, or with a
``--port`` already taken, exited 1 ("the server could not do this") or 3 (uvicorn's startup
failure after the rest had started); ``demo`` with a million-row ``--guide-points`` file ran
a 3-minute lead-through before it met the 200-point cap.
"""

from __future__ import annotations

import socket
import subprocess
import sys
from pathlib import Path

import pytest

from app.cli import main
from tests.api.server_process import free_port
from tests.app.test_cli_hardening import _one_line_error

ROOT = Path(__file__).resolve().parents[2]


def _serve(tmp_path: Path, *args: str) -> subprocess.CompletedProcess:
    return subprocess.run(
        [sys.executable, "-m", "app.cli", "serve", "--viser-port", str(free_port()), *args],
        cwd=ROOT, capture_output=True, text=True, timeout=120,
    )  # fmt: skip


def _assert_one_line(proc: subprocess.CompletedProcess, *words: str) -> None:
    assert proc.returncode == 2, proc.stderr
    assert "Traceback" not in proc.stderr
    lines = [line for line in proc.stderr.splitlines() if line.strip()]
    assert len(lines) == 1 and lines[0].startswith("robomach serve: error:"), proc.stderr
    for word in words:
        assert word in lines[0], lines[0]


@pytest.mark.slow  # a process each
def test_serve_refuses_a_data_folder_it_cannot_use(tmp_path: Path) -> None:
    a_file = tmp_path / "notes.txt"
    a_file.write_text("not a folder")
    _assert_one_line(_serve(tmp_path, "--port", str(free_port()), "--data", str(a_file)),
                     "--data", "cannot write files there")  # fmt: skip
    garbage = tmp_path / "garbage"
    garbage.mkdir()
    (garbage / "robomach.sqlite").write_bytes(b"not a database " * 100)
    _assert_one_line(_serve(tmp_path, "--port", str(free_port()), "--data", str(garbage)),
                     "--data", "not a readable robomach database")  # fmt: skip


@pytest.mark.slow  # a process
def test_serve_refuses_a_port_already_taken(tmp_path: Path) -> None:
    with socket.socket() as taken:
        taken.bind(("127.0.0.1", 0))
        taken.listen()
        port = taken.getsockname()[1]
        proc = _serve(tmp_path, "--port", str(port), "--data", str(tmp_path / "data"))
    _assert_one_line(proc, f"port {port}", "is not free", "--port")


def test_demo_refuses_more_guide_points_than_a_project_holds_before_any_work(
    tmp_path: Path, capsys: pytest.CaptureFixture
) -> None:
    many = tmp_path / "many.csv"
    many.write_text("x_mm,y_mm,z_mm\n" + "".join(f"{800 + i * 0.01},120,30\n" for i in range(201)))
    code = main(["demo", "--out", str(tmp_path / "o"), "--guide-points", str(many)])
    _one_line_error(capsys, code, "demo", "201 points, more than the 200")
    huge = tmp_path / "huge.csv"
    huge.write_text("1,2,3\n" * 400_000)
    code = main(["demo", "--out", str(tmp_path / "o"), "--guide-points", str(huge)])
    _one_line_error(capsys, code, "demo", "is not a guide-point file")
    assert not (tmp_path / "o" / "summary.json").exists()
