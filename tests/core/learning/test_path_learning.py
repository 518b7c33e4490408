from __future__ import annotations

import numpy as np
import pytest

from robomach_core.cell import TOOL_DOWN, Cell, CellConfig, GuidePoint, LeadThrough
from robomach_core.cell.simulator import CONTROL_PERIOD_S
from robomach_core.errors import InvalidInputError, NotEnoughGuidePointsError
from robomach_core.learning.route import plan_route
from robomach_core.learning.run import learn_path
from robomach_core.learning.settings import PathLearningSettings
from robomach_core.scoring import true_tool_path_distance


def _guides_on_bottom_run(cell: Cell) -> list[GuidePoint]:
    """Two guide points 1.5 mm off the straight bottom run of the pump groove (x -95..-80 mm).

    Built with IK here to test path learning alone; the demo records them by pushing.
    """
    wp = cell.workpiece
    guides = []
    for x in (-0.094, -0.078):
        T = np.eye(4)
        T[:3, :3] = TOOL_DOWN
        T[:3, 3] = wp.T_base_wobj[:3, 3] + np.array([x, -0.065 + 0.0025, wp.surface_z_m - 0.003])
        q = cell.robot.ik(T)
        guides.append(GuidePoint(T, q, 0.0))
    return guides


def _learn(seed: int = 0, **kwargs):
    cell = Cell(CellConfig(seed=seed))
    lt = LeadThrough(cell)
    state = lt.start(cell.initial_state())
    settings = PathLearningSettings(closed=False, wall_side="right", **kwargs)
    rec, _ = learn_path(
        cell, state.cell, plan_route(_guides_on_bottom_run(cell), settings), settings, lt.estimator
    )
    return cell, rec


@pytest.fixture(scope="module")
def learned():
    return _learn()


def _settled(rec) -> np.ndarray:
    """Samples from 0.3 s after the tool first reached the wall (searching at 5 mm/s before)."""
    first = np.argmax(rec.force_normal_N > 5.0)
    return rec.time_s > rec.time_s[first] + 0.3


def test_run_reaches_the_last_guide_point_with_4ms_samples(learned):
    _, rec = learned
    assert rec.completed, rec.stop_reason
    np.testing.assert_allclose(np.diff(rec.time_s), CONTROL_PERIOD_S, atol=1e-9)
    assert len(rec) > 0.016 / 0.005 / CONTROL_PERIOD_S * 0.9  # 16 mm at 5 mm/s
    for name in ("joints_rad", "position_m", "quaternion_wxyz", "wrench_sensor", "wrench_tool"):
        assert len(getattr(rec, name)) == len(rec)


def test_contact_force_is_held_at_the_reference(learned):
    _, rec = learned
    settled = _settled(rec)
    assert settled.sum() > 500
    f = rec.force_normal_N[settled]
    assert np.mean(np.abs(f - 10.0) <= 2.0) >= 0.95
    assert rec.in_contact[settled].all()


def test_the_recording_follows_the_wall(learned):
    cell, rec = learned
    settled = _settled(rec)
    d = true_tool_path_distance(cell.workpiece, cell.tool.radius_m, rec.position_m[settled])
    # Inside the wall by the contact compliance F / k = 10 N / 100 N/mm = 0.1 mm, not more.
    assert np.median(d) == pytest.approx(0.1e-3, abs=0.03e-3)


def test_same_seed_same_recording(learned):
    _, rec = learned
    _, again = _learn()
    np.testing.assert_array_equal(rec.position_m, again.position_m)
    np.testing.assert_array_equal(rec.wrench_sensor, again.wrench_sensor)


def test_the_wall_is_searched_for_slowly(learned):
    """Out of contact the tool approaches the wall at the 5 mm/s search speed, no faster."""
    _, rec = learned
    before = np.argmax(rec.force_normal_N > 1.0)
    assert before > 10
    yp = rec.yp[0]
    v = np.diff(rec.position_m[:before] @ yp) / np.diff(rec.time_s[:before])
    assert v.max() <= 0.005 + 1e-4
    assert rec.force_normal_N.max() < 20.0  # no impact spike


def test_protection_rule_stops_the_run_and_says_why():
    _, rec = _learn(force_limit_N=11.0)
    assert not rec.completed
    assert rec.stop_reason.startswith("protection: the contact force reached")


def test_fewer_than_two_guide_points_is_refused():
    cell = Cell()
    with pytest.raises(NotEnoughGuidePointsError, match="at least 2 guide points"):
        plan_route(_guides_on_bottom_run(cell)[:1], PathLearningSettings())


@pytest.mark.parametrize("kwargs", [{"force_N": 0.5}, {"force_N": 60.0}, {"speed_m_s": 0.2}])
def test_out_of_range_settings_are_refused(kwargs):
    with pytest.raises(InvalidInputError):
        PathLearningSettings(**kwargs)


def _guides_past_the_boss(cell: Cell) -> list[GuidePoint]:
    """The example's first two guide points: the bottom run between them passes a bolt boss,
    where the wall turns up to ~70 degrees from the program line."""
    wp = cell.workpiece
    guides = []
    for x in (-0.0836, -0.0415):
        T = np.eye(4)
        T[:3, :3] = TOOL_DOWN
        T[:3, 3] = wp.T_base_wobj[:3, 3] + np.array([x, -0.0641, wp.surface_z_m - 0.0028])
        guides.append(GuidePoint(T, cell.robot.ik(T), 0.0))
    return guides


@pytest.mark.parametrize(("force_N", "speed_mm_s"), [(20.0, 10.0), (10.0, 20.0)])
def test_the_force_normal_to_the_edge_is_held_past_a_boss(force_N, speed_mm_s):
    """The chapter's 20 N, and a fast run, pass the boss: the loop holds the force normal to
    the edge (its Yp part alone let |F| reach F_ref / cos(70 deg) = 58 N at 20 N and trip the
    60 N protection), the run slows where the force climbs, and searches no faster than it
    advances."""
    cell = Cell(CellConfig(seed=0))
    lt = LeadThrough(cell)
    state = lt.start(cell.initial_state())
    settings = PathLearningSettings(
        force_N=force_N, speed_m_s=speed_mm_s * 1e-3, closed=False, wall_side="right"
    )
    rec, _ = learn_path(
        cell, state.cell, plan_route(_guides_past_the_boss(cell), settings), settings, lt.estimator
    )
    assert rec.completed, rec.stop_reason
    settled = _settled(rec)
    planar = np.linalg.norm(rec.wrench_tool[settled, :2], axis=1)
    assert planar.max() < 2.0 * force_N
    held = np.mean(np.abs(rec.force_normal_N[settled] - force_N) <= 0.2 * force_N)
    # At 20 mm/s the loop loses the wall on the boss's far side more than it holds it (32 %
    # within 20 %): it passes safely, but the chapter's 5-10 mm/s is what learns well.
    assert held >= (0.9 if speed_mm_s <= 10.0 else 0.25), held
