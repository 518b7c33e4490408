"""``robomach machine``: cut the learned program on the simulated compliant arm (issue 8).

Without ``--from`` it first runs the demo pipeline (``robomach demo``'s, progress on the
terminal); ``--from DIR`` opens the ``project.npz`` a demo wrote there. Then it runs the
chosen controller and compensation, or the matrix (``all``), on the stock and on
``--variations`` stocks drawn from the part's variation (on the local cores, or a Dask
cluster), prints the side-by-side table, chooses a configuration the cell can run
(``robomach_core.machining.choice``) and writes the program files for it, the per-run traces,
the summary, a figure and the project (``project.npz``, with the choice) into ``--out``.
"""

from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path

from robomach_core.machining.choice import OPTION_NAMES as CELL_OPTION_CHOICES
from robomach_core.machining.settings import MACHINING_CONTROLLERS as CONTROLLER_CHOICES
from robomach_core.machining.settings import STAGE_PLANS as STAGE_CHOICES
from robomach_core.machining.settings import MachiningSettings
from robomach_core.stiffness.modes import COMPENSATIONS as COMPENSATION_CHOICES

MESH_STOCK_SUFFIXES = (".stl", ".obj", ".ply")
# Exit codes (also in the README and --help).
EXIT_OK = 0  # the comparison ran and a configuration was chosen and exported (stops included)
# no configuration the cell can run completed within the force limit, the chosen one cannot
# be exported, or the project's program is not fit to machine
EXIT_NOTHING_CHOSEN = 1
EXIT_BAD_INPUT = 2  # a bad argument, file or setting (one line on stderr, nothing written)
EXIT_INTERRUPTED = 130  # Ctrl-C
EXIT_CODES_TEXT = """exit codes:
  0    the comparison ran, a configuration the cell can run was chosen and its program
       written; configurations that stopped (protection rule, force supervision) or were
       refused are rows of the table, not failures
  1    no configuration the cell can run completed within the force limit, the chosen one
       could not be exported, or the project's program is NOT FIT TO MACHINE (a partial run,
       the wrong wall, an overcut: printed above the table): the table and traces are still
       written, no program is
  2    bad input: an argument, file or setting out of range (one line on stderr)
  130  interrupted (Ctrl-C)"""


