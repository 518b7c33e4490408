"""``robomach machine``: cut the learned program on the simulated compliant arm (issue 8).

Without ``--from`` it first runs the demo pipeline (``robomach demo``'s, progress on the
terminal); ``--from DIR`` opens the ``project.npz`` a demo wrote there. Then it runs the
chosen controller and compensation, or the matrix (``all``), prints the side-by-side table,
chooses a configuration (``robomach_core.project.best_row``) and writes the program files for
it, the per-run traces, the summary, a figure and the project (``project.npz``, with the
choice) into ``--out``.
"""

from __future__ import annotations

import argparse
import json
from pathlib import Path

CONTROLLER_CHOICES = ("constant", "fixed-pi", "adaptive-pi", "fuzzy", "two-stage", "adaptive-lq")
COMPENSATION_CHOICES = ("off", "offline", "online")
MESH_STOCK_SUFFIXES = (".stl", ".obj", ".ply")


def add_parser(subparsers: argparse._SubParsersAction) -> None:
    p = subparsers.add_parser(
        "machine",
        help="simulate the machining run of the learned program: CMRR and compensation compared",
        description=(
            "Cut the project's program along its stock on the simulated compliant robot at 4 ms: "
            "the process force from the depth met (chapter eq. 3-6), the arm bending under it, "
            "the feed controlled by CMRR and the deflection compensated. Writes "
            "machining_summary.json, machining_<controller>_<compensation>.csv per run, "
            "program.mod (and the other program files) for the chosen configuration, "
            "machining.png and project.npz into --out, and prints the comparison table."
        ),
    )
    p.add_argument("--out", required=True, type=Path, help="output folder (created if missing)")
    p.add_argument(
        "--from",
        dest="from_dir",
        type=Path,
        metavar="DEMO_OUT_DIR",
        help="a `robomach demo --out` folder: machine its project.npz instead of running the "
        "demo first",
    )
    p.add_argument(
        "--workpiece",
        default=None,
        help="without --from: water_pump (default) or block for the demo run (for a mesh FILE "
        "run `robomach demo --guide-points` first, then --from)",
    )
    p.add_argument(
        "--stock",
        default="builtin",
        metavar="builtin|FILE",
        help="the part before machining: builtin (from the project's seed, default), an "
        "allowance profile CSV (rows s_mm,allowance_mm along the path) or a stock mesh "
        "(STL/OBJ/PLY in mm, in the workpiece's frame)",
    )
    p.add_argument(
        "--controller",
        default="adaptive-pi",
        choices=(*CONTROLLER_CHOICES, "all"),
        help="feed control: constant (the greatest safe feed) or a CMRR controller; all "
        "compares them (default adaptive-pi)",
    )
    p.add_argument(
        "--compensation",
        default="off",
        choices=(*COMPENSATION_CHOICES, "all"),
        help="deflection compensation: off (default), offline, online, or all",
    )
    p.add_argument(
        "--force-limit-N",
        dest="force_limit_N",
        type=float,
        default=150.0,
        metavar="N",
        help="the force the cut must not exceed in N (default 150; CMRR holds 0.7 of it)",
    )
    p.add_argument(
        "--seed",
        type=int,
        default=0,
        help="seed of the demo run (without --from), the sensor noise and the stiffness "
        "identification; the built-in stock uses the project's seed",
    )
    p.add_argument("--no-plot", action="store_true", help="skip machining.png")
    p.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    from app.cli import writable_folder
    from app.commands.demo import _ProgressLine
    from robomach_core import limits
    from robomach_core.errors import InvalidInputError

    limits.SEED.check(args.seed, "--seed")
    limits.MACHINING_FORCE_LIMIT_N.check(args.force_limit_N, "--force-limit-N")
    if args.from_dir is not None and args.workpiece is not None:
        raise InvalidInputError("give --workpiece (a new demo run) or --from DIR, not both")
    stock_arg = _stock_argument(args.stock)
    writable_folder(args.out)

    from robomach_core import project as core
    from robomach_core.machining import MachiningSettings, plot_runs, write_run_csv
    from robomach_core.robot import Robot

    bar = _ProgressLine()
    try:
        project = _project(args, bar)
        settings = MachiningSettings(force_limit_N=args.force_limit_N, seed=args.seed)
        setup = core.MachiningSetup(settings, **stock_arg)
        project = core.with_machining_setup(project, setup)
        workpiece = core.build_workpiece(project.cell, project.mesh)
        robot = Robot(project.cell.robot, project.tool().T_flange_tcp)
        controllers = CONTROLLER_CHOICES if args.controller == "all" else (args.controller,)
        compensations = COMPENSATION_CHOICES if args.compensation == "all" else (args.compensation,)
        result = core.machine(
            project,
            workpiece,
            robot,
            controllers=controllers,
            compensations=compensations,
            progress=lambda f: bar("machining", f),
        )
    finally:
        bar.close()
    chosen = result.rows[result.chosen]
    project = core.choose(
        core.with_machining_result(project, result), chosen["controller"], chosen["compensation"]
    )
    out: Path = args.out
    written = []
    summary = result.summary()
    summary["settings"] = core.machining_setup_document(core.machining_setup_of(project))
    summary["stock"] = {
        "source": result.stock.source,
        "path_length_mm": result.stock.path_length_m * 1e3,
        "allowance_max_mm": result.stock.max_allowance_m * 1e3,
        "burrs": len(result.stock.burrs),
    }
    path = out / "machining_summary.json"
    path.write_text(json.dumps(summary, indent=2) + "\n")
    written.append(path)
    for run_ in result.runs:
        written.append(
            write_run_csv(run_, out / f"machining_{run_.controller}_{run_.compensation}.csv")
        )
    files = core.program_files(project, workpiece, robot)
    for name, text in files.items():
        (out / name).write_text(text)
        written.append(out / name)
    written.append(core.save_project_file(project, out / core.PROJECT_FILE))
    if not args.no_plot:
        shown = _figure_runs(result, chosen)
        written.append(
            plot_runs(
                shown,
                out / "machining.png",
                title=f"{workpiece.name}: {len(result.runs)} runs, chosen "
                f"{chosen['controller']} / {chosen['compensation']}",
            )
        )
    print(result.table_text)
    print(
        f"\nchosen            {chosen['controller']} / {chosen['compensation']} "
        f"(cycle {chosen['cycle_time_s']:.1f} s, peak {chosen['force_peak_N']:.1f} N, "
        f"wall max {chosen['wall_error_max_mm']:.3f} mm)"
        if chosen["cycle_time_s"] is not None
        else f"\nchosen            {chosen['controller']} / {chosen['compensation']} (stopped)"
    )
    print(f"rule              {summary['choice_rule']}")
    print(f"wrote             {', '.join(p.name for p in written)} in {out}")
    return 0 if all(r["completed"] for r in result.rows) else 1


