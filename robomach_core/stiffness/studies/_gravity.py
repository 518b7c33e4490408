"""The gravity-compensation study of the F/T sensor."""

from __future__ import annotations

from pathlib import Path

import numpy as np

from ...cell import (
    Robot,
    Tool,
    ToolGravity,
    compensate_gravity,
    contact_reading,
    gravity_reading,
    wrench_at_tcp_in_base,
    wrench_in_tool_frame,
)
from .. import plots
from ..gravity import calibration_joints, identify_tool_gravity, simulate_sensor_readings
from ..milling import (
    CHAPTER_END_MILLING,
)
from ._common import (
    DEFAULT_OPTIONS,
    SENSOR_FORCE_BIAS_N,
    SENSOR_FORCE_NOISE_N,
    SENSOR_TORQUE_BIAS_NM,
    SENSOR_TORQUE_NOISE_NM,
    Cancel,
    Progress,
    StudyOptions,
    StudyResult,
    _Progress,
    _work_joints,
    _write_csv,
    study_robot,
)


def run_gravity_study(
    options: StudyOptions = DEFAULT_OPTIONS,
    out_dir: Path | None = None,
    *,
    progress: Progress | None = None,
    cancel: Cancel | None = None,
) -> StudyResult:
    """Tool mass, centre of mass and sensor bias from 15 configurations; residual force at
    random poses; the compensated force in the tool frame."""
    report = progress if isinstance(progress, _Progress) else _Progress(progress, cancel)
    tool = Tool()
    robot = Robot(study_robot(options, "gravity"), tool.T_flange_tcp)
    true_tool = ToolGravity.from_tool(
        tool, force_bias_N=SENSOR_FORCE_BIAS_N, torque_bias_Nm=SENSOR_TORQUE_BIAS_NM
    )
    # centred on the arm's own home (the UR home is out of an ABB arm's axis-2 range)
    joints = calibration_joints(
        options.gravity_configurations, seed=options.seed, center_rad=robot.home_rad
    )
    R, W = simulate_sensor_readings(
        robot,
        joints,
        true_tool,
        force_noise_N=SENSOR_FORCE_NOISE_N,
        torque_noise_Nm=SENSOR_TORQUE_NOISE_NM,
        seed=options.seed,
    )
    estimate = identify_tool_gravity(R, W)
    report(0.4)
    test = calibration_joints(50, seed=options.seed + 100, center_rad=robot.home_rad)
    R_test, W_test = simulate_sensor_readings(
        robot,
        test,
        true_tool,
        force_noise_N=SENSOR_FORCE_NOISE_N,
        torque_noise_Nm=SENSOR_TORQUE_NOISE_NM,
        seed=options.seed + 101,
    )
    residual = np.array(
        [
            np.linalg.norm(compensate_gravity(w, r, estimate)[:3])
            for w, r in zip(W_test, R_test, strict=True)
        ]
    )
    model_error = np.array(
        [
            np.linalg.norm(compensate_gravity(gravity_reading(r, true_tool), r, estimate)[:3])
            for r in R_test
        ]
    )
    # The chapter's chain at the work pose: reading -> gravity-compensated -> tool frame.
    q = _work_joints(robot)
    R_work = robot.flange_pose(q)[:3, :3].copy()
    p_tcp = robot.T_flange_tcp[:3, 3]
    contact = CHAPTER_END_MILLING.nominal_wrench()
    reading = gravity_reading(R_work, true_tool) + contact_reading(R_work, p_tcp, contact)
    compensated = compensate_gravity(reading, R_work, estimate)
    in_tool = wrench_in_tool_frame(compensated, robot.T_flange_tcp)
    in_base = wrench_at_tcp_in_base(compensated, R_work, p_tcp)
    report(0.8)
    summary = {
        "gravity_robot": robot.name,
        "gravity_configurations": int(len(joints)),
        "tool_mass_true_kg": true_tool.mass_kg,
        "tool_mass_identified_kg": estimate.mass_kg,
        "tool_com_true_mm": [v * 1e3 for v in true_tool.com_m],
        "tool_com_identified_mm": [v * 1e3 for v in estimate.com_m],
        "sensor_force_bias_true_N": list(true_tool.force_bias_N),
        "sensor_force_bias_identified_N": list(estimate.force_bias_N),
        "sensor_torque_bias_identified_Nm": list(estimate.torque_bias_Nm),
        "sensor_force_noise_N": SENSOR_FORCE_NOISE_N,
        "gravity_residual_max_N": float(residual.max()),
        "gravity_residual_mean_N": float(residual.mean()),
        "gravity_model_error_max_N": float(model_error.max()),
        "work_pose_contact_force_tool_frame_N": in_tool[:3].tolist(),
        "work_pose_contact_force_base_error_N": float(np.linalg.norm(in_base[:3] - contact[:3])),
    }
    arrays = {
        "calibration_joints_rad": joints,
        "calibration_wrench_sensor": W,
        "test_joints_rad": test,
        "residual_N": residual,
        "model_error_N": model_error,
    }
    files: list[Path] = []
    if out_dir is not None:
        out = Path(out_dir)
        files += [
            _write_csv(
                out / "gravity_calibration.csv",
                [f"q{i}_deg" for i in range(1, 7)]
                + ["fx_N", "fy_N", "fz_N", "tx_Nm", "ty_Nm", "tz_Nm"],
                np.column_stack([np.degrees(joints), W]),
            ),
            _write_csv(
                out / "gravity_residuals.csv",
                [f"q{i}_deg" for i in range(1, 7)] + ["residual_N", "model_error_N"],
                np.column_stack([np.degrees(test), residual, model_error]),
            ),
            plots.plot_gravity(out / "gravity.png", residual, SENSOR_FORCE_NOISE_N),
        ]
    report(1.0)
    return StudyResult(
        "gravity",
        summary,
        arrays,
        tuple(files),
        {"tool_gravity": estimate, "true_tool_gravity": true_tool},
    )
