"""An uploaded URDF with a built-in arm's kinematics is that arm (a UR5 gets URScript); the
user may name the controller instead; a new arm is taken for an ABB's, as before."""

from __future__ import annotations

import shutil
from pathlib import Path

import numpy as np
import pytest

from robomach_core.cell import Robot, program_language, robots_directory
from robomach_core.project import program_languages
from robomach_core.robots import abb, custom, registry
from robomach_core.robots.custom import RobotFileError, register_urdf
from robomach_core.robots.recognise import recognise_arm
from robomach_core.robots.registry import arm


@pytest.fixture(scope="module")
def ur5_file(tmp_path_factory) -> Path:
    """ur5_robot.urdf copied out of example-robot-data, as a user would."""
    source = robots_directory() / "ur_description/urdf/ur5_robot.urdf"
    return Path(shutil.copy(source, tmp_path_factory.mktemp("upload") / "my_ur5.urdf"))


def test_a_ur5_copied_out_of_example_robot_data_is_a_ur5_and_gets_urscript(ur5_file):
    name = register_urdf(ur5_file.name, ur5_file.read_bytes())
    assert name.startswith("urdf_my_ur5_")
    robot = Robot(name)
    assert robot.family == "ur" and program_language(name) == "urscript"
    assert "urscript" in program_languages(robot)
    assert "krl" not in program_languages(robot)
    # the built-in UR5's placement, home and stiffness, which learn the pump (robots.registry)
    assert arm(name).part_position_m == arm("ur5").part_position_m
    np.testing.assert_allclose(arm(name).home_rad, arm("ur5").home_rad)
    assert arm(name).stiffness_Nm_rad == arm("ur5").stiffness_Nm_rad


def test_recognition_compares_the_axes_not_the_names():
    ur5 = Robot("ur5").model
    assert recognise_arm(ur5) == "ur5"
    assert recognise_arm(Robot("ur10").model) == "ur10"
    assert recognise_arm(Robot("kr270").model) == "kr270"
    # the IRB 4400 with a forearm 10 cm longer is no built-in arm
    longer = abb.urdf_text(abb.ABB_ARMS["irb4400"]).replace(
        '<origin xyz="0.88 0 0" rpy="0 0 0"/><axis xyz="0 1 0"/>',
        '<origin xyz="0.98 0 0" rpy="0 0 0"/><axis xyz="0 1 0"/>',
    )
    assert longer != abb.urdf_text(abb.ABB_ARMS["irb4400"])
    name = register_urdf("longer_4400.urdf", longer.encode())
    assert Robot(name).family == "abb" and program_language(name) == "rapid"
    assert recognise_arm(Robot(name).model) is None


def test_the_user_names_the_controller_and_the_choice_is_in_the_name(ur5_file):
    text = abb.urdf_text(abb.ABB_ARMS["irb6640"]).replace('name="irb6640"', 'name="cell_7"')
    base = register_urdf("cell_7.urdf", text.encode())
    assert Robot(base).family == "abb"  # an IRB 6640's kinematics
    kuka = register_urdf("cell_7.urdf", text.encode(), family="kuka")
    assert kuka == f"{base}_kuka"
    robot = Robot(kuka)
    assert robot.family == "kuka" and program_languages(robot) == ("krl",)
    # a restart registers the file again under its plain name; the chosen one comes back
    registry.forget(kuka)
    assert custom.is_custom(kuka) and Robot(kuka).family == "kuka"
    with pytest.raises(RobotFileError, match="unknown controller family"):
        register_urdf("cell_7.urdf", text.encode(), family="fanuc")
