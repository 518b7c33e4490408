"""Real-time factor of path learning on the water pump, with the cost of one control step's parts.

Run: python benchmarks/bench_path_learning.py [--repeats N] [--quick]
Prints the simulated seconds per wall second of ``learn_path`` (median over repeats) and, measured
in the same run as references, the cost of the parts of one 4 ms control step. ``--quick`` leads
the robot to the first two guide points only and learns that open stretch once (a smoke test,
not a measurement).
"""

from __future__ import annotations

import argparse
import statistics
import time

import numpy as np

from robomach_core.cell import CONTROL_PERIOD_S, Cell
from robomach_core.demo_operator import guide_plan, scripted_leadthrough
from robomach_core.leadthrough import LeadThrough
from robomach_core.path_learning import PathLearningSettings, learn_path


def per_call_us(fn, n: int) -> float:
    samples = []
    for _ in range(5):
        t = time.perf_counter()
        for _ in range(n):
            fn()
        samples.append((time.perf_counter() - t) / n * 1e6)
    return statistics.median(samples)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__)
    parser.add_argument("--repeats", type=int, default=3)
    parser.add_argument("--quick", action="store_true", help="two guide points, one run")
    args = parser.parse_args()
    repeats, calls = (1, 50) if args.quick else (args.repeats, 3000)

    cell = Cell()
    lt = LeadThrough(cell)
    state = lt.start(cell.initial_state())
    rng = np.random.default_rng(0)
    intents = None
    if args.quick:
        intents = guide_plan(cell.workpiece, cell.tool.radius_m, rng)[:2]
    learning = PathLearningSettings(closed=not args.quick)
    t = time.perf_counter()
    state, guides = scripted_leadthrough(lt, state, cell.workpiece, rng, intents=intents)
    lead_wall = time.perf_counter() - t
    print(
        f"lead-through: {state.cell.time_s:.1f} s simulated in {lead_wall:.1f} s "
        f"(x{state.cell.time_s / lead_wall:.1f})"
    )

    factors, per_step = [], []
    for _ in range(repeats):
        c = Cell()
        t = time.perf_counter()
        rec, end = learn_path(c, state.cell, guides, learning, lt.estimator)
        wall = time.perf_counter() - t
        factors.append(rec.time_s[-1] / wall)
        per_step.append(wall / len(rec) * 1e6)
    print(
        f"path learning: {len(rec)} samples, {rec.time_s[-1]:.1f} s simulated; "
        f"real-time factor median x{statistics.median(factors):.1f} "
        f"(runs: {', '.join(f'x{f:.1f}' for f in factors)}); "
        f"{statistics.median(per_step):.0f} us per {CONTROL_PERIOD_S * 1e3:.0f} ms step"
    )
    print("  aim: x100 (40 us per step)")

    # References in the same run: the parts of one control step.
    q = end.q_motor.copy()
    T = c.robot.fk(q).copy()
    robot = c.robot

    def fk_jacobian() -> None:
        robot._cache_key = b""
        robot.fk_and_jacobian(q)

    v = np.array([0.005, 0.0, 0.0])
    contact = c.contact_model
    T_wall = end.T_base_tcp_true.copy()
    print("per-step parts (median us):")
    print(f"  pinocchio FK + Jacobian      {per_call_us(fk_jacobian, calls):7.1f}")
    print(f"  IK step (FK cached)          {per_call_us(lambda: robot.ik_step(q, T), calls):7.1f}")
    print(
        f"  coal contact evaluation      "
        f"{per_call_us(lambda: contact.evaluate(T_wall, v, 1e-4, CONTROL_PERIOD_S), calls):7.1f}"
    )
    print(f"  whole cell step              {per_call_us(lambda: c.step(end, q), calls // 3):7.1f}")


if __name__ == "__main__":
    main()
