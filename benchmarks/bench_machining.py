"""Real-time factor of the machining run (issue 8: at least 50x), and the comparison matrix.

Run from the repository root: ``python benchmarks/bench_machining.py [--quick] [--repeats N]``.

The program is the water pump's learned one (the headless demo pipeline, defaults, seed 0; it
runs once first and is not timed) or, with ``--quick``, a program along the pump's true wall
(no pipeline). The stock is the built-in one, seed 0. Each configuration runs ``--repeats``
times; the median real-time factor (simulated cut time / wall time of ``run_machining``) is
printed. The full mode also times the whole 18-run matrix once.
"""

from __future__ import annotations

import argparse
import statistics
import sys
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from robomach_core.machining import (  # noqa: E402
    MACHINING_CONTROLLERS,
    MachiningSettings,
    builtin_stock,
    compare_configurations,
    identify_stiffness,
    run_machining,
    targets_along_wall,
    wall_normals_for_workpiece,
)
from robomach_core.robot import Robot  # noqa: E402
from robomach_core.tool import Tool  # noqa: E402
from robomach_core.workpiece import builtin_workpiece  # noqa: E402


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--quick", action="store_true", help="program along the true wall")
    parser.add_argument("--repeats", type=int, default=None, help="runs per configuration")
    args = parser.parse_args()
    repeats = args.repeats or (3 if args.quick else 5)

    tool = Tool()
    robot = Robot("ur10", tool.T_flange_tcp)
    pump = builtin_workpiece("water_pump")
    if args.quick:
        targets = targets_along_wall(robot, pump, tool_radius_m=tool.radius_m)
        source = "program along the true wall (--quick)"
    else:
        try:
            from robomach_core.pipeline import DemoSettings, run_demo
        except ImportError:  # the pipeline is moving into robomach_core.project
            from robomach_core.project import DemoSettings, run_demo

        t0 = time.perf_counter()
        targets = run_demo(DemoSettings()).processed.targets
        source = f"learned program (demo pipeline, {time.perf_counter() - t0:.0f} s, not timed)"
    normals = wall_normals_for_workpiece(pump, targets.position_m)
    stock = builtin_stock(targets.position_m, seed=0, wall_normals_m=normals)
    model = identify_stiffness(robot.name, seed=0).model
    print(f"water pump, {source}: {len(targets)} targets, {stock.path_length_m * 1e3:.0f} mm")
    configs = [("adaptive-pi", "off"), ("constant", "off"), ("adaptive-pi", "online")]
    if not args.quick:
        configs += [(c, "off") for c in MACHINING_CONTROLLERS if (c, "off") not in configs]
    print(
        f"{'controller':<12} {'comp.':<8} {'sim [s]':>8} {'wall [s]':>9} "
        f"{'median x real time':>19} (over {repeats})"
    )
    for controller, mode in configs:
        settings = MachiningSettings(controller=controller, compensation=mode)
        factors, walls = [], []
        for _ in range(repeats):
            t0 = time.perf_counter()
            run = run_machining(robot, targets, normals, stock, settings, compensation_model=model)
            walls.append(time.perf_counter() - t0)
            factors.append(run.summary["sim_time_s"] / walls[-1])
        print(
            f"{controller:<12} {mode:<8} {run.summary['sim_time_s']:8.1f} "
            f"{statistics.median(walls):9.2f} {statistics.median(factors):19.1f}"
        )
    if not args.quick:
        t0 = time.perf_counter()
        result = compare_configurations(
            robot, targets, normals, stock, MachiningSettings(), compensation_model=model
        )
        print(f"\nmatrix of {len(result.runs)} runs: {time.perf_counter() - t0:.1f} s wall\n")
        print(result.table_text)


if __name__ == "__main__":
    main()
