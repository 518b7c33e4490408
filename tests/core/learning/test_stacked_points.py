"""Two neighbouring guide points one above the other (issue 28, "the same height"): less than
``MIN_SPACING_M`` apart across the tool axis they give no leg, and the route holds one height at
one place, so one of the two heights was dropped without a word (a block set whose G2 was taught
11 mm above G3 passed 5.3 mm off it). Such a pair is refused before any motion, naming both;
a pair within ``TAUGHT_WALL_HEIGHT_BAND_M`` of each other is not. A fresh seed each run
(``ROBOMACH_SEED`` replays it)."""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest

from robomach_core.errors import RouteRefusedError
from robomach_core.learning import thresholds as th
from robomach_core.learning.route import mean_tool_axis, plan_route
from robomach_core.learning.settings import PathLearningSettings
from tests.envelope import example_points, replay, run_seed

SEED = run_seed()


@pytest.mark.parametrize("stacked", [True, False])
def test_a_point_taught_straight_above_its_neighbour_is_refused_naming_both(stacked):
    rng = np.random.default_rng(SEED + stacked)
    pset, _, _ = example_points("water_pump", 0)
    guides = list(pset.guides)
    axis = mean_tool_axis(guides)
    k = int(rng.integers(len(guides)))
    lift = rng.uniform(1.05, 3.0) if stacked else rng.uniform(0.0, 0.95)
    across = np.cross(axis, rng.normal(size=3))
    across *= rng.uniform(0.0, 0.9) * th.MIN_SPACING_M / np.linalg.norm(across)
    T = guides[k].T_base_tcp.copy()
    T[:3, 3] += -axis * lift * th.TAUGHT_WALL_HEIGHT_BAND_M + across  # up: against the axis
    guides.insert(k + 1, replace(guides[k], T_base_tcp=T))
    where = f"{replay(SEED)}: G{k + 2} {lift * th.TAUGHT_WALL_HEIGHT_BAND_M * 1e3:.1f} mm above"
    settings = PathLearningSettings(closed=True, wall_side="right")
    if stacked:
        with pytest.raises(RouteRefusedError, match=f"G{k + 1} and G{k + 2} stand one above"):
            plan_route(guides, settings)
    else:
        try:
            plan_route(guides, settings)
        except RouteRefusedError as exc:
            assert "one above the other" not in str(exc), f"{where}: {exc}"
