"""Two neighbouring guide points one above the other (issue 28, "the same height"): less than
``MIN_SPACING_M`` apart across the tool axis they give no leg, and the route holds one height at
one place, so one of the two heights was dropped without a word (a block set whose G2 was taught
11 mm above G3 passed 5.3 mm off it). The same at one place of the wall (``at_one_station``: one
point on the wall, the other a gap off it, the way between them more across the wall than along
it, and less than ``MIN_SPACING_M`` along it): a block set whose G6, 1.7 mm off the wall, was
taught 12.6 mm above G7 on it was passed half-way between the two heights with no NOT FIT. Such
a pair is refused before any motion, naming both; a pair within ``TAUGHT_WALL_HEIGHT_BAND_M`` of
each other is not. A fresh seed each run (``ROBOMACH_SEED`` replays it)."""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest

from robomach_core.errors import RouteRefusedError
from robomach_core.learning import thresholds as th
from robomach_core.learning.part_walls import PartWalls
from robomach_core.learning.route import mean_tool_axis, plan_route, station_normals
from robomach_core.learning.settings import PathLearningSettings
from tests.envelope import example_points, part_named, replay, run_seed

SEED = run_seed()


@pytest.mark.parametrize("place", ["above", "station"])
@pytest.mark.parametrize("stacked", [True, False])
def test_a_point_taught_high_over_its_neighbour_at_one_place_is_refused_naming_both(stacked, place):
    rng = np.random.default_rng(SEED + 2 * stacked + (place == "station"))
    part = part_named("water_pump")
    pset, _, _ = example_points("water_pump", 0)
    cell = part.cell(0)
    guides = list(pset.guides)
    axis = mean_tool_axis(guides)
    lift = rng.uniform(1.05, 3.0) if stacked else rng.uniform(0.0, 0.95)
    if place == "above":
        k = int(rng.integers(len(guides)))
        across = np.cross(axis, rng.normal(size=3))
        across *= rng.uniform(0.0, 0.9) * th.MIN_SPACING_M / np.linalg.norm(across)
    else:  # a gap off the wall the point stands by, a little along it
        normals = station_normals(guides, PartWalls(cell.workpiece, axis, cell.tool.radius_m))
        assert normals is not None
        k = int(rng.choice(np.flatnonzero(np.linalg.norm(normals, axis=1) > 0.5)))
        gap = rng.uniform(1.2, 2.5) * 1e-3
        along = np.cross(axis, normals[k]) * th.MIN_SPACING_M * rng.uniform(-0.9, 0.9)
        across = normals[k] * gap + along
    T = guides[k].T_base_tcp.copy()
    T[:3, 3] += -axis * lift * th.TAUGHT_WALL_HEIGHT_BAND_M + across  # up: against the axis
    guides.insert(k + 1, replace(guides[k], T_base_tcp=T))
    where = f"{replay(SEED)}: G{k + 2} {lift * th.TAUGHT_WALL_HEIGHT_BAND_M * 1e3:.1f} mm above"
    settings = PathLearningSettings(closed=True, wall_side="right")
    said = "one above the other" if place == "above" else "at one station"
    kw = {"workpiece": cell.workpiece, "tool_radius_m": cell.tool.radius_m}
    if stacked:
        with pytest.raises(RouteRefusedError, match=f"G{k + 1} and G{k + 2} stand {said}"):
            plan_route(guides, settings, **kw)
    else:
        try:
            plan_route(guides, settings, **kw)
        except RouteRefusedError as exc:
            assert said not in str(exc), f"{where}: {exc}"
