"""Real-time factor of the CMRR simulation: a 60 s cut at 250 Hz for each controller.

Run: ``python benchmarks/bench_cmrr.py [--quick]``. The cut is the milling process
(F = 23 d^0.9 f^0.5) at 10 mm/s command speed over a 600 mm path whose depth alternates 1 / 3 mm
every 50 mm, so every controller works for the whole minute (15 000 control periods).
``--quick`` simulates one second per controller (a smoke test, not a measurement).
"""

from __future__ import annotations

import argparse
import time
from dataclasses import replace

import numpy as np

from robomach_core.cmrr import CONTROLLER_NAMES, PathProfile, build_scenario, run_study

MM = 1e-3
SIM_SECONDS = 60.0
QUICK_SIM_SECONDS = 1.0


def scenario(sim_seconds: float = SIM_SECONDS):
    positions, depths = [0.0], [1.0 * MM]
    for i in range(1, 12):
        positions += [i * 0.05 - 0.002, i * 0.05 + 0.002]
        depths += [depths[-1], (3.0 if i % 2 else 1.0) * MM]
    positions.append(0.6)
    depths.append(depths[-1])
    base = build_scenario("milling-steps", reference_force_N=150.0, command_speed_mm_s=10.0)
    return replace(
        base,
        name="bench-60s",
        depth_profile=PathProfile(np.array(positions), np.array(depths)),
        segments=(),
        max_time_s=sim_seconds,
    )


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--quick", action="store_true", help="one simulated second per controller")
    args = parser.parse_args()
    sc = scenario(QUICK_SIM_SECONDS if args.quick else SIM_SECONDS)
    print(f"{'controller':<12} {'sim [s]':>8} {'wall [s]':>9} {'real-time factor':>17}")
    for name in CONTROLLER_NAMES:
        t0 = time.perf_counter()
        result = run_study(sc, name)
        wall = time.perf_counter() - t0
        sim = float(result.trace.time_s[-1])
        print(f"{name:<12} {sim:8.1f} {wall:9.2f} {sim / wall:17.1f}")


if __name__ == "__main__":
    main()
