"""Joint-stiffness identification from simulated CMM measurements (chapter 5.2, eq. 23)."""

from __future__ import annotations

import numpy as np
import pytest

from robomach_core.joint_compliance import JointCompliance
from robomach_core.robot import Robot
from robomach_core.stiffness.errors import IdentificationError
from robomach_core.stiffness.identification import (
    StiffnessMeasurements,
    identify_joint_stiffness,
    prediction_errors,
    sample_workspace_joints,
    simulate_stiffness_measurements,
    sphere_tip_transform,
)

from .conftest import CHAPTER_WRENCH


@pytest.fixture(scope="module")
def tip_robot() -> Robot:
    return Robot("ur10", sphere_tip_transform())


@pytest.fixture(scope="module")
def poses(tip_robot) -> np.ndarray:
    return sample_workspace_joints(tip_robot, 30, seed=3)


def test_noise_free_linear_data_recover_kq_exactly(tip_robot, poses, truth):
    data = simulate_stiffness_measurements(
        tip_robot, poses, truth, cmm_noise_m=0.0, force_noise_N=0.0, nonlinear=False
    )
    result = identify_joint_stiffness(tip_robot, data)
    np.testing.assert_allclose(result.model.stiffness_Nm_rad, truth.stiffness_Nm_rad, rtol=1e-8)
    assert result.residual_rms_m < 1e-12


def test_noise_free_nonlinear_data_recover_kq_within_a_percent(tip_robot, poses, truth):
    """The linear regressor misses only the tiny change of geometry under the loads."""
    data = simulate_stiffness_measurements(
        tip_robot, poses, truth, cmm_noise_m=0.0, force_noise_N=0.0
    )
    result = identify_joint_stiffness(tip_robot, data)
    np.testing.assert_allclose(result.model.stiffness_Nm_rad, truth.stiffness_Nm_rad, rtol=0.01)


@pytest.mark.parametrize("seed", [0, 1])
def test_cmm_noise_gives_errors_within_the_stated_uncertainty(tip_robot, poses, truth, seed):
    """20 um CMM noise: each joint within 4 standard errors; the arm joints within 15 %."""
    data = simulate_stiffness_measurements(tip_robot, poses, truth, cmm_noise_m=20e-6, seed=seed)
    result = identify_joint_stiffness(tip_robot, data)
    k = np.array(result.model.stiffness_Nm_rad)
    k_true = np.array(truth.stiffness_Nm_rad)
    assert np.all(np.abs(k - k_true) <= 4 * result.standard_error_Nm_rad)
    assert np.all(np.abs(k[:3] / k_true[:3] - 1) < 0.15)


def test_prediction_error_over_workspace_below_chapter_bound(robot, tip_robot, poses, truth):
    """The chapter: deviation over the whole workspace under 0.04 mm."""
    data = simulate_stiffness_measurements(tip_robot, poses, truth, cmm_noise_m=20e-6, seed=5)
    model = identify_joint_stiffness(tip_robot, data).model
    test_joints = sample_workspace_joints(robot, 15, seed=11)
    errors = prediction_errors(robot, test_joints, np.tile(CHAPTER_WRENCH, (15, 1)), model, truth)
    assert errors.max() < 0.04e-3


def test_more_noise_gives_larger_errors(tip_robot, poses, truth):
    def error(noise: float) -> float:
        data = simulate_stiffness_measurements(tip_robot, poses, truth, cmm_noise_m=noise, seed=2)
        k = np.array(identify_joint_stiffness(tip_robot, data).model.stiffness_Nm_rad)
        return float(np.abs(k / np.array(truth.stiffness_Nm_rad) - 1).max())

    assert error(5e-6) < error(50e-6)


def test_too_few_measurements_are_refused(tip_robot, poses, truth):
    data = simulate_stiffness_measurements(tip_robot, poses[:1], truth, loads_N=((0, 0, -100.0),))
    with pytest.raises(IdentificationError):
        identify_joint_stiffness(tip_robot, data)


def test_unexcited_joint_is_refused(tip_robot, poses):
    data = StiffnessMeasurements(poses[:5], np.zeros((5, 3)), np.zeros((5, 3)))
    with pytest.raises(IdentificationError):
        identify_joint_stiffness(tip_robot, data)


def test_identified_model_is_a_joint_compliance(tip_robot, poses, truth):
    data = simulate_stiffness_measurements(tip_robot, poses[:10], truth, seed=1)
    assert isinstance(identify_joint_stiffness(tip_robot, data).model, JointCompliance)
