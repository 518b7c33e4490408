"""``robomach compensate``: robot stiffness, deformation compensation and ILC studies."""

from __future__ import annotations

import argparse
from pathlib import Path
from typing import get_args

from app.commands.progress import StageProgress
from robomach_core.stiffness.modes import COMPENSATIONS, OFFLINE_MODELS
from robomach_core.stiffness.studies import StudyName, StudyOptions

STUDY_CHOICES = get_args(StudyName)


def add_parser(subparsers: argparse._SubParsersAction) -> None:
    p = subparsers.add_parser(
        "compensate",
        help="identify the arm's stiffness and simulate deflection compensation and ILC",
        description=(
            "Simulate the stiffness identification (CMM under known loads), the F/T gravity "
            "compensation, the chapter's end-milling block and the Lund face-milling pass with "
            "and without deflection compensation, iterative learning control and the "
            "compliance paper's KR 270 line, each on its paper's arm (the chapter's on the IRB "
            "6640, its IRB 6400 having no published kinematics; the Lund papers' on the IRB "
            "2400; the compliance paper's on the KR 270) unless --robot names one. Writes CSVs, "
            "PNG plots, compensation_summary.json and compensation_settings.json into --out."
        ),
    )
    p.add_argument(
        "--study", choices=STUDY_CHOICES, default="all", help="which study to run (default all)"
    )
    p.add_argument(
        "--out",
        type=Path,
        default=Path("compensation"),
        help="output folder, created if missing (default ./compensation)",
    )
    from robomach_core.cell import ROBOT_NAMES
    from robomach_core.stiffness.studies import PAPER_ARMS

    papers = ", ".join(f"{study} {arm}" for study, arm in PAPER_ARMS.items())
    p.add_argument(
        "--robot",
        default=None,
        metavar="|".join(ROBOT_NAMES),
        help=f"run every study on this arm (default: each on its paper's: {papers})",
    )
    p.add_argument("--seed", type=int, default=0, help="seed of every random element")
    p.add_argument(
        "--cmm-noise",
        type=float,
        default=StudyOptions.cmm_noise_um,
        metavar="UM",
        help="CMM noise per axis in um (the chapter: 10-50; default %(default)g)",
    )
    p.add_argument(
        "--poses",
        type=int,
        default=StudyOptions.identification_poses,
        help="poses of the identification campaign (default %(default)s)",
    )
    p.add_argument(
        "--iterations",
        type=int,
        default=StudyOptions.ilc_iterations,
        help="ILC iterations (default %(default)s)",
    )
    p.add_argument(
        "--mode",
        default=StudyOptions.mode,
        metavar="{" + ",".join(COMPENSATIONS) + "}",
        help="compensation written to compensation_settings.json (default %(default)s): off, "
        "offline (targets corrected before the run) or online (from the measured force); "
        "the old spellings offline_linear and offline_nonlinear still read as offline with "
        "that model",
    )
    p.add_argument(
        "--offline-model",
        choices=OFFLINE_MODELS,
        default=None,
        help="how offline compensation corrects the targets, in the settings and "
        f"milling_compensated.mod: linear (t0 - C W) or nonlinear (eq. 32); default "
        f"{StudyOptions.offline_model}, or the old --mode spelling's",
    )
    p.add_argument(
        "--rapid",
        action="store_true",
        help="also write milling_compensated.mod with offline-compensated robtargets",
    )
    p.add_argument(
        "--quick",
        action="store_true",
        help="shorter cuts and fewer poses: a preview in a few seconds",
    )
    p.set_defaults(func=run)


