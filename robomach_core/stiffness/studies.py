"""Study runners: identification, gravity compensation, milling compensation and ILC.

Each runner is a plain function a CLI, a GUI panel or a REST job can call: options in, a
``StudyResult`` out (summary dict in boundary units, named arrays, paths of the CSVs and PNGs it
wrote when given a folder). ``progress(fraction)`` is called as the work advances and
``cancel()`` is polled; True stops the study with ``CancelledError``.

The simulator's true joint stiffness is used only to bend the simulated arm and to score the
identified model; every controller in here uses the identified model.
"""

from __future__ import annotations

import json
from collections.abc import Callable
from dataclasses import dataclass, field, replace
from pathlib import Path
from typing import Any, Literal

import numpy as np

from ..errors import CancelledError
from ..export.rapid import write_rapid_module
from ..joint_compliance import JointCompliance, true_joint_compliance
from ..robot import Robot
from ..tool import Tool
from ..transforms import make_transform, pose_error, quaternion_from_matrix, rotation_about
from . import plots
from .compensation import compensate_targets_and_joints
from .errors import UnknownStudyError
from .export import compensated_rapid_program
from .gravity import (
    ToolGravity,
    calibration_joints,
    compensate_gravity,
    contact_reading,
    gravity_reading,
    identify_tool_gravity,
    simulate_sensor_readings,
    wrench_at_tcp_in_base,
    wrench_in_tool_frame,
)
from .identification import (
    DEFAULT_LOADS_N,
    StiffnessIdentification,
    identify_joint_stiffness,
    prediction_errors,
    sample_workspace_joints,
    simulate_stiffness_measurements,
    sphere_tip_transform,
)
from .ilc import IlcSystem, milling_process_gain, perturbed, run_ilc, square_path
from .milling import (
    CHAPTER_END_MILLING,
    LUND_FACE_MILLING,
    MillingRun,
    MillingScenario,
    predicted_wrenches,
    program_poses,
    simulate_milling,
)
from .model import cartesian_compliance, loaded_equilibrium
from .settings import CompensationSetting, CompensationSettings, save_settings

StudyName = Literal["identify", "gravity", "milling", "ilc", "all"]
STUDIES: tuple[str, ...] = ("identify", "gravity", "milling", "ilc")
Progress = Callable[[float], None]
Cancel = Callable[[], bool]

SUMMARY_FILE = "compensation_summary.json"
SETTINGS_FILE = "compensation_settings.json"
RAPID_FILE = "milling_compensated.mod"
# Share of the whole run each study takes, for one progress bar over "all".
STUDY_WEIGHTS = {"identify": 0.2, "gravity": 0.05, "milling": 0.6, "ilc": 0.15}
# The work pose of the studies: TCP in front of the UR10, tool pointing down [m].
WORK_POSITION_M = (0.70, 0.10, 0.03)
# The sensor's true offsets in the simulated cell.
SENSOR_FORCE_BIAS_N = (1.5, -0.8, 2.0)
SENSOR_TORQUE_BIAS_NM = (0.05, 0.10, -0.02)
SENSOR_FORCE_NOISE_N = 0.3
SENSOR_TORQUE_NOISE_NM = 0.02
# The ILC study's model errors: process gain, servo bandwidth and resonance off by this much.
ILC_MODEL_ERRORS = {"process_gain_scale": 1.15, "bandwidth_scale": 0.9, "resonance_scale": 1.1}
ILC_FORCE_DISTURBANCE_N = 30.0
ILC_TRACKER_NOISE_M = 10e-6
# What the papers report, next to what the simulation gives.
PAPER_REFERENCES = {
    "chapter_prediction_error_max_mm": 0.04,
    "chapter_error_uncompensated_mm": 0.4,
    "chapter_error_compensated_mm_below": 0.1,
    "lund_error_max_uncompensated_um": 273.9,
    "lund_error_max_compensated_um": 51.4,
    "lund_error_std_uncompensated_um": 37.9,
    "lund_error_std_compensated_um": 18.6,
    "compliance_paper_max_deviation_reduction_percent": 92.6,
    "ilc_arm_reduction_percent": 85.0,
    "ilc_force_reduction_percent": 50.0,
}


