"""Speed of the stiffness model and compensation: run ``python benchmarks/bench_stiffness.py``.

Prints the time per call of the Cartesian compliance, the linear and non-linear loaded
equilibrium, one online compensation step (against the 4 ms control period) and offline
target correction per target, linear and by eq. (32). ``--quick`` makes 1/100 of the calls (a
smoke test, not a measurement).
"""

from __future__ import annotations

import argparse
import time
from collections.abc import Callable

import numpy as np

from robomach_core.cell import Robot, Tool, ToolGravity, gravity_reading, true_joint_compliance
from robomach_core.stiffness.compensation import (
    OnlineCompensationParams,
    OnlineCompensationState,
    compensate_targets,
    online_compensation_step,
)
from robomach_core.stiffness.milling import CHAPTER_END_MILLING
from robomach_core.stiffness.model import cartesian_compliance, loaded_equilibrium
from robomach_core.transforms import make_transform

CONTROL_PERIOD_US = 4000.0


def per_call_us(fn: Callable[[], object], *, repeat: int) -> float:
    """Best of three runs of ``repeat`` calls, microseconds per call."""
    best = np.inf
    for _ in range(3):
        start = time.perf_counter()
        for _ in range(repeat):
            fn()
        best = min(best, (time.perf_counter() - start) / repeat)
    return best * 1e6


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--quick", action="store_true", help="1/100 of the calls")
    args = parser.parse_args()
    scale = 0.01 if args.quick else 1.0

    def calls(n: int) -> int:
        return max(1, int(n * scale))

    tool = Tool()
    robot = Robot("ur10", tool.T_flange_tcp)
    model = true_joint_compliance("ur10")
    T = make_transform(np.diag([1.0, -1.0, -1.0]), np.array([0.70, 0.10, 0.03]))
    q = robot.ik(T)
    W = CHAPTER_END_MILLING.nominal_wrench()
    gravity = ToolGravity.from_tool(tool)
    params = OnlineCompensationParams(model, gravity)
    reading = gravity_reading(robot.flange_pose(q)[:3, :3].copy(), gravity)
    state = OnlineCompensationState()
    Ts = np.repeat(T[None], 100, axis=0)
    qs = np.repeat(q[None], 100, axis=0)
    Ws = np.repeat(W[None], 100, axis=0)

    rows = [
        (
            "Cartesian compliance C = J Kq^-1 J^T",
            per_call_us(lambda: cartesian_compliance(robot, q, model), repeat=calls(2000)),
        ),
        (
            "loaded equilibrium, linear",
            per_call_us(
                lambda: loaded_equilibrium(robot, q, W, model, mode="linear"), repeat=calls(2000)
            ),
        ),
        (
            "loaded equilibrium, non-linear",
            per_call_us(lambda: loaded_equilibrium(robot, q, W, model), repeat=calls(1000)),
        ),
        (
            "online compensation step (fig. 15)",
            per_call_us(
                lambda: online_compensation_step(robot, state, q, reading, params, 0.004),
                repeat=calls(2000),
            ),
        ),
        (
            "offline correction per target, linear",
            per_call_us(
                lambda: compensate_targets(robot, Ts, qs, Ws, model, "linear"), repeat=calls(5)
            )
            / 100,
        ),
        (
            "offline correction per target, eq. (32)",
            per_call_us(
                lambda: compensate_targets(robot, Ts, qs, Ws, model, "nonlinear"), repeat=calls(3)
            )
            / 100,
        ),
    ]
    width = max(len(name) for name, _ in rows)
    print(f"{'operation':<{width}}  us/call  share of a 4 ms period")
    for name, us in rows:
        print(f"{name:<{width}}  {us:7.1f}  {us / CONTROL_PERIOD_US * 100:5.2f} %")


if __name__ == "__main__":
    main()
