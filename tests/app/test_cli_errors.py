"""No tracebacks from the command line (issue 19, R14): a binary settings file, crafted
``machine --from`` project files, and the R1/R2 files (a flat STL, a 5,000-link URDF, which
exited 139) each give one line and a non-zero exit.

The crafted files are the kinds the audit met (OverflowError, ValueError, TypeError): numbers
far out of range, arrays that disagree, values of the wrong type. R1 and R2 run as
subprocesses: on the old code they crashed the interpreter (SIGSEGV), which would take pytest
down with them in process.
"""

from __future__ import annotations

import json
import struct
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from app.cli import main
from tests.api.test_hardening import _deep_urdf
from tests.app.test_cli_hardening import _one_line_error
from tests.core.project.test_project_file_check import arrays_of, npz, small_project_bytes

ROOT = Path(__file__).resolve().parents[2]
BINARY = bytes(range(256)) * 4


@pytest.fixture(scope="module")
def good_project() -> bytes:
    return small_project_bytes()


@pytest.mark.parametrize(
    ("argv", "flag"),
    [
        (["cmrr", "--scenario", "lund-df", "--settings"], "--settings"),
        (["demo", "--cmrr-settings"], "--cmrr-settings"),
        (["demo", "--compensation-settings"], "--compensation-settings"),
    ],
)
def test_a_binary_settings_file_is_one_line(tmp_path, capsys, argv, flag):
    settings = tmp_path / "settings.json"
    settings.write_bytes(BINARY)
    out = ["--out", str(tmp_path / "out")] if argv[0] == "demo" else []
    code = main([*argv, str(settings), *out])
    line = _one_line_error(capsys, code, argv[0])
    assert "not a text file" in line or "cannot read" in line, line


def _crafted(base: bytes, *, arrays: dict | None = None, edit=None) -> bytes:
    a = arrays_of(base)
    a.update(arrays or {})
    doc = json.loads(a["document"].tobytes())
    if edit is not None:
        edit(doc)
    a["document"] = np.frombuffer(json.dumps(doc).encode(), np.uint8)
    return npz(a)


CRAFTED = {
    "wobj-1e308": ({}, lambda d: d["cell"].update(wobj_mm_deg=[1e308, 0, 0]), "work-object x"),
    "feed-1e308": ({}, lambda d: d["post_settings"].update(speed_mean_m_s=1e308), "speed"),
    "seed-2^70": ({}, lambda d: d["cell"].update(seed=2**70), "seed"),
    "wrong-type": ({}, lambda d: d["post_settings"].update(tolerance_m="x"), "tolerance"),
    "not-a-mapping": ({}, lambda d: d["recording"].update(learning=[1, 2]), "damaged"),
    "lengths": ("short", None, "differ in length"),
    "x1e300": ("far", None, "more than 10 m"),
}


@pytest.mark.parametrize("case", sorted(CRAFTED))
def test_crafted_machine_from_files_are_one_line(tmp_path, capsys, good_project, case):
    arrays, edit, needle = CRAFTED[case]
    a = arrays_of(good_project)
    if arrays == "short":
        arrays = {"rec_time_s": a["rec_time_s"][:-3]}
    elif arrays == "far":
        arrays = {"rec_position_m": a["rec_position_m"] * 1e300}
    folder = tmp_path / "from"
    folder.mkdir()
    (folder / "project.npz").write_bytes(_crafted(good_project, arrays=arrays, edit=edit))
    code = main(["machine", "--from", str(folder), "--out", str(tmp_path / "out")])
    assert needle in _one_line_error(capsys, code, "machine")


def _run_cli(*args: str, cwd: Path) -> subprocess.CompletedProcess:
    return subprocess.run(
        [sys.executable, "-m", "app.cli", *args],
        cwd=cwd,
        env={"PYTHONPATH": str(ROOT), "PATH": "/usr/bin:/bin"},
        capture_output=True,
        text=True,
        timeout=300,
    )


@pytest.mark.slow  # CLI subprocesses
def test_r1_and_r2_files_through_the_cli_are_one_line_not_a_crash(tmp_path):
    flat = tmp_path / "flat.stl"
    square = [(0, 0, 0, 100, 0, 0, 100, 100, 0), (0, 0, 0, 100, 100, 0, 0, 100, 0)]
    flat.write_bytes(
        bytes(80)
        + struct.pack("<I", 2)
        + b"".join(struct.pack("<12f", 0, 0, 0, *t) + b"\0\0" for t in square)
    )
    deep = tmp_path / "deep.urdf"
    deep.write_bytes(_deep_urdf(5000))
    for args, needle in (
        (("--workpiece", str(flat)), "0 mm thick"),
        (("--robot", str(deep)), "5008 links"),
    ):
        done = _run_cli("demo", "--out", str(tmp_path / "out"), *args, cwd=tmp_path)
        assert done.returncode == 2, (done.returncode, done.stderr[-2000:])
        lines = [line for line in done.stderr.splitlines() if line.strip()]
        assert len(lines) == 1 and lines[0].startswith("robomach demo: error:"), done.stderr
        assert needle in lines[0]


def test_an_unforeseen_fault_is_one_line_and_the_traceback_on_request(
    capsys, monkeypatch: pytest.MonkeyPatch
):
    import app.commands.cmrr as command

    def broken(args) -> int:
        raise OverflowError("(34, 'Numerical result out of range')")

    monkeypatch.setattr(command, "run", broken)
    parser_default = command.add_parser

    def add_parser(subparsers) -> None:
        parser_default(subparsers)
        subparsers.choices["cmrr"].set_defaults(func=broken)

    monkeypatch.setattr(command, "add_parser", add_parser)
    code = main(["cmrr", "--scenario", "lund-df"])
    err = capsys.readouterr().err
    assert code == 1 and "Traceback" not in err
    lines = [line for line in err.splitlines() if line.strip()]
    assert len(lines) == 1 and "outside what the simulation can compute" in lines[0]
    assert "ROBOMACH_DEBUG=1" in lines[0]
    monkeypatch.setenv("ROBOMACH_DEBUG", "1")
    with pytest.raises(OverflowError):
        main(["cmrr", "--scenario", "lund-df"])
