"""Compensation settings JSON and the compensated RAPID program."""

from __future__ import annotations

import json

import numpy as np
import pytest

from robomach_core.cell import Tool, ToolGravity
from robomach_core.export.rapid import rapid_module
from robomach_core.export.rapid_check import check_rapid_module
from robomach_core.stiffness.errors import SettingsFileError
from robomach_core.stiffness.export import compensated_rapid_program
from robomach_core.stiffness.settings import (
    CompensationSettings,
    load_settings,
    save_settings,
    settings_from_dict,
    settings_to_dict,
)
from robomach_core.transforms import make_transform

SETTINGS = CompensationSettings(
    robot="ur10",
    joint_stiffness_Nm_rad=(1.1e6, 1.0e6, 7.2e5, 2.4e5, 2.6e5, 1.9e5),
    mode="online",
    joint_stiffness_std_Nm_rad=(1e4, 1e4, 1e4, 5e3, 5e3, 2e4),
    tool_gravity=ToolGravity(2.5, (0.0, 0.001, 0.07), (1.0, -2.0, 0.5), (0.01, 0.0, -0.02)),
)


def test_round_trip_through_a_file(tmp_path):
    path = save_settings(SETTINGS, tmp_path / "settings.json")
    back = load_settings(path)
    assert back.mode == SETTINGS.mode
    np.testing.assert_allclose(back.joint_stiffness_Nm_rad, SETTINGS.joint_stiffness_Nm_rad)
    np.testing.assert_allclose(back.tool_gravity.com_m, SETTINGS.tool_gravity.com_m)
    np.testing.assert_allclose(back.tool_gravity.force_bias_N, SETTINGS.tool_gravity.force_bias_N)
    assert json.loads(path.read_text())["tool"]["com_mm"][2] == pytest.approx(70.0)


@pytest.mark.parametrize(
    "change",
    [
        {"format": "other"},
        {"version": 99},
        {"mode": "sometimes"},
        {"joint_stiffness_Nm_rad": [1, 2, 3]},
        {"joint_stiffness_Nm_rad": [1, 2, 3, 4, 5, -6]},
        {"force_filter_cutoff_hz": 0},
    ],
)
def test_malformed_settings_are_refused(change):
    data = settings_to_dict(SETTINGS) | change
    with pytest.raises(SettingsFileError):
        settings_from_dict(data)


def test_missing_and_broken_files_are_refused(tmp_path):
    with pytest.raises(SettingsFileError):
        load_settings(tmp_path / "absent.json")
    broken = tmp_path / "broken.json"
    broken.write_text("{not json")
    with pytest.raises(SettingsFileError):
        load_settings(broken)


def test_online_without_tool_gravity_is_refused():
    with pytest.raises(SettingsFileError):
        CompensationSettings("ur10", SETTINGS.joint_stiffness_Nm_rad, mode="online")


def test_compensated_program_parses_and_moves_targets_against_the_load(robot, truth):
    R = np.diag([1.0, -1.0, -1.0])
    Ts = np.array([make_transform(R, [0.70 + 0.01 * i, 0.10, 0.03]) for i in range(4)])
    q = robot.ik(Ts[0])
    joints = []
    for T in Ts:
        q = robot.ik(T, q)
        joints.append(q)
    W = np.tile([0.0, 0.0, -400.0, 0.0, 0.0, 0.0], (4, 1))  # pushes the tool down
    program = compensated_rapid_program(
        robot, Tool(), Ts, np.array(joints), W, truth, "linear", speed_mm_s=20.0
    )
    info = check_rapid_module(rapid_module(program))
    assert len(info.robtargets) >= 4
    z_mm = [t.T_wobj_target[2, 3] * 1e3 for t in program.targets]
    assert all(z > 30.0 for z in z_mm)  # raised to meet a downward push
