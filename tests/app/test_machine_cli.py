"""``robomach machine`` end to end (its ``main`` in this process) on a block demo project (slow:
the shared demo subprocess), its exit codes, and its answers to bad input; the interrupt test
runs a process of its own."""

from __future__ import annotations

import csv
import json
import subprocess
import sys
from pathlib import Path

import pytest

from robomach_core.export import check_rapid_module
from robomach_core.project import load_project_file
from tests.cli import robomach_here
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


def _assert_one_line_error(proc: subprocess.CompletedProcess, *words: str) -> None:
    assert proc.returncode == 2, proc.stderr
    assert "Traceback" not in proc.stderr
    lines = [line for line in proc.stderr.splitlines() if "error" in line]
    assert len(lines) == 1, proc.stderr
    for w in words:
        assert w in lines[0], lines[0]


@pytest.fixture(scope="module")
def compared(tmp_path_factory) -> Path:  # exit 0: the matrix
    """constant and adaptive-pi, compensation off and offline, on the block demo's program."""
    out = tmp_path_factory.mktemp("machine")
    proc = robomach_here(
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
    (out / "stdout.txt").write_text(proc.stdout)
    return out


@pytest.mark.slow
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
    assert chosen["force_peak_N"] <= chosen["force_limit_N"]  # the limit as documented
    program = (compared / "program.mod").read_text()
    check_rapid_module(program)
    assert ("FCSpdChgAct" in program) == (chosen["controller"] != "constant")
    settings = json.loads((compared / "settings.json").read_text())
    assert settings["machining"]["chosen"] == summary["chosen"]
    assert settings["status"]["machining"] == "current"
    assert (compared / "machining.png").read_bytes()[:4] == b"\x89PNG"


@pytest.mark.slow
def test_the_saved_project_holds_the_choice(compared):
    project = load_project_file(compared / "project.npz")
    chosen = json.loads((compared / "machining_summary.json").read_text())["chosen"]
    assert project.machining_settings.settings.controller == chosen["controller"]
    assert (project.cmrr is None) == (chosen["controller"] == "constant")
    assert project.status()["postprocess"] == "current"


@pytest.mark.slow
def test_offline_compensation_exports_the_corrected_program(tmp_path):
    profile = tmp_path / "stock.csv"
    profile.write_text("s_mm,allowance_mm\n0,0\n10,1.5\n200,2.5\n")
    out = tmp_path / "o"
    proc = robomach_here(
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
    assert "offline, planned from rehearsals of the fuzzy cut" in program
    plain = (block_demo_dir() / "program.mod").read_text()
    assert program.count("MoveL") > 5 * plain.count("MoveL")  # densified and corrected


@pytest.mark.slow
@pytest.mark.parametrize("stages", ["online", "planned"])
def test_a_comparison_says_what_the_other_stage_plan_cuts(tmp_path, stages):
    """With offline compensation in the matrix, the staged controllers' offline rows are cut
    with the other stage plan too, and the table and the summary say what it gives."""
    out = tmp_path / "o"
    proc = robomach_here(
        "machine", "--out", str(out), "--from", str(block_demo_dir()), "--controller", "all",
        "--compensation", "offline", "--stages", stages, "--no-plot",
    )  # fmt: skip
    assert proc.returncode == 0, proc.stderr
    other = "planned" if stages == "online" else "online"
    summary = json.loads((out / "machining_summary.json").read_text())
    for row in summary["runs"]:
        if row["controller"] in ("fuzzy", "two-stage"):
            assert row["feed"] == ("program" if stages == "planned" else "controller")
            assert row["other_stages"]["stages"] == other
            assert row["other_stages"]["feed"] == (
                "program" if other == "planned" else "controller"
            )
            assert row["other_stages"]["wall_error_max_mm"] >= 0.0
        else:
            assert "other_stages" not in row
    note = next(n for n in summary["notes"] if n.startswith(f"stages {other}: "))
    assert "fuzzy / offline" in note and "two-stage / offline" in note
    assert note in proc.stdout


@pytest.mark.slow
def test_planned_stages_export_the_schedule_as_the_feeds(tmp_path):
    """``--stages planned``: the fuzzy controller's offline row runs its stage schedule, the
    program carries it as its speeds with no FC SpeedChange, and the table and header say so."""
    out = tmp_path / "o"
    proc = robomach_here(
        "machine", "--out", str(out), "--from", str(block_demo_dir()), "--controller", "fuzzy",
        "--compensation", "offline", "--stages", "planned", "--no-plot",
    )  # fmt: skip
    assert proc.returncode == 0, proc.stderr
    summary = json.loads((out / "machining_summary.json").read_text())
    assert summary["runs"][0]["feed"] == "program"
    assert "schedule: fuzzy / offline run the stage schedule" in proc.stdout
    program = (out / "program.mod").read_text()
    assert "FCSpdChgAct" not in program
    assert "planned from rehearsals of its stage schedule's cut" in program
    refused = robomach_here("machine", "--out", str(out), "--stages", "sometimes")
    assert refused.returncode != 0 and "--stages" in refused.stderr


@pytest.mark.parametrize(
    ("args", "words"),
    [
        (["--force-limit-N", "0"], ["--force-limit-N", "1.5-1400 N"]),
        (["--variations", "-1"], ["--variations", "0-1000"]),
        (["--cell-options", "laser"], ["--cell-options", "laser", "fc_speed_change"]),
        (["--seed", "-1"], ["--seed"]),
        (["--from", "/nonexistent/demo"], ["--from", "no such folder"]),
        (["--from", "/tmp", "--workpiece", "block"], ["not both"]),
        (["--stock", "/nonexistent/stock.stl"], ["--stock", "no such file"]),
        (["--workpiece", "part.stl"], ["--workpiece", "guide points", "--from"]),
    ],
)
def test_bad_arguments_give_one_line_and_exit_2(tmp_path, args, words):
    _assert_one_line_error(robomach_here("machine", "--out", str(tmp_path / "o"), *args), *words)


def test_a_folder_without_a_project(tmp_path):
    (tmp_path / "demo").mkdir()
    proc = robomach_here("machine", "--out", str(tmp_path / "o"), "--from", str(tmp_path / "demo"))
    _assert_one_line_error(proc, "project.npz", "robomach demo")


def test_an_unwritable_out_is_refused_before_work():
    proc = robomach_here("machine", "--out", "/proc/robomach-machine", "--workpiece", "block")
    _assert_one_line_error(proc, "--out", "cannot write")


def test_help_lists_every_exit_code():
    proc = robomach_here("machine", "--help")
    assert proc.returncode == 0
    for code in ("0 ", "1 ", "2 ", "130"):
        assert f"\n  {code}" in proc.stdout, proc.stdout
    assert "--variations" in proc.stdout and "--cluster" in proc.stdout


@pytest.mark.slow
def test_exit_0_when_some_configurations_stop_and_the_stops_are_shown(tmp_path):
    """A comparison in which a configuration stops is a result: the two-stage controller on a
    casting whose allowance is far beyond anything its low stage allows for stops on its
    protection rule, the constant feed (designed for the deepest cut) finishes."""
    profile = tmp_path / "stock.csv"
    profile.write_text("s_mm,allowance_mm\n0,0\n5,1\n60,1\n62,12\n70,12\n72,1\n")
    out = tmp_path / "o"
    proc = robomach_here(
        "machine", "--out", str(out), "--from", str(block_demo_dir()), "--controller", "all",
        "--stock", str(profile), "--no-plot", "--workers", "1",
    )  # fmt: skip
    assert proc.returncode == 0, proc.stderr
    summary = json.loads((out / "machining_summary.json").read_text())
    stopped = [r for r in summary["runs"] if not r["completed"]]
    assert stopped, "the steep wall was meant to stop a controller"
    assert "stopped" in proc.stdout and all(r["controller"] in proc.stdout for r in stopped)
    assert summary["chosen"] is not None and (out / "program.mod").is_file()


@pytest.mark.slow
def test_exit_1_when_the_cell_can_run_nothing_that_completes(tmp_path):
    out = tmp_path / "o"
    proc = robomach_here(
        "machine", "--out", str(out), "--from", str(block_demo_dir()), "--controller",
        "adaptive-pi", "--cell-options", "none", "--no-plot", "--workers", "1",
    )  # fmt: skip
    assert proc.returncode == 1, proc.stderr
    assert "nothing to choose" in proc.stderr and "Traceback" not in proc.stderr
    summary = json.loads((out / "machining_summary.json").read_text())
    assert summary["chosen"] is None and summary["runs"][0]["runnable"] is False
    assert not (out / "program.mod").exists()  # nothing the cell can run is exported


@pytest.mark.slow
def test_exit_130_when_interrupted(tmp_path):
    import signal

    # As from a terminal: a suite started in the background (``cmd &``) ignores SIGINT, and a
    # child inherits that, so Python would install no KeyboardInterrupt handler at all.
    proc = subprocess.Popen(
        [sys.executable, "-m", "app.cli", "machine", "--out", str(tmp_path / "o"),
         "--workpiece", "block", "--no-plot"],
        stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True,
        preexec_fn=lambda: signal.signal(signal.SIGINT, signal.SIG_DFL),
    )  # fmt: skip
    # Interrupt while it works (path learning has begun), not after a fixed time: a fast
    # machine finished the block's whole run within 6 s.
    seen = []
    for line in proc.stderr:
        seen.append(line)
        if line.startswith("path learning:"):
            break
    assert proc.poll() is None, "".join(seen)
    proc.send_signal(signal.SIGINT)
    _, err = proc.communicate(timeout=120)
    err = "".join(seen) + err
    assert proc.returncode == 130, err
    assert "Traceback" not in err


@pytest.mark.slow
def test_variations_report_percentiles_and_choose_on_them(tmp_path):
    """The sweep cuts the nominal stock's program on three drawn stocks too: the percentiles
    count all four, and the constant feed designed for the nominal stock's deepest cut passes
    the limit on a harder or thicker casting, so nothing can be chosen (exit 1, the reason)."""
    out = tmp_path / "o"
    proc = robomach_here(
        "machine", "--out", str(out), "--from", str(block_demo_dir()), "--controller",
        "constant", "--compensation", "off", "--variations", "3", "--workers", "2", "--no-plot",
    )  # fmt: skip
    summary = json.loads((out / "machining_summary.json").read_text())
    (row,) = summary["runs"]
    assert row["stocks"] == 4 and row["completed_share"] == 1.0
    over = row["force_peak_p95_N"] > row["force_limit_N"]
    assert proc.returncode == (1 if over else 0), proc.stderr
    assert (summary["chosen"] is None) == over
    for key in ("cycle_time", "force_peak", "wall_error_max"):
        unit = {"cycle_time": "s", "force_peak": "N", "wall_error_max": "mm"}[key]
        assert row[f"{key}_p50_{unit}"] <= row[f"{key}_p95_{unit}"]
    variation = summary["variation"]
    assert variation["stocks"] == 4 and variation["drawn"] == 3
    assert "material K" in variation["ranges"]
    assert "95th percentiles" in summary["choice_reason"]


@pytest.mark.slow
def test_a_not_fit_program_is_shown_above_the_table_and_not_written(tmp_path):
    """A project whose learning stopped before its last guide point (a partial program): the
    comparison runs and is written, its problem is printed above the table, no program is
    written, and the exit code is 1 (issue 29)."""
    from dataclasses import replace

    from robomach_core import project as core

    project = load_project_file(block_demo_dir() / "project.npz")
    rec = replace(project.learned.recording, completed=False, stop_reason="stopped by the test")
    partial = replace(project, learned=replace(project.learned, recording=rec))
    demo = tmp_path / "demo"
    demo.mkdir()
    core.save_project_file(partial, demo / core.PROJECT_FILE)
    reopened = load_project_file(demo / core.PROJECT_FILE)
    assert reopened.status()["postprocess"] == "current" and reopened.processed.problems()
    out = tmp_path / "o"
    proc = robomach_here(
        "machine", "--out", str(out), "--from", str(demo), "--controller", "constant",
        "--compensation", "off", "--no-plot", "--workers", "1",
    )  # fmt: skip
    assert proc.returncode == 1, proc.stderr
    lines = proc.stdout.splitlines()
    first = next(k for k, line in enumerate(lines) if line.startswith("NOT FIT TO MACHINE"))
    header = next(k for k, line in enumerate(lines) if "controller" in line and "cycle" in line)
    assert first < header and "partial" in lines[first]
    assert "not fit to machine" in proc.stderr
    assert not (out / "program.mod").exists()
    summary = json.loads((out / "machining_summary.json").read_text())
    assert summary["problems"] and summary["runs"][0]["completed"]
