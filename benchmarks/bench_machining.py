"""Machining speed (issue 29): the real-time factor of every configuration (at least x1000,
offline compensation's rehearsals included), the 18-run comparison (under 3 s) and a sweep of
100 stocks x 18 runs (under 2 minutes) on every local core.

Run from the repository root on an idle machine:
``python benchmarks/bench_machining.py [--quick] [--repeats N] [--variations N]``.

The program is the water pump's learned one (the headless demo pipeline, defaults, seed 0; it
runs once first and is not timed) or, with ``--quick``, a program along the pump's true wall
(no pipeline). Each configuration runs ``--repeats`` times in this process after one untimed
run that loads the compiled kernels; the median real-time factor (simulated cut time / wall
time of ``run_machining``) is printed, and beside it, for the uncompensated runs, the same cut
through the Python reference loop (``compiled=False``): the ratio of the two holds on a busy
machine, where the factors themselves drop with the load. Then the comparison as
``robomach machine`` runs it (``project.machine``: the matrix on every core, the pool started
as the CLI starts it) and the sweep of ``--variations`` drawn stocks plus the nominal one.
"""

from __future__ import annotations

import argparse
import os
import statistics
import sys
import time
from dataclasses import replace
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from robomach_core import project as core  # noqa: E402
from robomach_core.cell import (
    Robot,  # noqa: E402
    Tool,  # noqa: E402
)
from robomach_core.machining import (  # noqa: E402
    MACHINING_CONTROLLERS,
    MachiningSettings,
    builtin_stock,
    identify_stiffness,
    run_machining,
    targets_along_wall,
    wall_normals_for_workpiece,
)
from robomach_core.machining.parallel import default_workers  # noqa: E402
from robomach_core.machining.run import cut_program  # noqa: E402
from robomach_core.machining.schedule import STAGED_CONTROLLERS  # noqa: E402
from robomach_core.part import builtin_workpiece  # noqa: E402
from robomach_core.stiffness import COMPENSATIONS  # noqa: E402


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--quick", action="store_true", help="program along the true wall")
    parser.add_argument("--repeats", type=int, default=None, help="runs per configuration")
    parser.add_argument("--variations", type=int, default=None, help="drawn stocks of the sweep")
    args = parser.parse_args()
    repeats = args.repeats or (1 if args.quick else 3)
    variations = args.variations if args.variations is not None else (4 if args.quick else 100)
    load = os.getloadavg()[0] if hasattr(os, "getloadavg") else float("nan")
    print(f"{default_workers()} cores, load average {load:.1f} at the start")

    tool = Tool()
    robot = Robot("ur10", tool.T_flange_tcp)
    pump = builtin_workpiece("water_pump")
    project = None
    if args.quick:
        targets = quick_program(robot, tool, pump)
        source = "program along the true wall (--quick)"
    else:
        from robomach_core.pipeline import run_demo
        from robomach_core.project import Project

        t0 = time.perf_counter()
        demo = run_demo(Project())
        targets, project = demo.processed.targets, demo.project
        source = f"learned program (demo pipeline, {time.perf_counter() - t0:.0f} s, not timed)"
    normals = wall_normals_for_workpiece(pump, targets.position_m)
    stock = builtin_stock(targets.position_m, seed=0, wall_normals_m=normals)
    model = identify_stiffness(robot.name, seed=0).model
    print(f"water pump, {source}: {len(targets)} targets, {stock.path_length_m * 1e3:.0f} mm")
    configs = [(c, m, "online") for c in MACHINING_CONTROLLERS for m in COMPENSATIONS]
    # ... and the staged controllers' offline rows with their stages planned (``--stages``).
    configs += [(c, "offline", "planned") for c in STAGED_CONTROLLERS]
    if args.quick:
        configs = [
            ("adaptive-pi", "off", "online"),
            ("constant", "off", "online"),
            ("adaptive-lq", "offline", "online"),
            ("two-stage", "offline", "planned"),
        ]
    print(
        f"{'controller':<12} {'comp.':<8} {'sim [s]':>8} {'wall [ms]':>10} "
        f"{'x real time':>12} {'reference loop':>15} {'compiled / ref':>15}  (median of {repeats})"
    )
    worst = None
    for controller, mode, stages in configs:
        settings = MachiningSettings(controller=controller, compensation=mode, stages=stages)
        run_machining(robot, targets, normals, stock, settings, compensation_model=model)
        factors, walls = [], []
        for _ in range(repeats):
            t0 = time.perf_counter()
            run = run_machining(robot, targets, normals, stock, settings, compensation_model=model)
            walls.append(time.perf_counter() - t0)
            factors.append(run.summary["sim_time_s"] / walls[-1])
        median = statistics.median(factors)
        worst = median if worst is None else min(worst, median)
        reference = ratio = ""
        if mode == "off":
            t0 = time.perf_counter()
            slow = cut_program(robot, targets, normals, stock, settings, compiled=False)
            ref = slow.summary["sim_time_s"] / (time.perf_counter() - t0)
            reference, ratio = f"x{ref:.0f}", f"{median / ref:.1f}"
        if run.summary.get("feed") == "program":
            mode = "planned"  # offline, its stages planned (``machining.schedule``)
        print(
            f"{controller:<12} {mode:<8} {run.summary['sim_time_s']:8.1f} "
            f"{1e3 * statistics.median(walls):10.0f} {median:12.0f} {reference:>15} {ratio:>15}"
        )
    print(f"slowest configuration: x{worst:.0f} real time")
    _same_figures_on_every_core(robot, targets, normals, stock, model, 2 if args.quick else 4)
    if project is None:
        return
    workpiece = core.build_workpiece(project.cell, project.mesh)
    project = core.with_machining_setup(project, core.MachiningSetup(MachiningSettings()))

    def machine(p, label):
        t0 = time.perf_counter()
        result = core.machine(
            p, workpiece, robot, controllers=MACHINING_CONTROLLERS,
            compensations=tuple(COMPENSATIONS), workers=None,
        )  # fmt: skip
        wall = time.perf_counter() - t0
        runs = len(result.rows) * (1 + (p.machining_settings.variations or 0))
        # the staged controllers' offline rows cut with the other stage plan too
        other = sum(1 for r in result.rows if r.get("other_stages"))
        print(
            f"{label}: {runs} runs (+ {other} with the other stage plan) on "
            f"{default_workers()} workers in {wall:.1f} s wall"
        )
        return result

    machine(project, "comparison, first (starts the worker processes)")
    machine(project, "comparison")
    setup = replace(core.machining_setup_of(project), variations=variations)
    machine(core.with_machining_setup(project, setup), f"sweep of {variations} + 1 stocks")
    load = os.getloadavg()[0] if hasattr(os, "getloadavg") else float("nan")
    print(f"load average {load:.1f} at the end")


