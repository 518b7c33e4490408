"""``robomach compensate``: the CLI over the compensation studies."""

from __future__ import annotations

import json

import pytest

from app.cli import main

REQUIRED_KEYS = (
    "stiffness_rel_error_max",
    "prediction_error_max_mm",
    "gravity_residual_max_N",
    "error_max_uncompensated_um",
    "error_max_compensated_linear_um",
    "error_max_compensated_nonlinear_um",
    "error_std_uncompensated_um",
    "error_std_compensated_um",
    "ilc_arm_error_per_iteration",
    "ilc_force_error_per_iteration",
)


@pytest.mark.slow  # every study, with plots
def test_all_quick_writes_summary_plots_and_settings(tmp_path, capsys):
    out = tmp_path / "comp"
    assert main(["compensate", "--quick", "--out", str(out), "--seed", "1"]) == 0
    summary = json.loads((out / "compensation_summary.json").read_text())
    for key in REQUIRED_KEYS:
        assert key in summary, key
    assert (out / "compensation_settings.json").exists()
    assert {p.name for p in out.glob("*.png")} >= {
        "identification.png",
        "milling_chapter.png",
        "ilc.png",
        "gravity.png",
    }
    assert list(out.glob("*.csv"))
    captured = capsys.readouterr()
    assert "end milling" in captured.out
    assert "compensate all" in captured.err  # progress on the terminal


def test_single_study_writes_only_its_outputs(tmp_path):
    out = tmp_path / "g"
    assert main(["compensate", "--study", "gravity", "--out", str(out)]) == 0
    summary = json.loads((out / "compensation_summary.json").read_text())
    assert summary["studies"] == ["gravity"]
    assert "gravity_residual_max_N" in summary
    assert not (out / "compensation_settings.json").exists()


@pytest.mark.parametrize(
    "argv",
    [
        ["--cmm-noise", "-5"],
        ["--poses", "1"],
        ["--iterations", "-1"],
        ["--robot", "ur99", "--study", "identify"],
    ],
)
def test_user_errors_exit_2_with_one_line(tmp_path, capsys, argv):
    assert main(["compensate", "--out", str(tmp_path / "x"), *argv]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert err[-1].startswith("robomach compensate: error:")


def test_unknown_study_is_an_argparse_error(tmp_path):
    with pytest.raises(SystemExit) as exc:
        main(["compensate", "--study", "chatter", "--out", str(tmp_path)])
    assert exc.value.code == 2
