from __future__ import annotations

import numpy as np
from hypothesis import given, settings
from hypothesis import strategies as st

from robomach_core.transforms import (
    matrix_from_quaternion,
    quaternion_from_matrix,
    quaternions_from_matrices,
    rotation_about,
    rotation_log,
    slerp,
)

angles = st.floats(0.0, np.pi - 1e-6)
axes = st.tuples(*[st.floats(-1, 1)] * 3).filter(lambda a: np.linalg.norm(a) > 0.1)


@given(axes, angles)
@settings(max_examples=200, deadline=None)
def test_quaternion_round_trip_and_canonical_sign(axis, angle):
    R = rotation_about(np.array(axis), angle)
    q = quaternion_from_matrix(R)
    assert abs(np.linalg.norm(q) - 1) < 1e-12
    assert q[np.argmax(np.abs(q) > 1e-12)] > 0
    np.testing.assert_allclose(matrix_from_quaternion(q), R, atol=1e-12)
    np.testing.assert_allclose(quaternions_from_matrices(R[None])[0], q, atol=1e-7)


@given(axes, angles)
@settings(max_examples=100, deadline=None)
def test_rotation_log_inverts_rotation_about(axis, angle):
    a = np.array(axis) / np.linalg.norm(axis)
    np.testing.assert_allclose(rotation_log(rotation_about(a, angle)), a * angle, atol=1e-7)


def test_slerp_halfway_is_half_the_rotation():
    q0 = quaternion_from_matrix(np.eye(3))
    q1 = quaternion_from_matrix(rotation_about("z", 1.0))
    np.testing.assert_allclose(
        matrix_from_quaternion(slerp(q0, q1, 0.5)), rotation_about("z", 0.5), atol=1e-12
    )