def _stock_argument(value: str) -> dict:
    """MachiningSetup keyword arguments of ``--stock``."""
    from robomach_core.errors import InvalidInputError

    if value == "builtin":
        return {}
    path = Path(value)
    if not path.is_file():
        raise InvalidInputError(f"--stock {value}: no such file (or give builtin)")
    suffix = path.suffix.lower()
    if suffix in MESH_STOCK_SUFFIXES:
        return {"stock_source": "mesh", "stock_mesh": (path.name, path.read_bytes())}
    if suffix != ".csv":
        raise InvalidInputError(
            f"--stock {value}: expected builtin, a profile .csv or a mesh "
            f"({', '.join(MESH_STOCK_SUFFIXES)})"
        )
    rows = []
    for k, line in enumerate(path.read_text(errors="replace").splitlines(), 1):
        cells = [c.strip() for c in line.split(",")]
        if not line.strip() or line.lstrip().startswith("#"):
            continue
        try:
            rows.append((float(cells[0]), float(cells[1])))
        except (ValueError, IndexError):
            if not rows and k == 1:
                continue  # a header
            raise InvalidInputError(
                f"--stock {value}: line {k}: expected s_mm,allowance_mm"
            ) from None
    if not rows:
        raise InvalidInputError(f"--stock {value}: no (s_mm, allowance_mm) rows")
    return {"stock_source": "profile", "stock_profile_mm": tuple(rows)}


def _project(args: argparse.Namespace, bar):
    """The project to machine: the demo folder's project.npz, or a fresh demo run."""
    from robomach_core import project as core
    from robomach_core.errors import InvalidInputError

    if args.from_dir is not None:
        folder: Path = args.from_dir
        if not folder.is_dir():
            raise InvalidInputError(f"--from {folder}: no such folder")
        path = folder / core.PROJECT_FILE
        if not path.is_file():
            raise InvalidInputError(
                f"--from {folder}: no {core.PROJECT_FILE} there; it is written by "
                "`robomach demo --out DIR` (run the demo again with this version)"
            )
        project = core.load_project_file(path)
    else:
        from robomach_core.pipeline import DemoSettings, run_demo

        if Path(args.workpiece or "").suffix:  # a mesh: its guide points come with the demo
            raise InvalidInputError(
                f"--workpiece {args.workpiece}: a mesh needs guide points; run `robomach demo "
                "--workpiece FILE --guide-points CSV --out DIR`, then `robomach machine --from DIR`"
            )

        result = run_demo(
            DemoSettings(workpiece=args.workpiece or "water_pump", seed=args.seed), progress=bar
        )
        project = result.project
    status = project.status()
    if status["postprocess"] != "current":
        raise InvalidInputError(
            "the project has no current post-processed program: "
            + (
                project.stale_reasons().get("postprocess")
                or "run path learning and post-processing"
            )
        )
    return project


def _figure_runs(result, chosen: dict) -> list:
    """At most four runs for the figure: constant and the self-tuning PI without compensation,
    the chosen run and the chosen controller without compensation."""
    wanted = [
        ("constant", "off"),
        ("adaptive-pi", "off"),
        (chosen["controller"], "off"),
        (chosen["controller"], chosen["compensation"]),
    ]
    runs = []
    for c, m in wanted:
        run_ = result.run_for(c, m)
        if run_ is not None and run_ not in runs:
            runs.append(run_)
    return runs or list(result.runs[:4])