def add_parser(subparsers: argparse._SubParsersAction) -> None:
    p = subparsers.add_parser(
        "machine",
        epilog=EXIT_CODES_TEXT,
        formatter_class=argparse.RawDescriptionHelpFormatter,
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
        default=MachiningSettings.controller,
        choices=(*CONTROLLER_CHOICES, "all"),
        help="feed control: constant (the greatest safe feed) or a CMRR controller; all "
        "compares them (default %(default)s)",
    )
    p.add_argument(
        "--compensation",
        default=MachiningSettings.compensation,
        choices=(*COMPENSATION_CHOICES, "all"),
        help="deflection compensation: off, offline, online, or all (default %(default)s)",
    )
    p.add_argument(
        "--stages",
        default=MachiningSettings.stages,
        choices=STAGE_CHOICES,
        help="under offline compensation, how fuzzy and two-stage pick their stage: online "
        "(they switch in the cell by the force) or planned (their cuts of the nominal wall fix "
        "the lowest stage every 0.1 mm, the program carries it as its speeds and the cell runs "
        "no feed control: the correction meets the force it was planned for, but a casting "
        "with burrs elsewhere meets them at the planned speeds: --variations shows it) "
        "(default %(default)s)",
    )
    p.add_argument(
        "--force-limit-N",
        dest="force_limit_N",
        type=float,
        default=MachiningSettings.force_limit_N,
        metavar="N",
        help="the force the cut must not exceed in N (default %(default)g; CMRR holds 0.7 of "
        "it): "
        "only configurations whose peak force stays within it are chosen, none if none does",
    )
    p.add_argument(
        "--seed",
        type=int,
        default=0,
        help="seed of the demo run (without --from), the sensor noise and the stiffness "
        "identification; the built-in stock uses the project's seed",
    )
    p.add_argument(
        "--cell-options",
        default="default",
        metavar="LIST",
        help="the cell's controller options, comma-separated from "
        f"{', '.join(CELL_OPTION_CHOICES)}, or none; default: those of the arm's program "
        "language (RAPID: fc_speed_change; URScript: force_mode). Only configurations the cell "
        "can run are chosen",
    )
    p.add_argument(
        "--variations",
        type=int,
        default=0,
        metavar="N",
        help="also cut every configuration's program (designed on the nominal stock: its "
        "feed, controller design and offline correction) on N stocks drawn from the part's "
        "variation (allowance x0.85-1.15, burrs re-drawn, material K x0.9-1.1; seeded by the "
        "project's seed) and choose on the 95th percentiles over the N + 1 stocks (default 0: "
        "the one stock)",
    )
    p.add_argument(
        "--workers",
        type=int,
        default=None,
        metavar="N",
        help="local processes for the cuts (default: every core; 1: in this process)",
    )
    p.add_argument(
        "--cluster",
        default=None,
        metavar="ADDRESS",
        help="a Dask scheduler (tcp://host:8786) to run the cuts on instead of the local "
        "cores (pip install 'robomach[cluster]')",
    )
    p.add_argument("--no-plot", action="store_true", help="skip machining.png")
    p.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    from app.cli import writable_folder
    from app.commands.progress import StageProgress
    from robomach_core import limits
    from robomach_core.errors import InvalidInputError, RobomachError

    limits.SEED.check(args.seed, "--seed")
    limits.MACHINING_FORCE_LIMIT_N.check(args.force_limit_N, "--force-limit-N")
    limits.MACHINING_VARIATIONS.check(args.variations, "--variations")
    if args.workers is not None:
        limits.MACHINING_WORKERS.check(args.workers, "--workers")
    if args.from_dir is not None and args.workpiece is not None:
        raise InvalidInputError("give --workpiece (a new demo run) or --from DIR, not both")
    stock_arg = _stock_argument(args.stock)
    options = _cell_options(args.cell_options)
    writable_folder(args.out)

    from robomach_core import project as core
    from robomach_core.cell import Robot
    from robomach_core.machining import MachiningSettings, plot_runs, write_run_csv

    bar = StageProgress()
    try:
        project = _project(args, bar)
        settings = MachiningSettings(
            force_limit_N=args.force_limit_N, seed=args.seed, stages=args.stages
        )
        setup = core.MachiningSetup(
            settings, **stock_arg, cell_options=options, variations=args.variations
        )
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
            workers=args.workers,
            cluster=args.cluster,
        )
    finally:
        bar.close()
    project = core.with_machining_result(project, result)
    problems = core.require_processed(project).problems()
    chosen = None if result.chosen is None else result.rows[result.chosen]
    if chosen is not None:
        project = core.choose(project, chosen["controller"], chosen["compensation"])
    out: Path = args.out
    written = []
    summary = result.summary()
    summary["problems"] = problems
    summary["settings"] = core.machining_setup_document(core.machining_setup_of(project))
    summary["stock"] = {
        "source": result.stock.source,
        "path_length_mm": result.stock.path_length_m * 1e3,
        "allowance_max_mm": result.stock.max_allowance_m * 1e3,
        "burrs": len(result.stock.burrs),
    }
    for run_ in result.runs:
        written.append(
            write_run_csv(run_, out / f"machining_{run_.controller}_{run_.compensation}.csv")
        )
    export_error = None
    if chosen is not None and not problems:
        try:
            files = core.program_files(project, workpiece, robot)
        except RobomachError as exc:
            export_error = str(exc)
        else:
            for name, text in files.items():
                (out / name).write_text(text)
                written.append(out / name)
            written.append(core.save_project_file(project, out / core.PROJECT_FILE))
    summary["export_error"] = export_error
    path = out / "machining_summary.json"
    path.write_text(json.dumps(summary, indent=2) + "\n")
    written.insert(0, path)
    if not args.no_plot and result.runs:
        shown = _figure_runs(result, chosen)
        title = f"{workpiece.name}: {len(result.runs)} runs, chosen " + (
            "none" if chosen is None else f"{chosen['controller']} / {chosen['compensation']}"
        )
        written.append(plot_runs(shown, out / "machining.png", title=title))
    for problem in problems:
        print(f"NOT FIT TO MACHINE: {problem}")
    if problems:
        print()
    print(result.table_text)
    if chosen is None:
        print(f"\nchosen            none: {result.reason}")
    else:
        print(
            f"\nchosen            {chosen['controller']} / {chosen['compensation']} "
            f"(cycle {chosen['cycle_time_s']:.1f} s, peak {chosen['force_peak_N']:.1f} N, "
            f"wall max {chosen['wall_error_max_mm']:.3f} mm)"
        )
        print(f"why               {result.reason}")
    print(f"rule              {summary['choice_rule']}")
    stopped = [r for r in result.rows if not r["completed"]]
    if stopped:
        print(
            "stopped           "
            + "; ".join(
                f"{r['controller']} / {r['compensation']}: {r.get('stop_reason') or 'stopped'}"
                for r in stopped
            )
        )
    print(f"wrote             {', '.join(p.name for p in written)} in {out}")
    if export_error is not None:
        print(
            f"robomach machine: error: the chosen configuration cannot be exported: {export_error}",
            file=sys.stderr,
        )
    if chosen is None:
        print(f"robomach machine: error: nothing to choose: {result.reason}", file=sys.stderr)
    if problems:
        print(
            "robomach machine: error: the program is not fit to machine (see above); no "
            "program written: " + "; ".join(problems),
            file=sys.stderr,
        )
    failed = chosen is None or export_error is not None or problems
    return EXIT_NOTHING_CHOSEN if failed else EXIT_OK


