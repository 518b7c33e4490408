from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from robomach_core.cell import HOME_JOINTS_RAD, Robot, Tool
from robomach_core.errors import UnknownNameError, UnreachableTargetError
from robomach_core.transforms import rotation_about


@pytest.fixture(scope="module")
def ur10() -> Robot:
    return Robot("ur10", Tool().T_flange_tcp)


@pytest.mark.parametrize("name", ["ur10", "ur5", "ur3"])
def test_robots_load_with_six_joints(name):
    robot = Robot(name)
    assert robot.nq == 6
    assert robot.within_limits(HOME_JOINTS_RAD)


def test_unknown_robot_is_a_clear_error():
    with pytest.raises(
        UnknownNameError, match="choose one of irb2400, irb4400, irb6640, kr270, ur10, ur3, ur5"
    ):
        Robot("kuka")


def test_tcp_is_the_tool_offset_along_the_flange_axis(ur10):
    T_flange = ur10.flange_pose(HOME_JOINTS_RAD)
    T_tcp = ur10.fk(HOME_JOINTS_RAD)
    np.testing.assert_allclose(T_tcp[:3, 3], T_flange[:3, 3] + 0.18 * T_flange[:3, 2], atol=1e-12)


def test_jacobian_matches_finite_differences(ur10):
    q = HOME_JOINTS_RAD + 0.1
    T0, J = ur10.fk_and_jacobian(q)
    T0, J = T0.copy(), J.copy()
    eps = 1e-7
    for i in range(6):
        dq = np.zeros(6)
        dq[i] = eps
        T1 = ur10.fk(q + dq)
        np.testing.assert_allclose((T1[:3, 3] - T0[:3, 3]) / eps, J[:3, i], atol=1e-5)


@given(
    st.tuples(st.floats(-0.15, 0.15), st.floats(-0.15, 0.15), st.floats(-0.2, 0.1)),
    st.floats(-0.3, 0.3),
)
@settings(max_examples=25, deadline=None)
def test_fk_of_ik_is_the_target_inside_the_workspace(ur10, offset, tilt):
    T = ur10.fk(HOME_JOINTS_RAD).copy()
    T[:3, 3] += np.array(offset) + np.array([0.15, 0.0, 0.0])
    T[:3, :3] = rotation_about("x", tilt) @ T[:3, :3]
    q = ur10.ik(T)
    assert ur10.within_limits(q)
    np.testing.assert_allclose(ur10.fk(q), T, atol=1e-5)


def test_target_beyond_reach_says_how_far(ur10):
    T = np.eye(4)
    T[:3, 3] = [2.5, 0.0, 0.3]
    with pytest.raises(UnreachableTargetError, match="beyond the ur10 reach"):
        ur10.ik(T)


def test_ik_step_tracks_a_small_motion(ur10):
    q = HOME_JOINTS_RAD.copy()
    T = ur10.fk(q).copy()
    T[:3, 3] += [0.0, 0.00002, 0.0]  # 20 um: one 4 ms step at 5 mm/s
    q1 = ur10.ik_step(q, T)
    np.testing.assert_allclose(ur10.fk(q1)[:3, 3], T[:3, 3], atol=1e-9)


def test_kinematics_is_safe_from_several_threads(ur10):
    """The workbench steps the cell in a job while an export checks reachability."""
    import threading

    rng = np.random.default_rng(0)
    qs = [HOME_JOINTS_RAD + rng.uniform(-0.3, 0.3, 6) for _ in range(200)]
    expected = [ur10.fk(q).copy() for q in qs]
    errors = []

    def worker(offset: int) -> None:
        for k in range(600):
            i = (k + offset) % len(qs)
            T, _ = ur10.fk_and_jacobian(qs[i])
            if not np.allclose(T, expected[i], atol=1e-12):
                errors.append(i)
            T2 = ur10.fk(qs[(i + 7) % len(qs)])
            if not np.allclose(T2, expected[(i + 7) % len(qs)], atol=1e-12):
                errors.append(-i)

    threads = [threading.Thread(target=worker, args=(o,)) for o in (0, 50, 100)]
    for t in threads:
        t.start()
    for t in threads:
        t.join()
    assert not errors
