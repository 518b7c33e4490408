"""Shared fixtures: the UR10 with the spindle, its work pose and the simulator's true stiffness."""

from __future__ import annotations

import numpy as np
import pytest

from robomach_core.cell import JointCompliance, Robot, Tool, true_joint_compliance
from robomach_core.transforms import make_transform

WORK_POSITION_M = (0.70, 0.10, 0.03)
TOOL_DOWN = np.diag([1.0, -1.0, -1.0])
# The chapter's end-milling load on the arm: feed and cutting forces ~300 N, normal ~50 N.
CHAPTER_WRENCH = np.array([-300.0, 300.0, 50.0, 0.0, 0.0, 0.0])


@pytest.fixture(scope="session")
def robot() -> Robot:
    return Robot("ur10", Tool().T_flange_tcp)


@pytest.fixture(scope="session")
def truth() -> JointCompliance:
    return true_joint_compliance("ur10")


@pytest.fixture(scope="session")
def work_pose() -> np.ndarray:
    return make_transform(TOOL_DOWN, np.asarray(WORK_POSITION_M))


@pytest.fixture(scope="session")
def work_joints(robot: Robot, work_pose: np.ndarray) -> np.ndarray:
    return robot.ik(work_pose)
