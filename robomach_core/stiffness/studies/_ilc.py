"""The ILC study: arm-side and force ILC over repeated runs of the square."""

from __future__ import annotations

from pathlib import Path

import numpy as np

from ...cell import JointCompliance, Robot, Tool, true_joint_compliance
from .. import plots
from ..ilc import IlcKind, IlcSystem, milling_process_gain, perturbed, run_ilc, square_path
from ..model import cartesian_compliance
from ._common import (
    DEFAULT_OPTIONS,
    ILC_FORCE_DISTURBANCE_N,
    ILC_MODEL_ERRORS,
    ILC_TRACKER_NOISE_M,
    Cancel,
    Progress,
    StudyOptions,
    StudyResult,
    _Progress,
    _work_joints,
    _write_csv,
    study_robot,
    work_position_m,
)
from ._identify import identified_model


def run_ilc_study(
    options: StudyOptions = DEFAULT_OPTIONS,
    out_dir: Path | None = None,
    *,
    model: JointCompliance | None = None,
    progress: Progress | None = None,
    cancel: Cancel | None = None,
) -> StudyResult:
    """Arm-side and force ILC over repeated runs of the Lund paper's square, on its IRB 2400
    by default. ``model``: the stiffness identified on that arm (identified here if None)."""
    report = progress if isinstance(progress, _Progress) else _Progress(progress, cancel)
    share = 0.0
    name = study_robot(options, "ilc")
    if model is None:
        model = identified_model(options, name, report.slice(0.0, 0.3))
        share = 0.3
    truth = true_joint_compliance(name)
    robot = Robot(name, Tool().T_flange_tcp)
    q = _work_joints(robot)
    gain = milling_process_gain()
    truth_system = IlcSystem(cartesian_compliance(robot, q, truth)[:3, :3], gain)
    model_system = perturbed(
        IlcSystem(cartesian_compliance(robot, q, model)[:3, :3], gain), **ILC_MODEL_ERRORS
    )
    side = 0.02 if options.quick else 0.04
    path = square_path(side_m=side, center_m=tuple(work_position_m(name)))
    iterations = min(options.ilc_iterations, 3) if options.quick else options.ilc_iterations
    results = {}
    kinds: tuple[IlcKind, ...] = ("arm", "force")
    for i, kind in enumerate(kinds):
        results[kind] = run_ilc(
            truth_system,
            model_system,
            path,
            kind=kind,
            iterations=iterations,
            tracker_noise_m=ILC_TRACKER_NOISE_M,
            force_disturbance_N=ILC_FORCE_DISTURBANCE_N,
            seed=options.seed,
            progress=report.slice(share + i * (1 - share) / 2, (1 - share) / 2),
            cancel=report.cancelled,
        )
    arm, force = results["arm"], results["force"]
    summary = {
        "ilc_robot": name,
        "ilc_iterations": iterations,
        "ilc_arm_error_per_iteration": arm.error_mean_um.tolist(),
        "ilc_force_error_per_iteration": force.error_mean_um.tolist(),
        "ilc_force_deviation_per_iteration_um": force.deviation_mean_um.tolist(),
        "ilc_arm_normalized_per_iteration": arm.error_normalized.tolist(),
        "ilc_arm_reduction_percent": float(
            100 * (1 - arm.error_mean_um[-1] / arm.error_mean_um[0])
        ),
        "ilc_force_reduction_percent": float(
            100 * (1 - force.error_mean_um[-1] / force.error_mean_um[0])
        ),
        "ilc_force_deviation_reduction_percent": float(
            100 * (1 - force.deviation_mean_um[-1] / force.deviation_mean_um[0])
        ),
        "ilc_offset_um": [v * 1e6 for v in (60e-6, -40e-6, 30e-6)],
        "ilc_force_disturbance_N": ILC_FORCE_DISTURBANCE_N,
        "ilc_tracker_noise_um": ILC_TRACKER_NOISE_M * 1e6,
    }
    arrays = {
        "reference_m": path,
        "arm_errors_m": arm.errors_m,
        "force_errors_m": force.errors_m,
        "arm_correction_m": arm.correction_m,
        "force_correction_m": force.correction_m,
    }
    files: list[Path] = []
    if out_dir is not None:
        out = Path(out_dir)
        it = np.arange(len(arm.error_mean_um))
        files += [
            _write_csv(
                out / "ilc_errors.csv",
                [
                    "iteration",
                    "arm_error_um",
                    "force_error_um",
                    "force_deviation_um",
                    "arm_normalized",
                    "force_normalized",
                ],
                np.column_stack(
                    [
                        it,
                        arm.error_mean_um,
                        force.error_mean_um,
                        force.deviation_mean_um,
                        arm.error_normalized,
                        force.error_normalized,
                    ]
                ),
            ),
            plots.plot_ilc(out / "ilc.png", arm, force),
        ]
    report(1.0)
    return StudyResult("ilc", summary, arrays, tuple(files), {"arm": arm, "force": force})