@dataclass(frozen=True)
class StudyOptions:
    """Settings shared by the studies.

    Attributes:
        robot: Robot model.
        seed: Seeds every random element.
        cmm_noise_um: CMM noise per axis and reading (the chapter's 10-50 um).
        identification_poses: Poses of the CMM campaign.
        test_poses: Poses where the identified model's prediction is scored.
        gravity_configurations: Configurations of the gravity calibration (the chapter: 15).
        ilc_iterations: ILC runs after the first.
        mode: Compensation mode written to the settings file.
        rapid: Also write the offline-compensated milling program as RAPID.
        quick: Shorter cuts and fewer poses (tests, previews).
    """

    robot: str = "ur10"
    seed: int = 0
    cmm_noise_um: float = 20.0
    identification_poses: int = 30
    test_poses: int = 30
    gravity_configurations: int = 15
    ilc_iterations: int = 6
    mode: CompensationSetting = "online"
    rapid: bool = False
    quick: bool = False


@dataclass(frozen=True)
class StudyResult:
    """What a study returns.

    Attributes:
        name: Study name.
        summary: JSON-ready numbers in boundary units (µm, mm, N).
        arrays: Named arrays in SI units for plots and APIs.
        files: Paths of the CSVs, PNGs and other files written (empty without a folder).
        objects: Python results other studies reuse (identified model, tool gravity).
    """

    name: str
    summary: dict[str, Any]
    arrays: dict[str, np.ndarray] = field(default_factory=dict)
    files: tuple[Path, ...] = ()
    objects: dict[str, Any] = field(default_factory=dict)


class _Progress:
    """Maps a sub-task's 0..1 onto a slice of the caller's progress."""

    def __init__(self, progress: Progress | None, cancel: Cancel | None) -> None:
        self._progress = progress
        self._cancel = cancel
        self.start, self.width = 0.0, 1.0

    def slice(self, start: float, width: float) -> _Progress:
        sub = _Progress(self._progress, self._cancel)
        sub.start, sub.width = self.start + start * self.width, width * self.width
        return sub

    def __call__(self, fraction: float) -> None:
        self.check()
        if self._progress is not None:
            self._progress(min(max(self.start + fraction * self.width, 0.0), 1.0))

    def check(self) -> None:
        if self._cancel is not None and self._cancel():
            raise CancelledError("compensation study cancelled")

    def cancelled(self) -> bool:
        return self._cancel is not None and bool(self._cancel())


def _write_csv(path: Path, header: list[str], rows: np.ndarray) -> Path:
    np.savetxt(
        path,
        np.asarray(rows, dtype=float),
        delimiter=",",
        header=",".join(header),
        comments="",
        fmt="%.9g",
    )
    return path


def _work_joints(robot: Robot) -> np.ndarray:
    return robot.ik(make_transform(np.diag([1.0, -1.0, -1.0]), np.asarray(WORK_POSITION_M)))


def _chapter_wrenches(count: int, seed: int) -> np.ndarray:
    """The chapter's milling load (300 N feed, 300 N cutting, 50 N normal), random heading."""
    rng = np.random.default_rng(seed)
    base = CHAPTER_END_MILLING.nominal_wrench()[:3]
    return np.array(
        [
            np.concatenate([rotation_about("z", a) @ base, np.zeros(3)])
            for a in rng.uniform(-np.pi, np.pi, count)
        ]
    )


