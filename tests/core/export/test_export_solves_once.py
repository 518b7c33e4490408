"""An export solves each program target's inverse kinematics once (issue 17: 5-7 times before),
for every program, its force-controlled variant, the offline compensation and targets.csv."""

from __future__ import annotations

from dataclasses import replace

import pytest

from robomach_core import project as core
from robomach_core.cell import Robot
from tests.core.project.test_project import _compensation, processed  # noqa: F401 (the fixture)


@pytest.mark.parametrize("compensated", [False, True], ids=["plain", "offline-compensated"])
def test_program_files_solve_each_target_once(processed, monkeypatch, compensated):  # noqa: F811
    project, workpiece = processed
    if compensated:
        project = replace(project, compensation=_compensation())
    calls = []
    solve = Robot.ik

    def counted_ik(self, *args, **kwargs):
        calls.append(args[0])
        return solve(self, *args, **kwargs)

    monkeypatch.setattr(Robot, "ik", counted_ik)
    files = core.program_files(project, workpiece, robot=Robot("ur10"), project_name="p")
    targets = len(project.processed.result.targets)
    assert {"program.mod", "program_fc.mod", "program.script", "targets.csv"} <= set(files)
    assert len(calls) == targets
