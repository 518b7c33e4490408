"""``robomach demo`` end to end, and its answers to bad input."""

from __future__ import annotations

import json
import math
import subprocess
from pathlib import Path

import numpy as np
import pytest
import trimesh

from robomach_core.export import check_rapid_module
from tests.cli import robomach_here
from tests.demo_project import block_demo_dir
from tests.demo_project import pump_demo as shared_pump_demo


def _assert_one_line_error(proc: subprocess.CompletedProcess, *words: str) -> None:
    assert proc.returncode == 2, proc.stderr
    assert "Traceback" not in proc.stderr
    lines = [line for line in proc.stderr.splitlines() if "error" in line]
    assert len(lines) == 1, proc.stderr
    for w in words:
        assert w in lines[0], lines[0]


@pytest.mark.parametrize(
    ("args", "words"),
    [
        (["--tolerance", "0"], ["tolerance", "0.01-5 mm"]),
        (["--tolerance", "-0.1"], ["tolerance"]),
        (["--force", "60"], ["--force", "1-50 N"]),
        (["--force", "0.5"], ["--force"]),
        (["--workpiece", "gearbox"], ["unknown workpiece", "water_pump"]),
        (["--robot", "kuka"], ["unknown robot"]),
    ],
)
def test_bad_arguments_give_one_line_and_exit_2(tmp_path, args, words):
    _assert_one_line_error(robomach_here("demo", "--out", str(tmp_path / "o"), *args), *words)


def test_a_file_that_is_not_a_mesh(tmp_path):
    bad = tmp_path / "part.stl"
    bad.write_bytes(b"\x00\x01 definitely not an STL")
    _assert_one_line_error(
        robomach_here("demo", "--out", str(tmp_path / "o"), "--workpiece", str(bad)), "part"
    )


def test_fewer_than_two_guide_points(tmp_path):
    csv = tmp_path / "guides.csv"
    csv.write_text("x_mm,y_mm,z_mm\n700,100,40\n")
    _assert_one_line_error(
        robomach_here("demo", "--out", str(tmp_path / "o"), "--guide-points", str(csv)),
        "at least 2 guide points",
    )


def test_an_unreachable_guide_point(tmp_path):
    csv = tmp_path / "guides.csv"
    csv.write_text("x_mm,y_mm,z_mm\n700,100,40\n4000,0,40\n")
    _assert_one_line_error(
        robomach_here("demo", "--out", str(tmp_path / "o"), "--guide-points", str(csv)),
        "guide point 2",
        "reach",
    )


@pytest.fixture(scope="module")
def pump_demo() -> Path:
    """The README's demo, run once for the whole test run (tests/demo_project.py)."""
    return shared_pump_demo().folder


@pytest.mark.slow
def test_demo_writes_every_file_with_the_summary_keys(pump_demo):
    for name in (
        "program.mod",
        "samples.csv",
        "targets.csv",
        "workpiece.stl",
        "summary.json",
        "demo.png",
        "project.npz",
    ):
        assert (pump_demo / name).stat().st_size > 0, name
    summary = json.loads((pump_demo / "summary.json").read_text())
    for key in (
        "guide_points",
        "samples_raw",
        "samples_filtered",
        "targets",
        "sample_period_s",
        "force_setpoint_N",
        "force_mean_N",
        "force_abs_error_p95_N",
        "tool_radius_mm",
        "max_deviation_mm",
        "rms_deviation_mm",
        "sim_time_s",
        "wall_time_s",
        "realtime_factor",
    ):
        assert key in summary, key
    assert summary["sample_period_s"] == 0.004


@pytest.mark.slow
def test_demo_meets_the_papers_figures(pump_demo):
    """Thousands of 4 ms samples -> low hundreds of targets at 0.2 mm; force within 2 N."""
    s = json.loads((pump_demo / "summary.json").read_text())
    assert s["guide_points"] >= 6
    assert s["completed"] is True
    assert s["samples_raw"] >= 2000
    assert 100 <= s["targets"] <= 400
    assert s["force_within_2N_fraction"] >= 0.95
    assert s["max_deviation_mm"] <= 0.3
    # The deviation-height chords sit up to the tolerance off the samples; along a chord the
    # error ramps from 0 to the tolerance, so the RMS is about tolerance / sqrt(3).
    assert s["rms_deviation_mm"] <= s["tolerance_mm"] / math.sqrt(3) + 0.01
    assert s["targets_max_deviation_mm"] <= 0.1


@pytest.mark.slow
def test_program_parses_and_every_robtarget_is_reachable(pump_demo):
    s = json.loads((pump_demo / "summary.json").read_text())
    info = check_rapid_module((pump_demo / "program.mod").read_text())
    assert len(info.robtargets) == s["targets"] + 2  # plus approach and retract
    assert s["robtargets_reachable"] == s["robtargets_total"] == len(info.robtargets)
    check_rapid_module((pump_demo / "program_fc.mod").read_text())


