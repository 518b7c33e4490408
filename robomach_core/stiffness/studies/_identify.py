"""The identification study: CMM campaign, eq. (23), prediction error, non-linear model."""

from __future__ import annotations

from dataclasses import replace
from pathlib import Path

import numpy as np

from ...cell import JointCompliance, Robot, Tool, true_joint_compliance
from ...transforms import pose_error
from .. import plots
from ..compensation import compensate_targets_and_joints
from ..identification import (
    DEFAULT_LOADS_N,
    DEFAULT_TOOL_LOADS_N,
    StiffnessIdentification,
    StiffnessMeasurements,
    campaign_box,
    prediction_errors,
    sample_workspace_joints,
    stiffness_campaign,
)
from ..milling import (
    CHAPTER_END_MILLING,
)
from ..model import cartesian_compliance, loaded_equilibrium
from ..modes import OfflineModel
from ._common import (
    DEFAULT_OPTIONS,
    Cancel,
    Progress,
    StudyOptions,
    StudyResult,
    _chapter_wrenches,
    _Progress,
    _work_joints,
    _write_csv,
    study_robot,
)


def run_identification_study(
    options: StudyOptions = DEFAULT_OPTIONS,
    out_dir: Path | None = None,
    *,
    progress: Progress | None = None,
    cancel: Cancel | None = None,
) -> StudyResult:
    """Simulated CMM campaign, Kq by eq. (23), prediction error over the workspace, and the
    non-linear model next to the linear one."""
    report = progress if isinstance(progress, _Progress) else _Progress(progress, cancel)
    name = study_robot(options, "identify")
    tool_robot = Robot(name, Tool().T_flange_tcp)  # unknown names fail here
    truth = true_joint_compliance(name)
    center, half = campaign_box(name)  # above the work position, grown with the arm
    n_poses = (
        min(options.identification_poses, 12) if options.quick else options.identification_poses
    )
    n_test = min(options.test_poses, 10) if options.quick else options.test_poses
    report(0.2)
    data, ident = stiffness_campaign(
        name, poses=n_poses, seed=options.seed, cmm_noise_m=options.cmm_noise_um * 1e-6,
    )  # fmt: skip
    report(0.5)
    test_joints = sample_workspace_joints(
        tool_robot, n_test, seed=options.seed + 1, center_m=center, half_size_m=half
    )
    wrenches = _chapter_wrenches(n_test, options.seed + 2)
    errors = prediction_errors(tool_robot, test_joints, wrenches, ident.model, truth)
    report(0.8)

    q_work, nl = _linear_vs_nonlinear(tool_robot, truth)
    report(0.95)

    k_true = np.asarray(truth.stiffness_Nm_rad)
    k_id = np.asarray(ident.model.stiffness_Nm_rad)
    rel = k_id / k_true - 1.0
    summary = {
        "robot": name,
        "identify_robot": name,
        "cmm_noise_um": options.cmm_noise_um,
        "identification_poses": int(n_poses),
        "identification_loads": len(DEFAULT_LOADS_N) + len(DEFAULT_TOOL_LOADS_N),
        "identification_spheres": (
            1 if data.sphere_offsets_m is None else int(data.sphere_offsets_m.shape[0])
        ),
        "stiffness_true_Nm_rad": k_true.tolist(),
        "stiffness_identified_Nm_rad": k_id.tolist(),
        "stiffness_std_Nm_rad": ident.standard_error_Nm_rad.tolist(),
        "stiffness_rel_error_per_joint": rel.tolist(),
        "stiffness_rel_error_max": float(np.max(np.abs(rel))),
        "stiffness_rel_error_max_joints_1_to_5": float(np.max(np.abs(rel[:5]))),
        "identification_residual_rms_um": ident.residual_rms_m * 1e6,
        "prediction_error_max_mm": float(errors.max() * 1e3),
        "prediction_error_mean_mm": float(errors.mean() * 1e3),
        "prediction_test_poses": int(n_test),
        "nonlinear_minus_linear_at_chapter_load_um": float(nl["gap_at_m"][0] * 1e6),
        "nonlinear_minus_linear_at_10x_chapter_load_um": float(nl["gap_at_m"][1] * 1e6),
        "deflection_at_chapter_load_um": float(
            np.linalg.norm(
                (
                    cartesian_compliance(tool_robot, q_work, truth)
                    @ CHAPTER_END_MILLING.nominal_wrench()
                )[:3]
            )
            * 1e6
        ),
    }
    arrays = {
        "stiffness_true_Nm_rad": k_true,
        "stiffness_identified_Nm_rad": k_id,
        "stiffness_std_Nm_rad": ident.standard_error_Nm_rad,
        "measurement_joints_rad": data.joints_rad,
        "measurement_force_N": data.force_N,
        "measurement_displacement_m": data.displacement_m,
        "prediction_error_m": errors,
        "load_N": nl["load_N"],
        "nonlinear_minus_linear_m": nl["gap_m"],
        "landing_error_linear_m": nl["landing_linear_m"],
        "landing_error_nonlinear_m": nl["landing_nonlinear_m"],
    }
    files: list[Path] = []
    if out_dir is not None:
        files = _write_identification_files(
            Path(out_dir), data, ident, k_true, test_joints, wrenches, errors, nl
        )
    report(1.0)
    return StudyResult("identify", summary, arrays, tuple(files), {"identification": ident})


