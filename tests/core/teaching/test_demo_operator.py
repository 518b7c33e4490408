from __future__ import annotations

import numpy as np
import pytest

from robomach_core.cell import Cell, LeadThrough
from robomach_core.errors import InvalidInputError, NotEnoughGuidePointsError
from robomach_core.teaching import guide_plan, intents_from_csv, scripted_leadthrough


@pytest.fixture(scope="module")
def led():
    cell = Cell()
    lt = LeadThrough(cell)
    state = lt.start(cell.initial_state())
    intents = guide_plan(cell.workpiece, cell.tool.radius_m, np.random.default_rng(0))
    state, guides = scripted_leadthrough(lt, state, cell.workpiece, np.random.default_rng(0))
    return cell, intents, state, guides


def test_operator_reaches_every_planned_point_by_pushing(led):
    cell, intents, state, guides = led
    assert len(guides) == len(intents) >= 6
    for intent, g in zip(intents, guides, strict=True):
        # Pushed against the wall: within ~1.5 mm of where the operator aimed, touching it.
        assert np.linalg.norm(g.position_m - intent.position_m) < 0.002
        assert np.linalg.norm(g.force_N) > 3.0
    # A human-paced lead-through: no move waited out its timeout (20 s each).
    assert state.cell.time_s < 10.0 * len(guides)


def test_guide_points_are_square_to_the_part(led):
    _, _, _, guides = led
    for g in guides:
        assert g.T_base_tcp[2, 2] == pytest.approx(-1.0, abs=1e-3)  # tool axis straight down


def test_guide_csv_is_validated():
    with pytest.raises(NotEnoughGuidePointsError):
        intents_from_csv("x,y,z\n1,2,3\n")
    with pytest.raises(InvalidInputError, match="line 3"):
        intents_from_csv("x,y,z\n700,100,40\n1,2\n")
    two = intents_from_csv("700,100,40\n720,100,40,1,0,0,0,0,-1,0\n")
    np.testing.assert_allclose(two[0].position_m, [0.7, 0.1, 0.04])
    np.testing.assert_allclose(two[1].wall_normal, [0.0, -1.0, 0.0])