def _report(summary: dict) -> list[str]:
    """The numbers next to the papers', one line each."""
    lines = []
    if "stiffness_rel_error_max" in summary:
        lines.append(
            f"stiffness ({summary['identify_robot']}): max relative error "
            f"{summary['stiffness_rel_error_max'] * 100:.1f} % "
            f"(joints 1-5: {summary['stiffness_rel_error_max_joints_1_to_5'] * 100:.1f} %); "
            f"prediction error max {summary['prediction_error_max_mm']:.3f} mm "
            "(chapter: < 0.04 mm)"
        )
    if "gravity_residual_max_N" in summary:
        lines.append(
            f"gravity: mass {summary['tool_mass_identified_kg']:.3f} kg "
            f"(true {summary['tool_mass_true_kg']:.3f}); residual max "
            f"{summary['gravity_residual_max_N']:.2f} N"
        )
    if "error_max_uncompensated_um" in summary:
        lines.append(
            f"end milling ({summary['milling_robot']}): max error "
            f"{summary['error_max_uncompensated_um']:.0f} um -> "
            f"{summary['error_max_compensated_online_um']:.0f} online, "
            f"{summary['error_max_compensated_linear_um']:.0f} offline linear, "
            f"{summary['error_max_compensated_nonlinear_um']:.0f} offline non-linear "
            "(chapter: 400 -> < 100 um)"
        )
        lines.append(
            f"face milling ({summary['face_milling_robot']}): max "
            f"{summary['face_error_max_uncompensated_um']:.1f} -> "
            f"{summary['face_error_max_compensated_um']:.1f} um, std "
            f"{summary['face_error_std_uncompensated_um']:.1f} -> "
            f"{summary['face_error_std_compensated_um']:.1f} um (Lund: 273.9 -> 51.4, "
            "37.9 -> 18.6)"
        )
    if "compliance_max_ratio" in summary:
        lines.append(
            f"compliance paper ({summary['compliance_robot']}, Table 1): static "
            f"{summary['compliance_static_uncompensated_um']:.1f} -> "
            f"{summary['compliance_static_compensated_um']:.2f} um, max "
            f"{summary['compliance_max_uncompensated_um']:.1f} -> "
            f"{summary['compliance_max_compensated_um']:.2f} um (ratio "
            f"{summary['compliance_max_ratio']:.3f}; identified stiffness "
            f"{summary['compliance_max_ratio_identified']:.3f}; paper 58.1 -> 0.14, "
            f"63.2 -> 4.70 um, ratio {summary['compliance_paper_max_ratio']:.3f})"
        )
    if "ilc_arm_error_per_iteration" in summary:
        arm = ", ".join(f"{e:.0f}" for e in summary["ilc_arm_error_per_iteration"])
        force = ", ".join(f"{e:.0f}" for e in summary["ilc_force_error_per_iteration"])
        lines.append(f"ILC ({summary['ilc_robot']}) arm-side mean error per iteration [um]: {arm}")
        lines.append(
            f"ILC force mean error per iteration [um]: {force} (around the offset: "
            f"-{summary['ilc_force_deviation_reduction_percent']:.0f} %; paper: -85 % / -50 %)"
        )
    return lines


def run(args: argparse.Namespace) -> int:
    from app.cli import writable_folder
    from robomach_core.limits import CMM_NOISE_UM, IDENTIFICATION_POSES, ILC_ITERATIONS, SEED
    from robomach_core.stiffness import read_compensation

    SEED.check(args.seed, "--seed")
    CMM_NOISE_UM.check(args.cmm_noise, "--cmm-noise")
    IDENTIFICATION_POSES.check(args.poses, "--poses")
    ILC_ITERATIONS.check(args.iterations, "--iterations")
    mode, offline_model = read_compensation(args.mode, args.offline_model, name="--mode")
    writable_folder(args.out)

    from robomach_core.stiffness.studies import SUMMARY_FILE, StudyOptions, run_studies

    options = StudyOptions(
        robot=args.robot,
        seed=args.seed,
        cmm_noise_um=args.cmm_noise,
        identification_poses=args.poses,
        ilc_iterations=args.iterations,
        mode=mode,
        offline_model=offline_model,
        rapid=args.rapid,
        quick=args.quick,
    )
    bar = StageProgress(step=0.1)
    try:
        results = run_studies(
            args.study, args.out, options, progress=bar.for_stage(f"compensate {args.study}")
        )
    finally:
        bar.close()
    summary: dict = {}
    for result in results.values():
        summary.update(result.summary)
    for line in _report(summary):
        print(line)
    files = sum(len(r.files) for r in results.values())
    print(f"wrote {files} files and {SUMMARY_FILE} to {args.out}")
    return 0
