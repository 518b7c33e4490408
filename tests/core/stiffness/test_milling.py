"""Simulated milling passes and the surface error they leave."""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest

from robomach_core.cell import ToolGravity
from robomach_core.errors import CancelledError, InvalidInputError
from robomach_core.stiffness.milling import (
    CHAPTER_END_MILLING,
    LUND_FACE_MILLING,
    engagement,
    simulate_milling,
)

# A short block and a fast feed keep each pass to about a hundred control steps.
SHORT = replace(
    CHAPTER_END_MILLING,
    block_length_m=0.020,
    block_width_m=0.010,
    cutter_radius_m=0.008,
    feed_speed_m_s=0.100,
)
TOOL = ToolGravity(2.5, (0.0, 0.0, 0.07), (1.0, -0.5, 2.0), (0.01, 0.02, 0.0))


def test_engagement_is_zero_outside_and_full_inside_the_block():
    u = np.array([-0.05, 0.0, 0.075, 0.2])
    e = engagement(CHAPTER_END_MILLING, u, 0.0)
    assert e[0] == 0.0 and e[-1] == 0.0
    assert 0.0 < e[1] <= 1.0
    assert e[2] == 1.0


def test_no_force_leaves_the_programmed_surface(robot, truth):
    quiet = replace(SHORT, feed_force_N=0.0, cutting_force_N=0.0, normal_force_N=0.0)
    run = simulate_milling(robot, quiet, truth)
    assert run.error_max_m < 1e-9


COMPENSATED = [("online", "linear"), ("offline", "linear"), ("offline", "nonlinear")]


@pytest.mark.parametrize(("mode", "offline_model"), COMPENSATED)
def test_compensation_is_zero_at_zero_load(robot, truth, mode, offline_model):
    quiet = replace(SHORT, feed_force_N=0.0, cutting_force_N=0.0, normal_force_N=0.0)
    exact_sensor = {"sensor_force_noise_N": 0.0, "sensor_torque_noise_Nm": 0.0}
    plain = simulate_milling(robot, quiet, truth, true_tool_gravity=TOOL, **exact_sensor)
    comp = simulate_milling(
        robot, quiet, truth, compensation=mode, offline_model=offline_model, model=truth,
        tool_gravity=TOOL, **exact_sensor,
    )  # fmt: skip
    np.testing.assert_allclose(comp.position_actual_m, plain.position_actual_m, atol=1e-9)


def test_chapter_forces_cut_too_deep_without_compensation(robot, truth):
    """The chapter's coupling: feed and cutting forces push the cutter into the part."""
    run = simulate_milling(robot, SHORT, truth)
    assert run.error_mean_m > 50e-6
    assert np.all(run.error_m >= 0.0)


@pytest.mark.parametrize(("mode", "offline_model"), COMPENSATED)
def test_compensation_with_a_perfect_model_removes_most_of_the_error(
    robot, truth, mode, offline_model
):
    plain = simulate_milling(robot, SHORT, truth, seed=2, true_tool_gravity=TOOL)
    comp = simulate_milling(
        robot, SHORT, truth, compensation=mode, offline_model=offline_model, model=truth,
        tool_gravity=TOOL, seed=2,
    )  # fmt: skip
    assert comp.error_mean_m < 0.1 * plain.error_mean_m
    # Force noise the model cannot predict stays (the deepest excursion cuts); online also lags
    # the force by a step and a filter, which this fast feed shows at the entry.
    assert comp.error_max_m < (0.5 if mode == "online" else 0.25) * plain.error_max_m


def test_lateral_error_measure_uses_stationary_steps(robot, truth):
    short_face = replace(LUND_FACE_MILLING, block_length_m=0.030, feed_speed_m_s=0.05)
    run = simulate_milling(robot, short_face, truth)
    assert len(run.error_m) > 0
    assert run.error_max_m > 20e-6


def test_progress_and_cancel(robot, truth):
    fractions: list[float] = []
    simulate_milling(robot, SHORT, truth, progress=fractions.append)
    assert fractions[-1] == pytest.approx(1.0)
    assert all(b >= a for a, b in zip(fractions, fractions[1:], strict=False))
    with pytest.raises(CancelledError):
        simulate_milling(robot, SHORT, truth, cancel=lambda: True)


def test_compensation_without_model_is_refused(robot, truth):
    with pytest.raises(InvalidInputError):
        simulate_milling(robot, SHORT, truth, compensation="offline")
    with pytest.raises(InvalidInputError, match="off, offline, online"):
        simulate_milling(robot, SHORT, truth, compensation="offline_linear", model=truth)
