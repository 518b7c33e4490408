"""``robomach cmrr``: simulate a CMRR feed controller on one of the papers' cuts."""

from __future__ import annotations

import argparse
from pathlib import Path

from app.commands.progress import StageProgress
from robomach_core.cmrr import CONTROLLER_NAMES as CONTROLLERS
from robomach_core.cmrr import SCENARIO_NAMES as SCENARIOS


def add_parser(subparsers: argparse._SubParsersAction) -> None:
    p = subparsers.add_parser(
        "cmrr",
        help="simulate controlled material removal rate (feed control at a force reference)",
        description=(
            "Simulate a cut of --scenario under --controller (or all of them) and write "
            "cmrr.csv, cmrr_summary.json, cmrr.png and cmrr_settings.json into --out."
        ),
    )
    p.add_argument("--scenario", required=True, choices=SCENARIOS, help="the cut to simulate")
    p.add_argument(
        "--controller",
        choices=(*CONTROLLERS, "all"),
        default=None,
        help="feed controller, or all to compare them (default: the paper's for the scenario)",
    )
    p.add_argument("--out", type=Path, default=Path("cmrr-out"), help="output folder")
    p.add_argument("--seed", type=int, default=0, help="seed of the sensor noise")
    p.add_argument(
        "--reference-force-N",
        dest="reference_force_N",
        type=float,
        metavar="N",
        help="force reference (default: the scenario's)",
    )
    p.add_argument(
        "--command-speed-mm-s",
        dest="command_speed_mm_s",
        type=float,
        metavar="MM_S",
        help="programmed (greatest) feed (default: the scenario's)",
    )
    p.add_argument(
        "--feedback",
        choices=("force", "spindle-current"),
        default=None,
        help="feedback signal (default: force)",
    )
    p.add_argument(
        "--settings",
        type=Path,
        metavar="JSON",
        help="controller settings file (as written to cmrr_settings.json) to run instead",
    )
    p.add_argument("--quiet", action="store_true", help="no progress or table on the terminal")
    p.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    from app.cli import settings_file, writable_folder
    from robomach_core.cmrr import (
        build_scenario,
        compare_controllers,
        comparison_table,
        load_settings,
        settings_for,
        write_study_outputs,
    )
    from robomach_core.cmrr.errors import CmrrSettingsError
    from robomach_core.cmrr.settings import check_study_size
    from robomach_core.limits import CMRR_COMMAND_SPEED_MM_S, CMRR_REFERENCE_FORCE_N, SEED

    SEED.check(args.seed, "--seed")
    for value, rng, flag in (
        (args.reference_force_N, CMRR_REFERENCE_FORCE_N, "--reference-force-N"),
        (args.command_speed_mm_s, CMRR_COMMAND_SPEED_MM_S, "--command-speed-mm-s"),
    ):
        if value is not None:
            rng.check(value, flag, error=CmrrSettingsError)
    overrides: dict[str, object] = {}
    controllers: list = []
    if args.settings is not None:
        if args.controller == "all":
            raise CmrrSettingsError("--settings runs one controller; it cannot go with all")
        loaded = load_settings(settings_file(args.settings, "--settings"))
        if args.controller is not None and args.controller != loaded.controller.kind:
            raise CmrrSettingsError(
                f"--controller {args.controller} but {args.settings} holds {loaded.controller.kind}"
            )
        controllers = [loaded.controller]
        overrides.update(
            reference_force_N=loaded.reference_force_N,
            command_speed_mm_s=loaded.command_speed_m_s * 1e3,
            min_speed_ratio=loaded.min_speed_ratio,
            feedback=loaded.feedback,
        )
    if args.reference_force_N is not None:
        overrides["reference_force_N"] = args.reference_force_N
    if args.command_speed_mm_s is not None:
        overrides["command_speed_mm_s"] = args.command_speed_mm_s
    if args.feedback is not None:
        overrides["feedback"] = args.feedback.replace("-", "_")
    scenario = build_scenario(args.scenario, **overrides)

    if not controllers:
        name = args.controller or scenario.default_controller
        names = list(CONTROLLERS) if name == "all" else [name]
        controllers = [settings_for(n) for n in names]
    check_study_size(scenario, len(controllers))
    writable_folder(args.out)

    total = len(controllers)
    label = f"{scenario.name}/" + ("all" if total > 1 else controllers[0].kind)
    bar = StageProgress(quiet=args.quiet)
    try:
        results = compare_controllers(
            scenario, controllers, seed=args.seed, progress=bar.for_stage(label)
        )
    except (ArithmeticError, ValueError, MemoryError) as exc:
        if isinstance(exc, CmrrSettingsError):
            raise
        # Settings inside the ranges can still drive a controller's arithmetic out of bounds.
        raise CmrrSettingsError(
            f"the simulation failed with these settings ({exc.__class__.__name__}: {exc})"
        ) from None
    finally:
        bar.close()
    try:
        paths = write_study_outputs(results, args.out)
    except OSError as exc:
        raise CmrrSettingsError(f"cannot write to {args.out}: {exc.strerror}") from None
    if not args.quiet:
        print(scenario.description)
        print(comparison_table(results))
        print("wrote " + ", ".join(str(p) for p in paths.values()))
    return 0
