"""A project on the user's own arm (a URDF file) round-trips through ``project.npz``.

The file keeps the arm's URDF beside the mesh; a new process knows only the built-in arms, so
loading it registers the arm again (``project._file.register_robot_file``). ``robomach machine
--from`` and ``POST /api/projects/import`` read the file this way; before, they could not open
such a project at all.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from app.cli import main as robomach
from app.session import Session
from robomach_core import project as core
from robomach_core.cell.robot import robot_urdf_path
from robomach_core.robots import custom, registry
from tests.generated_parts import PARTS


def _custom_arm_demo(tmp_path: Path) -> tuple[Path, core.Project]:
    urdf = tmp_path / "my_arm.urdf"
    urdf.write_bytes(robot_urdf_path("ur10").read_bytes())
    part = PARTS["slotted_plate"]()
    stl = tmp_path / "slotted_plate.stl"
    stl.write_bytes(part.stl_bytes())
    x, y, z = part.picks["right side"]
    out = tmp_path / "demo"
    code = robomach(
        ["demo", "--out", str(out), "--robot", str(urdf), "--workpiece", str(stl),
         f"--propose-guide-points={x},{y},{z}", "--speed", "20", "--no-plot"]
    )  # fmt: skip
    assert code == 0
    return out, core.load_project_file(out / core.PROJECT_FILE)


def _same(a: core.Project, b: core.Project) -> None:
    assert a.cell == b.cell and a.mesh == b.mesh and a.robot_urdf == b.robot_urdf
    np.testing.assert_allclose(
        a.learned.recording.position_m, b.learned.recording.position_m, atol=1e-12
    )
    np.testing.assert_allclose(
        a.processed.result.targets.position_m, b.processed.result.targets.position_m, atol=1e-12
    )
    assert a.status() == b.status()


def test_a_custom_arm_project_round_trips_through_its_file(tmp_path) -> None:
    out, saved = _custom_arm_demo(tmp_path)
    arm = saved.cell.robot
    assert arm.startswith("urdf_my_arm_") and saved.robot_urdf is not None
    assert saved.robot_urdf[1] == (tmp_path / "my_arm.urdf").read_bytes()
    assert saved.status()["postprocess"] == "current"
    program = (out / "program.urscript").read_text() if (out / "program.urscript").exists() \
        else None  # fmt: skip

    registry.forget(arm)  # as in a new process: the arm is unknown
    assert not custom.is_custom(arm)
    reloaded = core.load_project_file(out / core.PROJECT_FILE)  # what machine --from does
    assert custom.is_custom(arm)
    _same(reloaded, saved)
    assert core.project_from_file_bytes(core.project_file_bytes(reloaded)).robot_urdf == (
        saved.robot_urdf
    )

    registry.forget(arm)
    session = Session(real_time=False)  # what POST /api/projects/import does
    try:
        session.projects.import_project((out / core.PROJECT_FILE).read_bytes(), "my arm")
        assert session.robot.cell.robot.name == arm
        _same(session.project(), saved)
        if program is not None:
            assert session.programs.program_texts("urscript")["program.urscript"] == program
        again = core.project_from_file_bytes(session.projects.export_project())
        _same(again, saved)
    finally:
        session.close()


def test_a_file_whose_arm_is_not_the_one_it_names_is_refused(tmp_path) -> None:
    out, saved = _custom_arm_demo(tmp_path)
    other = robot_urdf_path("ur5").read_bytes()
    tampered = core.project_file_bytes(
        core.Project(cell=saved.cell, mesh=saved.mesh, robot_urdf=("my_arm.urdf", other))
    )
    with pytest.raises(core.ProjectFileError, match="the project.s arm is"):
        core.project_from_file_bytes(tampered)


def test_switching_between_two_uploaded_arms_keeps_each_arms_own_file(tmp_path) -> None:
    """Upload arm A, then arm B, then choose A again by name (``set_cell``): the project must
    carry A's file, not B's, or the saved project cannot be opened again."""
    a_bytes = robot_urdf_path("ur10").read_bytes()
    b_bytes = robot_urdf_path("ur5").read_bytes()
    session = Session(real_time=False)
    try:
        a = session.upload_robot(a_bytes, "arm_a.urdf").robot
        b = session.upload_robot(b_bytes, "arm_b.urdf").robot
        assert session.project().robot_urdf == ("arm_b.urdf", b_bytes) and a != b
        session.set_cell(robot=a)
        assert session.project().cell.robot == a
        assert session.project().robot_urdf == ("arm_a.urdf", a_bytes)
        reopened = core.project_from_file_bytes(session.projects.export_project())
        assert reopened.cell.robot == a and reopened.robot_urdf == ("arm_a.urdf", a_bytes)
        session.set_cell(robot="ur10")  # a built-in arm carries no file
        assert session.project().robot_urdf is None
    finally:
        session.close()
