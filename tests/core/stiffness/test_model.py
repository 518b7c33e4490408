"""The linear and non-linear stiffness models."""

from __future__ import annotations

import numpy as np
from hypothesis import given, settings
from hypothesis import strategies as st

from robomach_core.cell import JointCompliance
from robomach_core.stiffness.model import (
    apply_twist,
    cartesian_compliance,
    equilibrium_at_pose,
    loaded_cartesian_compliance,
    loaded_equilibrium,
)
from robomach_core.transforms import pose_error

from .conftest import CHAPTER_WRENCH

stiffness = st.lists(st.floats(5e4, 5e6), min_size=6, max_size=6)
joint_offsets = st.lists(st.floats(-0.3, 0.3), min_size=6, max_size=6)


@settings(max_examples=30, deadline=None)
@given(k=stiffness, dq=joint_offsets)
def test_compliance_is_symmetric_positive_semidefinite(robot, work_joints, k, dq):
    C = cartesian_compliance(robot, work_joints + np.array(dq), JointCompliance(tuple(k)))
    np.testing.assert_allclose(C, C.T, atol=1e-12 * np.abs(C).max())
    assert np.linalg.eigvalsh(0.5 * (C + C.T)).min() >= -1e-12 * np.abs(C).max()


def test_coupling_pushes_cutter_into_part_under_feed_force(robot, truth, work_joints):
    """The chapter's explanation: a horizontal feed force moves the cutter vertically."""
    C = cartesian_compliance(robot, work_joints, truth)
    feed_force_against_x = np.array([-300.0, 0, 0, 0, 0, 0])
    dz = (C @ feed_force_against_x)[2]
    assert dz < -50e-6  # tens of micrometres down, from a purely horizontal force


def test_zero_load_leaves_the_tcp_in_place(robot, truth, work_joints):
    for mode in ("linear", "nonlinear"):
        eq = loaded_equilibrium(robot, work_joints, np.zeros(6), truth, mode=mode)
        np.testing.assert_array_equal(eq.deflection, np.zeros(6))
        np.testing.assert_allclose(eq.joints_arm_rad, work_joints)


def test_nonlinear_tends_to_linear_as_load_vanishes(robot, truth, work_joints):
    """|nonlinear - linear| / |linear| shrinks in proportion to the load (second-order term)."""
    ratios = []
    for scale in (10.0, 1.0, 0.1, 0.01):
        W = CHAPTER_WRENCH * scale
        lin = loaded_equilibrium(robot, work_joints, W, truth, mode="linear")
        nl = loaded_equilibrium(robot, work_joints, W, truth, mode="nonlinear")
        gap = np.linalg.norm(pose_error(lin.T_base_tcp, nl.T_base_tcp)[:3])
        ratios.append(gap / np.linalg.norm(lin.deflection[:3]))
    for bigger, smaller in zip(ratios, ratios[1:], strict=False):
        assert smaller < 0.2 * bigger
    assert ratios[-1] < 1e-5


def test_equilibrium_at_pose_inverts_loaded_equilibrium(robot, truth, work_joints):
    W = CHAPTER_WRENCH * 3
    loaded = loaded_equilibrium(robot, work_joints, W, truth)
    F, q_arm = equilibrium_at_pose(robot, work_joints, loaded.T_base_tcp, truth)
    np.testing.assert_allclose(F, W, atol=1e-3)
    np.testing.assert_allclose(q_arm, loaded.joints_arm_rad, atol=1e-10)


def test_loaded_compliance_equals_unloaded_at_zero_load(robot, truth, work_joints):
    C0 = cartesian_compliance(robot, work_joints, truth)
    C_loaded = loaded_cartesian_compliance(robot, work_joints, np.zeros(6), truth)
    np.testing.assert_allclose(C_loaded, C0, atol=1e-6 * np.abs(C0).max())


def test_loaded_compliance_predicts_small_load_increments(robot, truth, work_joints):
    W = CHAPTER_WRENCH * 10
    dW = np.array([1.0, -2.0, 0.5, 0, 0, 0])
    C = loaded_cartesian_compliance(robot, work_joints, W, truth)
    t0 = loaded_equilibrium(robot, work_joints, W, truth).T_base_tcp
    t1 = loaded_equilibrium(robot, work_joints, W + dW, truth).T_base_tcp
    np.testing.assert_allclose(pose_error(t0, t1)[:3], (C @ dW)[:3], atol=1e-9)


def test_apply_twist_zero_is_identity(work_pose):
    np.testing.assert_array_equal(apply_twist(work_pose, np.zeros(6)), work_pose)