def quick_program(robot, tool, pump):
    """The ``--quick`` program: the first 61 targets along the pump's true wall (no learning;
    bench_offline_stocks.py's ``--quick`` cuts it too)."""
    targets = targets_along_wall(robot, pump, tool_radius_m=tool.radius_m)
    return type(targets)(**{k: getattr(targets, k)[:61] for k in targets.__dataclass_fields__})


def _same_figures_on_every_core(robot, targets, normals, stock, model, count: int) -> None:
    """A small sweep on one worker and on every core: the same figures, and the speed-up."""
    from robomach_core.machining.parallel import CutTask, run_tasks
    from robomach_core.machining.variation import StockVariation, draw_stocks

    stocks = draw_stocks(stock, count, 0, StockVariation())
    tasks = [
        CutTask(
            robot.name,
            robot.T_flange_tcp,
            targets,
            normals,
            st,
            MachiningSettings(),
            c,
            tuple(COMPENSATIONS),
            model,
        )  # fmt: skip
        for st in stocks
        for c in MACHINING_CONTROLLERS
    ]
    run_tasks(tasks[:2], workers=None)  # start the worker processes
    t0 = time.perf_counter()
    one = run_tasks(tasks, workers=1)
    t_one = time.perf_counter() - t0
    t0 = time.perf_counter()
    many = run_tasks(tasks, workers=None)
    t_many = time.perf_counter() - t0
    same = _figures(one) == _figures(many)
    print(
        f"variations: {count} stocks x 18 runs: 1 worker {t_one:.1f} s, {default_workers()} "
        f"workers {t_many:.1f} s: x{t_one / t_many:.2f} faster (same figures: "
        f"{'yes' if same else 'NO'})"
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
