"""The study runners a CLI, a GUI panel or a REST job calls."""

from __future__ import annotations

import json

import numpy as np
import pytest

from robomach_core.errors import CancelledError
from robomach_core.export.rapid_check import check_rapid_module
from robomach_core.stiffness.errors import UnknownStudyError
from robomach_core.stiffness.settings import load_settings
from robomach_core.stiffness.studies import (
    RAPID_FILE,
    SETTINGS_FILE,
    SUMMARY_FILE,
    StudyOptions,
    run_gravity_study,
    run_studies,
)

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


@pytest.fixture(scope="module")
def all_studies(tmp_path_factory):
    out = tmp_path_factory.mktemp("compensation")
    fractions: list[float] = []
    results = run_studies(
        "all", out, StudyOptions(quick=True, rapid=True, seed=3), progress=fractions.append
    )
    return out, results, fractions


def test_all_writes_summary_with_required_keys(all_studies):
    out, _, _ = all_studies
    summary = json.loads((out / SUMMARY_FILE).read_text())
    for key in REQUIRED_KEYS:
        assert key in summary, key
    assert len(summary["ilc_arm_error_per_iteration"]) >= 2


def test_compensation_lowers_the_milling_error(all_studies):
    _, results, _ = all_studies
    s = results["milling"].summary
    assert s["error_max_compensated_linear_um"] < 0.5 * s["error_max_uncompensated_um"]
    assert s["error_max_compensated_nonlinear_um"] < 0.5 * s["error_max_uncompensated_um"]
    assert s["face_error_max_compensated_um"] < s["face_error_max_uncompensated_um"]


def test_ilc_learns(all_studies):
    _, results, _ = all_studies
    s = results["ilc"].summary
    assert s["ilc_arm_error_per_iteration"][-1] < 0.5 * s["ilc_arm_error_per_iteration"][0]
    # The force ILC keeps the calibration offset: it ends above the arm-side ILC.
    assert s["ilc_force_error_per_iteration"][-1] > s["ilc_arm_error_per_iteration"][-1]


def test_files_plots_settings_and_rapid(all_studies):
    out, results, _ = all_studies
    for result in results.values():
        assert result.files
        for path in result.files:
            assert path.exists() and path.stat().st_size > 0
    assert any(p.suffix == ".png" for r in results.values() for p in r.files)
    settings = load_settings(out / SETTINGS_FILE)
    identified = results["identify"].summary["stiffness_identified_Nm_rad"]
    np.testing.assert_allclose(settings.joint_stiffness_Nm_rad, identified)
    assert settings.tool_gravity is not None
    check_rapid_module((out / RAPID_FILE).read_text())


def test_progress_runs_from_zero_to_one(all_studies):
    _, _, fractions = all_studies
    assert fractions[-1] == pytest.approx(1.0)
    assert all(0.0 <= f <= 1.0 for f in fractions)
    assert all(b >= a - 1e-12 for a, b in zip(fractions, fractions[1:], strict=False))


def test_arrays_without_a_folder():
    result = run_gravity_study(StudyOptions(quick=True))
    assert result.files == ()
    assert result.arrays["residual_N"].shape == (50,)
    assert result.summary["gravity_residual_max_N"] < 2.0


def test_cancel_stops_a_study():
    with pytest.raises(CancelledError):
        run_studies("ilc", None, StudyOptions(quick=True), cancel=lambda: True)


def test_unknown_study_is_refused():
    with pytest.raises(UnknownStudyError):
        run_studies("chatter")  # type: ignore[arg-type]
