"""Iterative learning control over repeated runs (the Lund ILC paper)."""

from __future__ import annotations

import numpy as np
import pytest

from robomach_core.errors import InvalidInputError
from robomach_core.stiffness.ilc import (
    IlcSystem,
    milling_process_gain,
    run_ilc,
    square_path,
)
from robomach_core.stiffness.model import cartesian_compliance

OFFSET_M = (60e-6, -40e-6, 30e-6)


@pytest.fixture(scope="module")
def system(robot, truth, work_joints) -> IlcSystem:
    C = cartesian_compliance(robot, work_joints, truth)[:3, :3]
    return IlcSystem(C, milling_process_gain())


@pytest.fixture(scope="module")
def path() -> np.ndarray:
    return square_path(side_m=0.02, speed_m_s=0.02)


def test_square_path_starts_and_ends_at_rest_at_one_point(path):
    np.testing.assert_allclose(path[0], path[-1], atol=1e-12)
    np.testing.assert_allclose(path[1], path[0], atol=1e-12)
    assert np.ptp(path[:, 0]) == pytest.approx(0.02)


def test_robot_inverse_undoes_the_robot_model(system):
    x = np.cumsum(np.random.default_rng(0).normal(size=(300, 3)), axis=0) * 1e-6
    back = system.robot_inverse(system.apply_robot(x))
    np.testing.assert_allclose(back[:-1], x[:-1], atol=1e-12)


@pytest.mark.parametrize("kind", ["arm", "force"])
@pytest.mark.parametrize("gain", [0.5, 1.0])
def test_error_decreases_monotonically_on_the_nominal_model(system, path, kind, gain):
    result = run_ilc(
        system,
        system,
        path,
        kind=kind,
        iterations=5,
        tracker_noise_m=0.0,
        force_noise_N=0.0,
        learning_gain=gain,
        q_cutoff_hz=None,
    )
    e = result.error_mean_um if kind == "arm" else result.deviation_mean_um
    assert np.all(np.diff(e) <= 1e-9 * e[0])  # non-increasing, to round-off
    assert e[-1] < 0.1 * e[0]


@pytest.mark.parametrize("kind", ["arm", "force"])
def test_q_filtered_error_settles_without_growing(system, path, kind):
    """The Q filter stops learning above its cut-off: the error settles at what it leaves."""
    result = run_ilc(
        system, system, path, kind=kind, iterations=6, tracker_noise_m=0.0, force_noise_N=0.0
    )
    e = result.error_mean_um if kind == "arm" else result.deviation_mean_um
    assert np.all(np.diff(e) <= 1e-4 * e[1:])
    assert e[-1] < 0.1 * e[0]


def test_force_ilc_cannot_remove_a_constant_offset(system, path):
    kwargs = {
        "iterations": 3,
        "offset_m": OFFSET_M,
        "tracker_noise_m": 0.0,
        "force_noise_N": 0.0,
        "q_cutoff_hz": None,
    }
    arm = run_ilc(system, system, path, kind="arm", **kwargs)
    force = run_ilc(system, system, path, kind="force", **kwargs)
    offset_um = np.linalg.norm(OFFSET_M) * 1e6
    assert arm.error_mean_um[-1] < 0.1 * offset_um
    assert force.error_mean_um[-1] == pytest.approx(offset_um, rel=0.05)
    assert force.deviation_mean_um[-1] < 0.1 * offset_um


def test_unknown_kind_is_refused(system, path):
    with pytest.raises(InvalidInputError):
        run_ilc(system, system, path, kind="optical")  # type: ignore[arg-type]
