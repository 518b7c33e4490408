"""``robomach machine`` end to end on a block demo project, and its answers to bad input."""

from __future__ import annotations

import csv
import json
import subprocess
import sys
from pathlib import Path

import pytest

from robomach_core.export import check_rapid_module
from robomach_core.project import load_project_file
from tests.demo_project import block_demo_dir

SUMMARY_KEYS = {
    "controller",
    "compensation",
    "cycle_time_s",
    "force_peak_N",
    "force_limit_N",
    "force_rms_error_N",
    "wall_error_max_mm",
    "wall_error_rms_mm",
    "realtime_factor",
    "chosen",
}
CSV_COLUMNS = {
    "time_s",
    "path_mm",
    "feed_mm_s",
    "depth_mm",
    "force_N",
    "deflection_mm",
    "wall_error_mm",
}


def robomach(*args: str, timeout: float = 900) -> subprocess.CompletedProcess:
    return subprocess.run(
        [sys.executable, "-m", "app.cli", *args], capture_output=True, text=True, timeout=timeout
    )


def _assert_one_line_error(proc: subprocess.CompletedProcess, *words: str) -> None:
    assert proc.returncode == 2, proc.stderr
    assert "Traceback" not in proc.stderr
    lines = [line for line in proc.stderr.splitlines() if "error" in line]
    assert len(lines) == 1, proc.stderr
    for w in words:
        assert w in lines[0], lines[0]


@pytest.fixture(scope="module")
def compared(tmp_path_factory) -> Path:
    """constant and adaptive-pi, compensation off and offline, on the block demo's program."""
    out = tmp_path_factory.mktemp("machine")
    proc = robomach(
        "machine",
        "--out",
        str(out),
        "--from",
        str(block_demo_dir()),
        "--controller",
        "all",
        "--compensation",
        "off",
    )
    assert proc.returncode == 0, proc.stderr
    return out


def test_the_matrix_writes_summary_traces_program_and_figure(compared):
    summary = json.loads((compared / "machining_summary.json").read_text())
    runs = summary["runs"]
    assert [r["controller"] for r in runs] == [
        "constant",
        "fixed-pi",
        "adaptive-pi",
        "fuzzy",
        "two-stage",
        "adaptive-lq",
    ]
    for r in runs:
        assert SUMMARY_KEYS <= set(r), sorted(SUMMARY_KEYS - set(r))
        assert r["force_limit_N"] == 150.0
        assert r["completed"]
        assert r["cycle_time_s"] > 0 and r["realtime_factor"] > 1
        path = compared / f"machining_{r['controller']}_{r['compensation']}.csv"
        with path.open() as f:
            rows = list(csv.DictReader(f))
        assert CSV_COLUMNS <= set(rows[0])
        assert float(rows[-1]["path_mm"]) == pytest.approx(r["path_length_mm"], abs=1.0)
        assert max(float(row["force_N"]) for row in rows) == pytest.approx(r["force_peak_N"])
    assert sum(r["chosen"] for r in runs) == 1
    chosen = next(r for r in runs if r["chosen"])
    assert summary["chosen"] == {
        "controller": chosen["controller"],
        "compensation": chosen["compensation"],
    }
    assert chosen["force_peak_N"] <= 1.1 * chosen["force_limit_N"]
    program = (compared / "program.mod").read_text()
    check_rapid_module(program)
    assert ("FCSpdChgAct" in program) == (chosen["controller"] != "constant")
    settings = json.loads((compared / "settings.json").read_text())
    assert settings["machining"]["chosen"] == summary["chosen"]
    assert settings["status"]["machining"] == "current"
    assert (compared / "machining.png").read_bytes()[:4] == b"\x89PNG"


def test_the_saved_project_holds_the_choice(compared):
    project = load_project_file(compared / "project.npz")
    chosen = json.loads((compared / "machining_summary.json").read_text())["chosen"]
    assert project.machining_settings.settings.controller == chosen["controller"]
    assert (project.cmrr is None) == (chosen["controller"] == "constant")
    assert project.status()["postprocess"] == "current"


def test_offline_compensation_exports_the_corrected_program(tmp_path):
    profile = tmp_path / "stock.csv"
    profile.write_text("s_mm,allowance_mm\n0,0\n10,1.5\n200,2.5\n")
    out = tmp_path / "o"
    proc = robomach(
        "machine",
        "--out",
        str(out),
        "--from",
        str(block_demo_dir()),
        "--controller",
        "fuzzy",
        "--compensation",
        "offline",
        "--stock",
        str(profile),
        "--no-plot",
    )
    assert proc.returncode == 0, proc.stderr
    summary = json.loads((out / "machining_summary.json").read_text())
    assert summary["stock"]["source"] == "profile"
    assert summary["stock"]["allowance_max_mm"] == pytest.approx(2.5)
    program = (out / "program.mod").read_text()
    assert "FCSpdChgAct" in program
    assert "offline for the fuzzy cut's predicted process force" in program
    plain = (block_demo_dir() / "program.mod").read_text()
    assert program.count("MoveL") > 5 * plain.count("MoveL")  # densified and corrected


@pytest.mark.parametrize(
    ("args", "words"),
    [
        (["--force-limit-N", "0"], ["--force-limit-N", "1-5000 N"]),
        (["--seed", "-1"], ["--seed"]),
        (["--from", "/nonexistent/demo"], ["--from", "no such folder"]),
        (["--from", "/tmp", "--workpiece", "block"], ["not both"]),
        (["--stock", "/nonexistent/stock.stl"], ["--stock", "no such file"]),
        (["--workpiece", "part.stl"], ["--workpiece", "guide points", "--from"]),
    ],
)
def test_bad_arguments_give_one_line_and_exit_2(tmp_path, args, words):
    _assert_one_line_error(robomach("machine", "--out", str(tmp_path / "o"), *args), *words)


def test_a_folder_without_a_project(tmp_path):
    (tmp_path / "demo").mkdir()
    proc = robomach("machine", "--out", str(tmp_path / "o"), "--from", str(tmp_path / "demo"))
    _assert_one_line_error(proc, "project.npz", "robomach demo")


def test_an_unwritable_out_is_refused_before_work():
    proc = robomach("machine", "--out", "/proc/robomach-machine", "--workpiece", "block")
    _assert_one_line_error(proc, "--out", "cannot write")
