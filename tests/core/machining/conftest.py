"""Programs to cut: along the water pump's true wall (fast, for unit tests). The learned program
is the shared demo's (tests/demo_project.py)."""

from __future__ import annotations

import numpy as np
import pytest

from robomach_core.cell import Robot, Tool
from robomach_core.machining import targets_along_wall
from robomach_core.part import builtin_workpiece
from robomach_core.postprocess import Targets


@pytest.fixture(scope="session")
def robot() -> Robot:
    return Robot("ur10", Tool().T_flange_tcp)


@pytest.fixture(scope="session")
def wall_program(robot: Robot) -> Targets:
    """Every 2 mm along the water pump's true wall, tool down, ~10 mm/s."""
    return targets_along_wall(robot, builtin_workpiece("water_pump"), tool_radius_m=0.001)


@pytest.fixture(scope="session")
def short_program(wall_program: Targets) -> Targets:
    """The first ~120 mm of the wall program."""
    keep = slice(0, 61)
    return Targets(
        **{k: np.asarray(getattr(wall_program, k))[keep] for k in wall_program.__dataclass_fields__}
    )