def _linear_vs_nonlinear(
    robot: Robot, truth: JointCompliance
) -> tuple[np.ndarray, dict[str, np.ndarray]]:
    """The linear and the non-linear stiffness model side by side at the work pose, under a
    load growing along the chapter's wrench direction (10 N to 10 kN): how far the two
    equilibria lie apart (chapter eq. 16-19 against the compliance paper's eq. 6), and how far
    from the target each offline compensation (t_0 - C W, or the iteration of eq. 32) lands
    the tool on the true arm. Returns the work joints and
    ``load_N``, ``gap_m``, ``landing_linear_m``, ``landing_nonlinear_m`` and ``gap_at_m`` (the
    gap at the chapter's load and at ten times it) [m]."""
    q_work = _work_joints(robot)
    T_work = robot.fk(q_work).copy()
    direction = CHAPTER_END_MILLING.nominal_wrench()
    direction = direction / np.linalg.norm(direction[:3])
    loads = np.logspace(1, 4, 7)
    gap: list[float] = []
    landing_lin: list[float] = []
    landing_nl: list[float] = []
    mode: OfflineModel
    for load in loads:
        W = direction * load
        lin = loaded_equilibrium(robot, q_work, W, truth, mode="linear")
        nl = loaded_equilibrium(robot, q_work, W, truth)
        gap.append(float(np.linalg.norm(pose_error(lin.T_base_tcp, nl.T_base_tcp)[:3])))
        for mode, landings in (("linear", landing_lin), ("nonlinear", landing_nl)):
            _, q = compensate_targets_and_joints(
                robot, T_work[None], q_work[None], W[None], truth, mode
            )
            landed = loaded_equilibrium(robot, q[0], W, truth).T_base_tcp
            landings.append(float(np.linalg.norm(pose_error(landed, T_work)[:3])))
    chapter_load = float(np.linalg.norm(CHAPTER_END_MILLING.nominal_wrench()[:3]))
    gap_at = []
    for scale in (1.0, 10.0):
        W = direction * chapter_load * scale
        T_lin = loaded_equilibrium(robot, q_work, W, truth, mode="linear").T_base_tcp
        T_nl = loaded_equilibrium(robot, q_work, W, truth).T_base_tcp
        gap_at.append(float(np.linalg.norm(pose_error(T_lin, T_nl)[:3])))
    return q_work, {
        "load_N": loads,
        "gap_m": np.array(gap),
        "landing_linear_m": np.array(landing_lin),
        "landing_nonlinear_m": np.array(landing_nl),
        "gap_at_m": np.array(gap_at),
    }


def _write_identification_files(
    out: Path,
    data: StiffnessMeasurements,
    ident: StiffnessIdentification,
    k_true: np.ndarray,
    test_joints: np.ndarray,
    wrenches: np.ndarray,
    errors: np.ndarray,
    nl: dict[str, np.ndarray],
) -> list[Path]:
    """The study's CSVs (stiffness per joint, the CMM measurements, the prediction errors at
    the test poses, linear vs non-linear) and its two plots."""
    k_id = np.asarray(ident.model.stiffness_Nm_rad)
    rel = k_id / k_true - 1.0
    loads, gap = nl["load_N"], nl["gap_m"]
    landing_lin, landing_nl = nl["landing_linear_m"], nl["landing_nonlinear_m"]
    return [
        _write_csv(
            out / "identification_stiffness.csv",
            ["joint", "true_Nm_rad", "identified_Nm_rad", "std_Nm_rad", "rel_error"],
            np.column_stack([np.arange(1, 7), k_true, k_id, ident.standard_error_Nm_rad, rel]),
        ),
        _write_csv(
            out / "identification_measurements.csv",
            [f"q{i}_deg" for i in range(1, 7)]
            + ["fx_N", "fy_N", "fz_N", "dx_mm", "dy_mm", "dz_mm"],
            np.column_stack([np.degrees(data.joints_rad), data.force_N, data.displacement_m * 1e3]),
        ),
        _write_csv(
            out / "identification_prediction_errors.csv",
            [f"q{i}_deg" for i in range(1, 7)] + ["fx_N", "fy_N", "fz_N", "error_mm"],
            np.column_stack([np.degrees(test_joints), wrenches[:, :3], errors * 1e3]),
        ),
        _write_csv(
            out / "nonlinear_vs_linear.csv",
            [
                "load_N",
                "nonlinear_minus_linear_um",
                "landing_linear_um",
                "landing_nonlinear_um",
            ],
            np.column_stack(
                [
                    loads,
                    np.array(gap) * 1e6,
                    np.array(landing_lin) * 1e6,
                    np.array(landing_nl) * 1e6,
                ]
            ),
        ),
        plots.plot_identification(
            out / "identification.png", k_true, k_id, ident.standard_error_Nm_rad, errors
        ),
        plots.plot_nonlinear(
            out / "nonlinear_vs_linear.png",
            loads,
            np.array(gap),
            np.array(landing_lin),
            np.array(landing_nl),
        ),
    ]


def identified_model(
    options: StudyOptions, robot_name: str, progress: Progress | None = None
) -> JointCompliance:
    """The joint stiffness the CMM campaign identifies on ``robot_name`` (no files written):
    what a study on that arm compensates with when no identification was handed to it."""
    result = run_identification_study(replace(options, robot=robot_name), progress=progress)
    return result.objects["identification"].model
