"""``robomach demo --language``: the registry's choices, each language's own arm, and a
language the arm's controller does not run refused before any learning."""

from __future__ import annotations

import pytest

from app.cli import main
from robomach_core.export.languages import default_arm as default_robot


def test_each_language_brings_its_own_arm():
    assert default_robot("auto") == "ur10"
    assert default_robot("rapid") == "irb4400"
    assert default_robot("urscript") == "ur10"
    assert default_robot("krl") == "kr270"


@pytest.mark.parametrize(
    ("robot", "language", "runs"),
    [("irb4400", "urscript", "rapid"), ("kr270", "rapid", "krl"), ("ur10", "krl", "rapid")],
)
def test_a_language_the_arm_does_not_run_is_refused_at_once(
    tmp_path, capsys, robot, language, runs
):
    code = main(["demo", "--robot", robot, "--language", language, "--out", str(tmp_path)])
    assert code == 2
    lines = capsys.readouterr().err.strip().splitlines()
    err = lines[-1]
    assert err.startswith("robomach demo: error:")
    assert f"the {robot} arm's controller does not run" in err and runs in err
    # No stage began (each prints "stage: N %" to stderr): no lead-through, no learning.
    assert not [line for line in lines if line.endswith("%")], lines
    assert not (tmp_path / "summary.json").exists()