@pytest.mark.slow
def test_csv_and_stl_are_in_the_documented_units_and_frame(pump_demo):
    header = (pump_demo / "samples.csv").read_text().splitlines()[0].split(",")
    assert header[0] == "time_s" and "x_mm" in header and "sensor_fx_N" in header
    data = np.loadtxt(pump_demo / "samples.csv", delimiter=",", skiprows=1)
    s = json.loads((pump_demo / "summary.json").read_text())
    assert len(data) == s["samples_raw"]
    np.testing.assert_allclose(np.diff(data[:, 0]), 0.004, atol=1e-3)
    mesh = trimesh.load(pump_demo / "workpiece.stl")
    # The pump plate sits 0.8 m in front of the base: metres, base frame.
    assert 0.6 < mesh.bounds[0, 0] < 0.8 and mesh.bounds[1, 0] < 1.0
    x_mm = data[:, header.index("x_mm")]
    assert mesh.bounds[0, 0] * 1e3 < x_mm.min() and x_mm.max() < mesh.bounds[1, 0] * 1e3


@pytest.mark.slow
def test_same_seed_same_output(tmp_path):
    """A second block demo, in this process, against the run's shared one, a process of its own
    (same arguments, seed 0)."""
    out = tmp_path / "again"
    proc = robomach_here("demo", "--out", str(out), "--workpiece", "block", "--no-plot")
    assert proc.returncode == 0, proc.stderr
    for name in ("program.mod", "samples.csv", "targets.csv"):
        assert (block_demo_dir() / name).read_bytes() == (out / name).read_bytes(), name


@pytest.mark.slow
def test_demo_exports_cmrr_speed_change_and_compensated_targets(tmp_path):
    from robomach_core.cell.joint_compliance import TRUE_JOINT_STIFFNESS_NM_RAD
    from robomach_core.cmrr import build_scenario, cmrr_settings_for, save_settings, settings_for
    from robomach_core.stiffness import CompensationSettings
    from robomach_core.stiffness import save_settings as save_compensation

    cmrr_json = save_settings(
        cmrr_settings_for(build_scenario("deburr-burrs"), settings_for("two-stage")),
        tmp_path / "cmrr.json",
    )
    comp_json = save_compensation(
        CompensationSettings("ur10", TRUE_JOINT_STIFFNESS_NM_RAD["ur10"], mode="offline"),
        tmp_path / "comp.json",
    )
    out = tmp_path / "out"
    proc = robomach_here(
        "demo",
        "--out",
        str(out),
        "--workpiece",
        "block",
        "--no-plot",
        "--cmrr-settings",
        str(cmrr_json),
        "--compensation-settings",
        str(comp_json),
    )
    assert proc.returncode == 0, proc.stderr
    text = (out / "program.mod").read_text()
    check_rapid_module(text)
    assert "FCSpdChgAct" in text and "FCSpdChgDeact" in text
    correction = float(text.split("largest target correction ")[1].split(" mm")[0])
    assert 0.0 < correction < 0.1  # a 10 N contact on a ~1 N/um arm: micrometres
    settings = json.loads((out / "settings.json").read_text())
    assert settings["cmrr"]["controller"] == "two-stage"
    assert settings["compensation"]["mode"] == "offline"
    assert settings["compensation"]["offline_model"] == "linear"


def test_settings_files_are_validated(tmp_path):
    bad = tmp_path / "cmrr.json"
    bad.write_text("[1, 2]")
    _assert_one_line_error(
        robomach_here("demo", "--out", str(tmp_path / "o"), "--cmrr-settings", str(bad)), "CMRR"
    )
    _assert_one_line_error(
        robomach_here(
            "demo",
            "--out",
            str(tmp_path / "o"),
            "--compensation-settings",
            str(tmp_path / "missing.json"),
        ),
        "does not exist",
    )


def test_bad_or_unreachable_work_object(tmp_path):
    _assert_one_line_error(
        robomach_here("demo", "--out", str(tmp_path / "o"), "--wobj", "800,abc,0"), "--wobj"
    )
    _assert_one_line_error(
        robomach_here("demo", "--out", str(tmp_path / "o"), "--wobj", "800,160"), "x,y,z"
    )


@pytest.mark.slow
def test_demo_writes_the_cad_only_program_it_scored(pump_demo):
    """The CAD-only program is written beside the learned one (issue 31: it was scored but
    never written), in the same languages, and read back it is the program the comparison
    scored: its targets are the comparison's CAD positions."""
    from robomach_core.export.read_back import read_program
    from robomach_core.project import load_project_file

    folder = pump_demo / "cad_only"
    project = load_project_file(pump_demo / "project.npz")
    cad = np.asarray(project.processed.cad_comparison.cad_positions_m)
    for language, suffix in (("rapid", ".mod"), ("urscript", ".script")):
        files = {p.name: p.read_text() for p in folder.glob(f"*{suffix}")}
        assert files, f"no CAD-only {language} program in {sorted(folder.iterdir())}"
        path = read_program(language, files)
        assert len(path) == len(cad)
        assert np.abs(path.position_m - cad).max() < 1e-6, language