def run_identification_study(
    options: StudyOptions = StudyOptions(),
    out_dir: Path | None = None,
    *,
    progress: Progress | None = None,
    cancel: Cancel | None = None,
) -> StudyResult:
    """Simulated CMM campaign, Kq by eq. (23), prediction error over the workspace, and the
    non-linear model next to the linear one."""
    report = progress if isinstance(progress, _Progress) else _Progress(progress, cancel)
    tip_robot = Robot(options.robot, sphere_tip_transform())  # unknown names fail here
    tool_robot = Robot(options.robot, Tool().T_flange_tcp)
    truth = true_joint_compliance(options.robot)
    n_poses = (
        min(options.identification_poses, 12) if options.quick else options.identification_poses
    )
    n_test = min(options.test_poses, 10) if options.quick else options.test_poses
    poses = sample_workspace_joints(tip_robot, n_poses, seed=options.seed)
    report(0.2)
    data = simulate_stiffness_measurements(
        tip_robot, poses, truth, cmm_noise_m=options.cmm_noise_um * 1e-6, seed=options.seed
    )
    ident = identify_joint_stiffness(tip_robot, data)
    report(0.5)
    test_joints = sample_workspace_joints(tool_robot, n_test, seed=options.seed + 1)
    wrenches = _chapter_wrenches(n_test, options.seed + 2)
    errors = prediction_errors(tool_robot, test_joints, wrenches, ident.model, truth)
    report(0.8)

    # Linear vs non-linear at the work pose, growing load along the chapter's direction.
    q_work = _work_joints(tool_robot)
    T_work = tool_robot.fk(q_work).copy()
    direction = CHAPTER_END_MILLING.nominal_wrench()
    direction = direction / np.linalg.norm(direction[:3])
    loads = np.logspace(1, 4, 7)
    gap, landing_lin, landing_nl = [], [], []
    for load in loads:
        W = direction * load
        lin = loaded_equilibrium(tool_robot, q_work, W, truth, mode="linear")
        nl = loaded_equilibrium(tool_robot, q_work, W, truth)
        gap.append(np.linalg.norm(pose_error(lin.T_base_tcp, nl.T_base_tcp)[:3]))
        for mode, out in (("linear", landing_lin), ("nonlinear", landing_nl)):
            _, q = compensate_targets_and_joints(
                tool_robot, T_work[None], q_work[None], W[None], truth, mode
            )
            landed = loaded_equilibrium(tool_robot, q[0], W, truth).T_base_tcp
            out.append(np.linalg.norm(pose_error(landed, T_work)[:3]))
    report(0.95)

    k_true = np.asarray(truth.stiffness_Nm_rad)
    k_id = np.asarray(ident.model.stiffness_Nm_rad)
    rel = k_id / k_true - 1.0
    chapter_load = float(np.linalg.norm(CHAPTER_END_MILLING.nominal_wrench()[:3]))
    gap_at = []
    for scale in (1.0, 10.0):
        W = direction * chapter_load * scale
        lin = loaded_equilibrium(tool_robot, q_work, W, truth, mode="linear").T_base_tcp
        nl = loaded_equilibrium(tool_robot, q_work, W, truth).T_base_tcp
        gap_at.append(float(np.linalg.norm(pose_error(lin, nl)[:3])))
    summary = {
        "robot": options.robot,
        "cmm_noise_um": options.cmm_noise_um,
        "identification_poses": int(n_poses),
        "identification_loads": len(DEFAULT_LOADS_N),
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
        "nonlinear_minus_linear_at_chapter_load_um": float(gap_at[0] * 1e6),
        "nonlinear_minus_linear_at_10x_chapter_load_um": float(gap_at[1] * 1e6),
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
        "load_N": loads,
        "nonlinear_minus_linear_m": np.array(gap),
        "landing_error_linear_m": np.array(landing_lin),
        "landing_error_nonlinear_m": np.array(landing_nl),
    }
    files: list[Path] = []
    if out_dir is not None:
        out = Path(out_dir)
        files += [
            _write_csv(
                out / "identification_stiffness.csv",
                ["joint", "true_Nm_rad", "identified_Nm_rad", "std_Nm_rad", "rel_error"],
                np.column_stack([np.arange(1, 7), k_true, k_id, ident.standard_error_Nm_rad, rel]),
            ),
            _write_csv(
                out / "identification_measurements.csv",
                [f"q{i}_deg" for i in range(1, 7)]
                + ["fx_N", "fy_N", "fz_N", "dx_mm", "dy_mm", "dz_mm"],
                np.column_stack(
                    [np.degrees(data.joints_rad), data.force_N, data.displacement_m * 1e3]
                ),
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
    report(1.0)
    return StudyResult("identify", summary, arrays, tuple(files), {"identification": ident})


def run_gravity_study(
    options: StudyOptions = StudyOptions(),
    out_dir: Path | None = None,
    *,
    progress: Progress | None = None,
    cancel: Cancel | None = None,
) -> StudyResult:
    """Tool mass, centre of mass and sensor bias from 15 configurations; residual force at
    random poses; the compensated force in the tool frame."""
    report = progress if isinstance(progress, _Progress) else _Progress(progress, cancel)
    tool = Tool()
    robot = Robot(options.robot, tool.T_flange_tcp)
    true_tool = ToolGravity.from_tool(
        tool, force_bias_N=SENSOR_FORCE_BIAS_N, torque_bias_Nm=SENSOR_TORQUE_BIAS_NM
    )
    joints = calibration_joints(options.gravity_configurations, seed=options.seed)
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
    test = calibration_joints(50, seed=options.seed + 100)
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


def _quick(scenario: MillingScenario) -> MillingScenario:
    """A shorter block and a faster feed: the same physics in a fraction of the steps."""
    return replace(
        scenario,
        block_length_m=min(scenario.block_length_m, 0.03),
        feed_speed_m_s=scenario.feed_speed_m_s * 3,
        cutter_radius_m=min(scenario.cutter_radius_m, 0.015),
        block_width_m=min(scenario.block_width_m, 0.02),
        oscillation_hz=scenario.oscillation_hz * 3,
    )


def _compensated_targets_table(
    robot: Robot, scenario: MillingScenario, model: JointCompliance
) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """Program targets every 5 mm along the cut, their joints and predicted wrenches."""
    R_cut = scenario.cutter_radius_m
    u = np.arange(-R_cut, scenario.block_length_m + R_cut + 1e-9, 0.005)
    Ts = program_poses(scenario, u)
    q = robot.ik(Ts[0])
    joints = []
    for T in Ts:
        q = robot.ik(T, q)
        joints.append(q)
    return u, Ts, np.array(joints), predicted_wrenches(scenario, u)


def run_milling_study(
    options: StudyOptions = StudyOptions(),
    out_dir: Path | None = None,
    *,
    model: JointCompliance | None = None,
    tool_gravity: ToolGravity | None = None,
    true_tool_gravity: ToolGravity | None = None,
    progress: Progress | None = None,
    cancel: Cancel | None = None,
) -> StudyResult:
    """The chapter's end-milling block and the Lund face-milling pass, uncompensated and with
    each compensation. Without ``model``/``tool_gravity`` it identifies them first."""
    report = progress if isinstance(progress, _Progress) else _Progress(progress, cancel)
    share = 0.0
    if model is None:
        model = (
            run_identification_study(options, progress=report.slice(0.0, 0.1))
            .objects["identification"]
            .model
        )
        share = 0.1
    if tool_gravity is None:
        g = run_gravity_study(options, progress=report.slice(share, 0.02)).objects
        tool_gravity, true_tool_gravity = g["tool_gravity"], g["true_tool_gravity"]
        share += 0.02
    if true_tool_gravity is None:
        true_tool_gravity = ToolGravity.from_tool(
            Tool(), force_bias_N=SENSOR_FORCE_BIAS_N, torque_bias_Nm=SENSOR_TORQUE_BIAS_NM
        )
    truth = true_joint_compliance(options.robot)
    tool = Tool()
    robot = Robot(options.robot, tool.T_flange_tcp)
    chapter, lund = CHAPTER_END_MILLING, LUND_FACE_MILLING
    if options.quick:
        chapter, lund = _quick(chapter), _quick(lund)
    jobs = [(chapter, m) for m in ("none", "online", "offline_linear", "offline_nonlinear")]
    jobs += [(lund, m) for m in ("none", "online", "offline_linear")]
    runs: dict[str, dict[str, MillingRun]] = {"chapter": {}, "lund": {}}
    width = (1.0 - share) / len(jobs)
    for i, (scenario, mode) in enumerate(jobs):
        key = "chapter" if scenario.error_measure == "surface_depth" else "lund"
        runs[key][mode] = simulate_milling(
            robot,
            scenario,
            truth,
            compensation=mode,
            model=model,
            tool_gravity=tool_gravity,
            true_tool_gravity=true_tool_gravity,
            seed=options.seed,
            progress=report.slice(share + i * width, width),
            cancel=report.cancelled,
        )
    ch, lu = runs["chapter"], runs["lund"]

    def um(x: float) -> float:
        return float(x * 1e6)

    def reduction(before: MillingRun, after: MillingRun) -> float:
        return float(100.0 * (1.0 - after.error_max_m / before.error_max_m))

    summary = {
        "chapter_scenario": chapter.name,
        "error_max_uncompensated_um": um(ch["none"].error_max_m),
        "error_mean_uncompensated_um": um(ch["none"].error_mean_m),
        "error_std_uncompensated_um": um(ch["none"].error_std_m),
        "error_max_compensated_linear_um": um(ch["offline_linear"].error_max_m),
        "error_max_compensated_nonlinear_um": um(ch["offline_nonlinear"].error_max_m),
        "error_max_compensated_online_um": um(ch["online"].error_max_m),
        "error_mean_compensated_online_um": um(ch["online"].error_mean_m),
        "error_std_compensated_um": um(ch["offline_linear"].error_std_m),
        "error_std_compensated_nonlinear_um": um(ch["offline_nonlinear"].error_std_m),
        "error_std_compensated_online_um": um(ch["online"].error_std_m),
        "error_max_reduction_linear_percent": reduction(ch["none"], ch["offline_linear"]),
        "error_max_reduction_nonlinear_percent": reduction(ch["none"], ch["offline_nonlinear"]),
        "error_max_reduction_online_percent": reduction(ch["none"], ch["online"]),
        "face_scenario": lund.name,
        "face_error_max_uncompensated_um": um(lu["none"].error_max_m),
        "face_error_std_uncompensated_um": um(lu["none"].error_std_m),
        "face_error_max_compensated_um": um(lu["online"].error_max_m),
        "face_error_std_compensated_um": um(lu["online"].error_std_m),
        "face_error_max_compensated_offline_um": um(lu["offline_linear"].error_max_m),
        "face_error_std_compensated_offline_um": um(lu["offline_linear"].error_std_m),
        "quick": options.quick,
    }
    arrays: dict[str, np.ndarray] = {}
    for key, group in runs.items():
        for mode, run in group.items():
            arrays[f"{key}_{mode}_error_u_m"] = run.error_u_m
            arrays[f"{key}_{mode}_error_m"] = run.error_m
    files: list[Path] = []
    if out_dir is not None:
        out = Path(out_dir)
        modes = list(ch)
        files.append(
            _write_csv(
                out / "milling_chapter_surface.csv",
                ["u_mm"] + [f"{m}_overcut_um" for m in modes],
                np.column_stack(
                    [ch["none"].error_u_m * 1e3] + [ch[m].error_m * 1e6 for m in modes]
                ),
            )
        )
        for mode, run in lu.items():
            files.append(
                _write_csv(
                    out / f"milling_face_{mode}.csv",
                    ["u_mm", "lateral_error_um"],
                    np.column_stack([run.error_u_m * 1e3, run.error_m * 1e6]),
                )
            )
        for mode, run in ch.items():
            files.append(
                _write_csv(
                    out / f"milling_chapter_{mode}_timeseries.csv",
                    [
                        "t_s",
                        "x_nominal_mm",
                        "y_nominal_mm",
                        "z_nominal_mm",
                        "x_mm",
                        "y_mm",
                        "z_mm",
                        "fx_N",
                        "fy_N",
                        "fz_N",
                        "engagement",
                    ],
                    np.column_stack(
                        [
                            run.time_s,
                            run.position_nominal_m * 1e3,
                            run.position_actual_m * 1e3,
                            run.wrench[:, :3],
                            run.engagement,
                        ]
                    ),
                )
            )
        files.append(
            plots.plot_milling(
                out / "milling_chapter.png",
                ch,
                title=chapter.name,
                error_label="over-cut depth [µm] (+ = too deep)",
            )
        )
        files.append(
            plots.plot_milling(
                out / "milling_face.png",
                lu,
                title=lund.name,
                error_label="path error across the feed [µm]",
            )
        )
        u, Ts, joints, wrenches = _compensated_targets_table(robot, chapter, model)
        T_lin, _ = compensate_targets_and_joints(robot, Ts, joints, wrenches, model, "linear")
        T_nl, _ = compensate_targets_and_joints(robot, Ts, joints, wrenches, model, "nonlinear")
        rows = []
        for ui, T0, T1, T2 in zip(u, Ts, T_lin, T_nl, strict=True):
            rows.append(
                np.concatenate(
                    [
                        [ui * 1e3],
                        T0[:3, 3] * 1e3,
                        T1[:3, 3] * 1e3,
                        T2[:3, 3] * 1e3,
                        quaternion_from_matrix(T2[:3, :3]),
                    ]
                )
            )
        files.append(
            _write_csv(
                out / "milling_targets_compensated.csv",
                [
                    "u_mm",
                    "x_mm",
                    "y_mm",
                    "z_mm",
                    "x_linear_mm",
                    "y_linear_mm",
                    "z_linear_mm",
                    "x_nonlinear_mm",
                    "y_nonlinear_mm",
                    "z_nonlinear_mm",
                    "qw",
                    "qx",
                    "qy",
                    "qz",
                ],
                np.array(rows),
            )
        )
        if options.rapid:
            mode = "nonlinear" if options.mode == "offline_nonlinear" else "linear"
            program = compensated_rapid_program(
                robot,
                tool,
                Ts,
                joints,
                wrenches,
                model,
                mode,
                speed_mm_s=chapter.feed_speed_m_s * 1e3,
                module_name="CompensatedMilling",
            )
            files.append(write_rapid_module(program, out / RAPID_FILE))
    report(1.0)
    return StudyResult("milling", summary, arrays, tuple(files), {"runs": runs})


def run_ilc_study(
    options: StudyOptions = StudyOptions(),
    out_dir: Path | None = None,
    *,
    model: JointCompliance | None = None,
    progress: Progress | None = None,
    cancel: Cancel | None = None,
) -> StudyResult:
    """Arm-side and force ILC over repeated runs of the Lund paper's square."""
    report = progress if isinstance(progress, _Progress) else _Progress(progress, cancel)
    share = 0.0
    if model is None:
        model = (
            run_identification_study(options, progress=report.slice(0.0, 0.3))
            .objects["identification"]
            .model
        )
        share = 0.3
    truth = true_joint_compliance(options.robot)
    robot = Robot(options.robot, Tool().T_flange_tcp)
    q = _work_joints(robot)
    gain = milling_process_gain()
    truth_system = IlcSystem(cartesian_compliance(robot, q, truth)[:3, :3], gain)
    model_system = perturbed(
        IlcSystem(cartesian_compliance(robot, q, model)[:3, :3], gain), **ILC_MODEL_ERRORS
    )
    side = 0.02 if options.quick else 0.04
    path = square_path(side_m=side, center_m=WORK_POSITION_M)
    iterations = min(options.ilc_iterations, 3) if options.quick else options.ilc_iterations
    results = {}
    for i, kind in enumerate(("arm", "force")):
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


def run_studies(
    study: StudyName = "all",
    out_dir: Path | str | None = None,
    options: StudyOptions = StudyOptions(),
    *,
    progress: Progress | None = None,
    cancel: Cancel | None = None,
) -> dict[str, StudyResult]:
    """Run one study or all of them; with a folder, also write the summary JSON and settings.

    Raises:
        UnknownStudyError: ``study`` is not one of identify, gravity, milling, ilc, all.
        CancelledError: ``cancel()`` returned True.
    """
    if study not in (*STUDIES, "all"):
        raise UnknownStudyError(f"unknown study {study!r}; choose one of {', '.join(STUDIES)}, all")
    out = None if out_dir is None else Path(out_dir)
    if out is not None:
        out.mkdir(parents=True, exist_ok=True)
    names = STUDIES if study == "all" else (study,)
    total = sum(STUDY_WEIGHTS[n] for n in names)
    report = _Progress(progress, cancel)
    results: dict[str, StudyResult] = {}
    start = 0.0
    model = tool_gravity = true_tool = None
    for name in names:
        part = report.slice(start / total, STUDY_WEIGHTS[name] / total)
        start += STUDY_WEIGHTS[name]
        if name == "identify":
            results[name] = run_identification_study(options, out, progress=part)
            model = results[name].objects["identification"].model
        elif name == "gravity":
            results[name] = run_gravity_study(options, out, progress=part)
            tool_gravity = results[name].objects["tool_gravity"]
            true_tool = results[name].objects["true_tool_gravity"]
        elif name == "milling":
            results[name] = run_milling_study(
                options,
                out,
                model=model,
                tool_gravity=tool_gravity,
                true_tool_gravity=true_tool,
                progress=part,
            )
        else:
            results[name] = run_ilc_study(options, out, model=model, progress=part)
    if out is not None:
        summary: dict[str, Any] = {
            "studies": list(names),
            "seed": options.seed,
            "paper_references": PAPER_REFERENCES,
        }
        for result in results.values():
            summary.update(result.summary)
        (out / SUMMARY_FILE).write_text(json.dumps(summary, indent=2) + "\n", encoding="utf-8")
        if "identify" in results:
            ident: StiffnessIdentification = results["identify"].objects["identification"]
            mode = options.mode
            if mode == "online" and tool_gravity is None:
                mode = "offline_linear"  # online needs the tool gravity of the gravity study
            save_settings(
                CompensationSettings(
                    robot=options.robot,
                    joint_stiffness_Nm_rad=ident.model.stiffness_Nm_rad,
                    mode=mode,
                    joint_stiffness_std_Nm_rad=tuple(ident.standard_error_Nm_rad.tolist()),
                    tool_gravity=tool_gravity,
                ),
                out / SETTINGS_FILE,
            )
    report(1.0)
    return results