def _cell_options(value: str) -> tuple[str, ...] | None:
    """``--cell-options``: None for the language's defaults, else the options."""
    from robomach_core.errors import InvalidInputError

    text = value.strip().lower()
    if text in ("", "default"):
        return None
    if text == "none":
        return ()
    names = tuple(v.strip() for v in text.split(",") if v.strip())
    unknown = [n for n in names if n not in CELL_OPTION_CHOICES]
    if unknown:
        raise InvalidInputError(
            f"--cell-options: unknown option(s) {', '.join(unknown)}; choose from "
            f"{', '.join(CELL_OPTION_CHOICES)}, none or default"
        )
    return names


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
        from robomach_core.pipeline import run_demo

        if Path(args.workpiece or "").suffix:  # a mesh: its guide points come with the demo
            raise InvalidInputError(
                f"--workpiece {args.workpiece}: a mesh needs guide points; run `robomach demo "
                "--workpiece FILE --guide-points CSV --out DIR`, then `robomach machine --from DIR`"
            )

        job = core.with_cell(core.Project(), workpiece=args.workpiece, seed=args.seed)
        result = run_demo(job, progress=bar)
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


def _figure_runs(result, chosen: dict | None) -> list:
    """At most four runs for the figure: constant and the default controller (the self-tuning
    PI) without compensation, the chosen run and the chosen controller without compensation."""
    wanted = [("constant", "off"), (MachiningSettings.controller, "off")]
    if chosen is not None:
        wanted += [(chosen["controller"], "off"), (chosen["controller"], chosen["compensation"])]
    runs = []
    for c, m in wanted:
        run_ = result.run_for(c, m)
        if run_ is not None and run_ not in runs:
            runs.append(run_)
    return runs or list(result.runs[:4])
