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


@given(st.integers(0, 2**32 - 1))
@settings(max_examples=50, deadline=None)
def test_a_half_turn_with_noise_keeps_its_printed_sign(seed):
    """A half turn's w is +-1e-17 of noise: the sign is the first larger component's, so the
    same tool pose prints the same quaternion (SciPy's canonical form keys on w's sign)."""
    rng = np.random.default_rng(seed)
    axis = rng.normal(size=3)
    R = rotation_about(axis, np.pi) @ rotation_about(rng.normal(size=3), rng.choice([0, 1e-15]))
    q = quaternions_from_matrices(np.stack([R, R.T]))
    for row in q:
        assert row[np.argmax(np.abs(row) > 1e-12)] > 0, (seed, row)
    np.testing.assert_allclose(q[0], q[1], atol=1e-9)


@given(st.integers(0, 2**32 - 1))
@settings(max_examples=50, deadline=None)
def test_slerp_of_many_pairs_is_scipys_slerp_between_two_keys(seed):
    from scipy.spatial.transform import Rotation, Slerp

    rng = np.random.default_rng(seed)
    q0, q1 = rng.normal(size=(2, 20, 4))
    f = rng.uniform(0.0, 1.0, 20)
    got = slerp(q0, q1, f)
    for k in range(20):
        keys = Rotation.from_quat([q0[k], q1[k]], scalar_first=True)
        want = Slerp([0.0, 1.0], keys)([f[k]]).as_matrix()[0]
        np.testing.assert_allclose(matrix_from_quaternion(got[k]), want, atol=1e-12)
        np.testing.assert_allclose(slerp(q0[k], q1[k], f[k]), got[k], atol=1e-15)


def test_a_vector_of_any_finite_length_has_the_unit_of_its_direction():
    """1e-300 to 1e300, as a whole or one component far off the others (a fresh draw): the unit
    is its direction's; zero and non-finite vectors are refused."""
    import random

    import pytest

    from robomach_core.errors import InvalidInputError
    from robomach_core.transforms import unit_vector

    seed = random.randrange(2**32)
    rng = np.random.default_rng(seed)
    for _ in range(50):
        d = rng.normal(size=3)
        d /= np.linalg.norm(d)
        scale = 10.0 ** rng.uniform(-300, 300)
        np.testing.assert_allclose(unit_vector(d * scale), d, atol=1e-15, err_msg=f"seed {seed}")
        lopsided = np.array([10.0 ** rng.uniform(250, 300), 10.0 ** rng.uniform(-300, -250), 1.0])
        np.testing.assert_allclose(unit_vector(lopsided), [1.0, 0.0, 0.0], atol=1e-15)
    for bad in ([0.0, 0.0, 0.0], [np.inf, 0.0, 0.0], [np.nan, 1.0, 0.0], [1.0, 2.0]):
        with pytest.raises(InvalidInputError):
            unit_vector(bad)
