"""The compliance paper's KR 270 line (section 6): the compensation leaves the paper's ratio."""

from __future__ import annotations

import pytest

from robomach_core.stiffness.studies import StudyOptions, run_compliance_study
from robomach_core.stiffness.studies._compliance import (
    PAPER_MAX_RATIO,
    PAPER_STATIC_UNCOMPENSATED_UM,
    RATIO_TOLERANCE,
)


@pytest.fixture(scope="module")
def study(tmp_path_factory):
    out = tmp_path_factory.mktemp("compliance")
    # --robot names another arm: the compliance study stays on the paper's KR 270
    return out, run_compliance_study(StudyOptions(robot="ur10", quick=True), out)


def test_it_runs_on_the_kr270_from_table_1(study):
    _, result = study
    s = result.summary
    assert s["compliance_robot"] == "kr270"
    assert s["compliance_pose_deg"] == [90.0, -50.0, 120.0, 180.0, 25.0, 180.0]
    assert s["compliance_joint_compliance_1e6_rad_Nm"] == pytest.approx(
        [0.26, 0.15, 0.26, 1.79, 1.52, 2.13]
    )


def test_the_compensated_ratio_is_the_papers_within_the_documented_tolerance(study):
    """docs/compensation.md: within 0.01 of 4.70 / 63.2; the static part removed."""
    _, result = study
    s = result.summary
    assert abs(s["compliance_max_ratio"] - PAPER_MAX_RATIO) <= RATIO_TOLERANCE
    assert s["compliance_static_uncompensated_um"] == pytest.approx(
        PAPER_STATIC_UNCOMPENSATED_UM, rel=0.05
    )
    assert abs(s["compliance_static_compensated_um"]) < 0.5  # paper: 0.14 um
    # the identified stiffness compensates almost as well: joints 1-5 within a few per cent
    assert s["compliance_max_ratio"] < s["compliance_max_ratio_identified"] < 0.2


def test_it_writes_the_csv_and_the_figure(study):
    out, result = study
    names = {p.name for p in result.files}
    assert names == {"compliance_paper_line.csv", "compliance_paper.png"}
    assert all((out / n).stat().st_size > 0 for n in names)
