"""``robomach cmrr`` end to end: files written, their columns and keys, user errors."""

from __future__ import annotations

import csv
import json

from app.cli import main

SUMMARY_KEYS = {
    "controller",
    "scenario",
    "stable",
    "peak_force_N",
    "force_rms_error_N",
    "cycle_time_s",
    "baseline_cycle_time_s",
}
CSV_COLUMNS = {
    "time_s",
    "depth_mm",
    "commanded_feed_mm_s",
    "actual_feed_mm_s",
    "speed_ratio",
    "measured_force_N",
    "reference_force_N",
}


def test_one_controller_writes_csv_summary_plot_and_settings(tmp_path, capsys):
    out = tmp_path / "run"
    code = main(
        ["cmrr", "--scenario", "milling-steps", "--controller", "fixed-pi", "--out", str(out)]
    )
    assert code == 0
    summary = json.loads((out / "cmrr_summary.json").read_text())
    assert SUMMARY_KEYS <= set(summary)
    assert summary["controller"] == "fixed-pi" and summary["scenario"] == "milling-steps"
    assert summary["stable"] is False  # the paper's 3 mm instability
    with (out / "cmrr.csv").open() as fh:
        rows = list(csv.DictReader(fh))
    assert CSV_COLUMNS <= set(rows[0])
    assert float(rows[-1]["time_s"]) > 5.0
    assert (out / "cmrr.png").stat().st_size > 10_000
    settings = json.loads((out / "cmrr_settings.json").read_text())
    assert settings["controller"] == "fixed-pi" and settings["reference_force_N"] == 250.0
    assert "fixed-pi" in capsys.readouterr().out


def test_all_controllers_compare_in_one_table_and_the_settings_file_replays(tmp_path, capsys):
    out = tmp_path / "all"
    assert (
        main(["cmrr", "--scenario", "deburr-burrs", "--controller", "all", "--out", str(out)]) == 0
    )
    summary = json.loads((out / "cmrr_summary.json").read_text())
    names = [r["controller"] for r in summary["results"]]
    assert names == ["constant", "fixed-pi", "adaptive-pi", "fuzzy", "two-stage", "adaptive-lq"]
    table = capsys.readouterr().out
    assert all(name in table for name in names)
    with (out / "cmrr.csv").open() as fh:
        assert {row["controller"] for row in csv.DictReader(fh)} == set(names)
    # Replay the two-stage settings from its exported JSON, at another reference.
    entry = json.loads((out / "cmrr_settings.json").read_text())[names.index("two-stage")]
    settings_file = tmp_path / "two_stage.json"
    settings_file.write_text(json.dumps(entry))
    replay = tmp_path / "replay"
    code = main(
        [
            "cmrr",
            "--scenario",
            "deburr-burrs",
            "--settings",
            str(settings_file),
            "--reference-force-N",
            "180",
            "--out",
            str(replay),
            "--quiet",
        ]
    )
    assert code == 0
    replayed = json.loads((replay / "cmrr_summary.json").read_text())
    assert replayed["controller"] == "two-stage" and replayed["reference_force_N"] == 180.0


def test_user_errors_exit_2_with_one_line(tmp_path, capsys):
    bad = tmp_path / "bad.json"
    bad.write_text("{not json")
    code = main(["cmrr", "--scenario", "lund-df", "--settings", str(bad), "--out", str(tmp_path)])
    assert code == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and err[0].startswith("robomach cmrr: error:")
    code = main(
        ["cmrr", "--scenario", "lund-df", "--reference-force-N", "-3", "--out", str(tmp_path)]
    )
    assert code == 2
