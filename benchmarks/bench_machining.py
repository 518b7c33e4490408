"""Real-time factor of every machining run (issue 16: at least x100), the 18-run matrix (under
15 s) and a variation sweep on every core against one worker (at least 1.7 x on 2 cores).

Run from the repository root on an idle machine:
``python benchmarks/bench_machining.py [--quick] [--repeats N] [--variations N]``.

The program is the water pump's learned one (the headless demo pipeline, defaults, seed 0; it
runs once first and is not timed) or, with ``--quick``, a program along the pump's true wall
(no pipeline). The stock is the built-in one, seed 0. Each configuration runs ``--repeats``
times in this process (the first run of a controller compiles its kernels and is not counted);
the median real-time factor (simulated cut time / wall time of ``run_machining``, offline
compensation's rehearsals included) is printed. Then the matrix through
``project.machine``-like tasks on every core, and the sweep of ``--variations`` stocks per
configuration on one worker and on every core.
"""

from __future__ import annotations

import argparse
import statistics
import sys
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from robomach_core.machining import (  # noqa: E402
    COMPENSATION_NAMES,
    MACHINING_CONTROLLERS,
    MachiningSettings,
    builtin_stock,
    identify_stiffness,
    run_machining,
    targets_along_wall,
    wall_normals_for_workpiece,
)
from robomach_core.machining.parallel import CutTask, default_workers, run_tasks  # noqa: E402
from robomach_core.machining.variation import StockVariation, draw_stocks  # noqa: E402
from robomach_core.robot import Robot  # noqa: E402
from robomach_core.tool import Tool  # noqa: E402
from robomach_core.workpiece import builtin_workpiece  # noqa: E402


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--quick", action="store_true", help="program along the true wall")
    parser.add_argument("--repeats", type=int, default=None, help="runs per configuration")
    parser.add_argument("--variations", type=int, default=None, help="stocks of the sweep")
    args = parser.parse_args()
    repeats = args.repeats or (1 if args.quick else 3)
    variations = args.variations or (1 if args.quick else 20)

    tool = Tool()
    robot = Robot("ur10", tool.T_flange_tcp)
    pump = builtin_workpiece("water_pump")
    if args.quick:
        targets = targets_along_wall(robot, pump, tool_radius_m=tool.radius_m)
        targets = type(targets)(
            **{k: getattr(targets, k)[:61] for k in targets.__dataclass_fields__}
        )
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
    configs = [(c, m) for c in MACHINING_CONTROLLERS for m in COMPENSATION_NAMES]
    if args.quick:
        configs = [("adaptive-pi", "off"), ("constant", "off"), ("adaptive-lq", "offline")]
    print(
        f"{'controller':<12} {'comp.':<8} {'sim [s]':>8} {'wall [s]':>9} "
        f"{'median x real time':>19} (over {repeats})"
    )
    worst = None
    warm = set()
    for controller, mode in configs:
        settings = MachiningSettings(controller=controller, compensation=mode)
        if controller not in warm:  # compile the controller's kernels, fill the LQ designs
            run_machining(robot, targets, normals, stock, settings, compensation_model=model)
            warm.add(controller)
        factors, walls = [], []
        for _ in range(repeats):
            t0 = time.perf_counter()
            run = run_machining(robot, targets, normals, stock, settings, compensation_model=model)
            walls.append(time.perf_counter() - t0)
            factors.append(run.summary["sim_time_s"] / walls[-1])
        median = statistics.median(factors)
        worst = median if worst is None else min(worst, median)
        print(
            f"{controller:<12} {mode:<8} {run.summary['sim_time_s']:8.1f} "
            f"{statistics.median(walls):9.2f} {median:19.1f}"
        )
    print(f"slowest configuration: x{worst:.0f} real time")

    def tasks(stocks):
        return [
            CutTask(
                robot.name,
                robot.T_flange_tcp,
                targets,
                normals,
                st,
                MachiningSettings(),
                c,
                tuple(COMPENSATION_NAMES),
                model,
            )  # fmt: skip
            for st in stocks
            for c in MACHINING_CONTROLLERS
        ]

    cores = default_workers()
    if not args.quick:
        t0 = time.perf_counter()
        run_tasks(tasks([stock]), workers=None)
        print(f"matrix of 18 runs on {cores} workers: {time.perf_counter() - t0:.1f} s wall")
    stocks = draw_stocks(stock, variations, 0, StockVariation())
    t0 = time.perf_counter()
    one = run_tasks(tasks(stocks), workers=1)
    t_one = time.perf_counter() - t0
    t0 = time.perf_counter()
    many = run_tasks(tasks(stocks), workers=None)
    t_many = time.perf_counter() - t0
    same = _figures(one) == _figures(many)
    print(
        f"variations: {variations} stocks x 18 runs: 1 worker {t_one:.1f} s, {cores} workers "
        f"{t_many:.1f} s: x{t_one / t_many:.2f} faster (same figures: {'yes' if same else 'NO'})"
    )


def _figures(results) -> list:
    """The runs' figures without the wall-clock ones (which differ from run to run)."""
    timing = ("wall_time_s", "realtime_factor")
    return [
        {k: v for k, v in s.items() if k not in timing} if s is not None else None
        for task in results
        for _, s, _ in task
    ]


if __name__ == "__main__":
    main()
