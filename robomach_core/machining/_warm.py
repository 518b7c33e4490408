"""The machining loop's compiled kernels, loaded once for every worker process.

The local pool's workers are forked from a forkserver that imports this module
(``parallel._pool_context``): it runs a few short cuts here, which loads the compiled kernels
from numba's disk cache (0.4-0.5 s), and every worker forked afterwards starts with them in
memory instead of loading them again at every comparison.
"""

from __future__ import annotations

import numpy as np


def warm() -> None:
    """A short offline-compensated cut and a fuzzy one on a synthetic 20 mm path: every kernel
    of a machining run is called once with its real argument types."""
    from ..cell import Robot
    from ..postprocess import Targets
    from .compare import run_configuration
    from .settings import MachiningSettings
    from .stock import stock_from_profile

    robot = Robot("ur10")
    n = 5
    q = np.tile(robot.home_rad, (n, 1))
    start = robot.fk(robot.home_rad)[:3, 3]
    points = start + np.outer(np.linspace(0.0, 0.02, n), [1.0, 0.0, 0.0])
    targets = Targets(
        position_m=points,
        quaternion_wxyz=np.tile([1.0, 0.0, 0.0, 0.0], (n, 1)),
        joints_rad=q,
        speed_m_s=np.full(n, 0.01),
        curvature_1_m=np.zeros(n),
        sample_index=np.arange(n),
    )
    normals = np.tile([0.0, 1.0, 0.0], (n, 1))
    stock = stock_from_profile(points, ((0.0, 0.5), (20.0, 0.8)), wall_normals_m=normals)
    settings = MachiningSettings(identification_poses=8)
    from ..cell import true_joint_compliance

    model = true_joint_compliance(robot.name)
    for controller, compensation in (("constant", "offline"), ("fuzzy", "off")):
        run_configuration(
            robot, targets, None, stock, settings, controller, compensation,
            compensation_model=model,
        )  # fmt: skip


try:  # a failure here only costs the workers the load
    warm()
except Exception:  # pragma: no cover - never stop a pool from starting
    pass
