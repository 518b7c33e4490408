"""Offline compensation over fresh stocks: the share of the wall error it cuts, per controller.

Issue 29's measure (``machining/offline.py`` LIMIT, ``schedule``): on a demo's program, each
of N built-in stocks drawn from seeds BASE, BASE + 1, ... (new allowance phases and burrs, the
project's path and normals) is cut with compensation off and offline under every controller,
the defaults (seed 0) and the stiffness the seed-0 CMM campaign identifies, as
tests/core/machining/test_acceptance.py's castings test cuts them. Prints per stock and per
controller the median, worst and share under 75 % of 1 - offline / off wall max error, and the
median offline cycle and peak.

    python benchmarks/bench_offline_stocks.py DEMO_DIR [--stocks 20] [--base 2026120500]
        [--stages online|planned]
    python benchmarks/bench_offline_stocks.py --quick   (a short program along the pump's
        true wall, one stock, three controllers: that the script runs, not a measurement)
"""

from __future__ import annotations

import argparse
import json

import numpy as np
from bench_machining import quick_program  # the same --quick program (this folder)

from robomach_core import project as core
from robomach_core.cell import Robot, Tool
from robomach_core.export.target_joints import with_target_joints
from robomach_core.machining import (
    MACHINING_CONTROLLERS,
    STAGE_PLANS,
    MachiningSettings,
    builtin_stock,
    run_machining,
    stiffness_model,
    wall_normals_for_workpiece,
)
from robomach_core.part import builtin_workpiece
from robomach_core.project._machining_cut import build_stock, wall_normals_for_project


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("demo", nargs="?", help="a `robomach demo` output folder (its project.npz)")
    parser.add_argument("--quick", action="store_true", help="see the module docstring")
    parser.add_argument("--stocks", type=int, default=20)
    parser.add_argument("--base", type=int, default=2026120500, help="first stock seed")
    parser.add_argument("--json", default=None, help="write the per-stock figures here")
    parser.add_argument(
        "--stages", choices=STAGE_PLANS, default="online", help="MachiningSettings.stages"
    )
    args = parser.parse_args()
    if args.quick:
        robot, targets, nominal, controllers = _quick()
        args.stocks = 1
    elif args.demo is None:
        parser.error("give a `robomach demo` output folder, or --quick")
    else:
        robot, targets, nominal = _demo(args.demo)
        controllers = MACHINING_CONTROLLERS
    model = stiffness_model(robot.name, MachiningSettings())
    out: dict[str, list] = {c: [] for c in controllers}
    for k in range(args.stocks):
        seed = args.base + k
        stock = builtin_stock(nominal.path_points_m, seed, wall_normals_m=nominal.wall_normals_m)
        line = [f"{robot.name} stock {seed}:"]
        for c in controllers:
            runs = {
                m: run_machining(
                    robot, targets, None, stock,
                    MachiningSettings(controller=c, compensation=m, stages=args.stages),
                    compensation_model=model,
                ).summary
                for m in ("off", "offline")
            }  # fmt: skip
            off, on = runs["off"], runs["offline"]
            if not (off["completed"] and on["completed"]):
                line.append(f"{c} stopped")
                continue
            cut = 100.0 * (1.0 - on["wall_error_max_mm"] / off["wall_error_max_mm"])
            out[c].append(
                {"seed": seed, "cut_pct": cut, "cycle_s": on["cycle_time_s"],
                 "peak_N": on["force_peak_N"], "off_cycle_s": off["cycle_time_s"],
                 "feed": on.get("feed")}
            )  # fmt: skip
            line.append(f"{c} {cut:.1f}%")
        print(" ".join(line), flush=True)
    print(
        f"\n{robot.name}, {args.stocks} stocks from seed {args.base}, stages {args.stages}: "
        "offline % cut"
    )
    for c, rows in out.items():
        cuts = np.array([r["cut_pct"] for r in rows])
        if not cuts.size:
            print(f"  {c:12s} none completed")
            continue
        print(
            f"  {c:12s} median {np.median(cuts):5.1f} %  worst {cuts.min():5.1f} %  "
            f"under 75 %: {int(np.sum(cuts < 75))}/{cuts.size}  "
            f"offline cycle median {np.median([r['cycle_s'] for r in rows]):.1f} s  "
            f"peak max {max(r['peak_N'] for r in rows):.1f} N"
        )
    if args.json:
        with open(args.json, "w") as f:
            json.dump(out, f, indent=1)


def _demo(folder: str):
    """The arm, the demo's program (its targets' joints the arm's IK) and its nominal stock."""
    project = core.load_project_file(f"{folder}/project.npz")
    workpiece = core.build_workpiece(project.cell, project.mesh)
    robot = Robot(project.cell.robot, project.tool().T_flange_tcp)
    processed = core.require_processed(project).result.targets
    normals = wall_normals_for_project(project, workpiece, processed)
    return (
        robot,
        with_target_joints(robot, processed),
        build_stock(project, workpiece, processed, normals),
    )


def _quick():
    """The UR10, 61 targets along the pump's true wall, its stock; constant and the staged."""
    tool = Tool()
    robot = Robot("ur10", tool.T_flange_tcp)
    pump = builtin_workpiece("water_pump")
    targets = quick_program(robot, tool, pump)
    normals = wall_normals_for_workpiece(pump, targets.position_m)
    stock = builtin_stock(targets.position_m, seed=0, wall_normals_m=normals)
    return robot, targets, stock, ("constant", "fuzzy", "two-stage")


if __name__ == "__main__":
    main()
