"""The milling study: the chapter's block and the Lund face-milling pass, each compensation."""

from __future__ import annotations

from dataclasses import replace
from pathlib import Path

import numpy as np

from ...cell import JointCompliance, Robot, Tool, ToolGravity, true_joint_compliance
from ...export.rapid import write_rapid_module
from ...transforms import quaternion_from_matrix
from .. import plots
from ..compensation import compensate_targets_and_joints
from ..export import compensated_rapid_program
from ..milling import (
    CHAPTER_END_MILLING,
    LUND_FACE_MILLING,
    MillingRun,
    MillingScenario,
    predicted_wrenches,
    program_poses,
    simulate_milling,
)
from ..modes import (
    COMPENSATIONS,
    DEFAULT_OFFLINE_MODEL,
    OFFLINE_MODELS,
    Compensation,
    OfflineModel,
    variant_name,
)
from ._common import (
    DEFAULT_OPTIONS,
    RAPID_FILE,
    SENSOR_FORCE_BIAS_N,
    SENSOR_TORQUE_BIAS_NM,
    Cancel,
    Progress,
    StudyOptions,
    StudyResult,
    _Progress,
    _write_csv,
    study_robot,
    work_position_m,
)
from ._gravity import run_gravity_study
from ._identify import identified_model

# The compensations the study compares: each one, offline with each model (``modes``).
VARIANTS: tuple[tuple[Compensation, OfflineModel], ...] = tuple(
    (c, m)
    for c in COMPENSATIONS
    for m in (OFFLINE_MODELS if c == "offline" else (DEFAULT_OFFLINE_MODEL,))
)


def _quick(scenario: MillingScenario) -> MillingScenario:
    """A shorter block and a faster feed: the same physics in a fraction of the steps."""
    return replace(
        scenario,
        block_length_m=min(scenario.block_length_m, 0.02),
        feed_speed_m_s=scenario.feed_speed_m_s * 4,
        cutter_radius_m=min(scenario.cutter_radius_m, 0.01),
        block_width_m=min(scenario.block_width_m, 0.015),
        oscillation_hz=scenario.oscillation_hz * 4,
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
    options: StudyOptions = DEFAULT_OPTIONS,
    out_dir: Path | None = None,
    *,
    model: JointCompliance | None = None,
    models: dict[str, JointCompliance] | None = None,
    tool_gravity: ToolGravity | None = None,
    true_tool_gravity: ToolGravity | None = None,
    progress: Progress | None = None,
    cancel: Cancel | None = None,
) -> StudyResult:
    """The chapter's end-milling block (on the chapter's arm, the IRB 6640 by default) and the
    Lund face-milling pass (on the Lund IRB 2400), uncompensated and with each compensation.

    Args:
        model: The stiffness identified on the chapter's arm.
        models: Identified stiffness by arm name (the chapter's and the face pass's arms);
            an arm with none is identified here, as is the tool gravity without
            ``tool_gravity``.
    """
    report = progress if isinstance(progress, _Progress) else _Progress(progress, cancel)
    names = {
        "chapter": study_robot(options, "milling"),
        "lund": study_robot(options, "face_milling"),
    }
    known = dict(models or {})
    if model is not None:
        known.setdefault(names["chapter"], model)
    share, tool_gravity, true_tool_gravity = _identified(
        options, names, known, tool_gravity, true_tool_gravity, report
    )
    tool = Tool()
    robots = {key: Robot(name, tool.T_flange_tcp) for key, name in names.items()}
    truths = {key: true_joint_compliance(name) for key, name in names.items()}
    chapter = replace(
        CHAPTER_END_MILLING, surface_center_m=tuple(work_position_m(names["chapter"]))
    )
    lund = replace(LUND_FACE_MILLING, surface_center_m=tuple(work_position_m(names["lund"])))
    if options.quick:
        chapter, lund = _quick(chapter), _quick(lund)
    jobs = [(chapter, c, m) for c, m in VARIANTS]
    jobs += [(lund, c, m) for c, m in VARIANTS if m == DEFAULT_OFFLINE_MODEL]  # Lund: linear only
    runs: dict[str, dict[str, MillingRun]] = {"chapter": {}, "lund": {}}
    width = (1.0 - share) / len(jobs)
    for i, (scenario, compensation, offline_model) in enumerate(jobs):
        key = "chapter" if scenario.error_measure == "surface_depth" else "lund"
        runs[key][variant_name(compensation, offline_model)] = simulate_milling(
            robots[key],
            scenario,
            truths[key],
            compensation=compensation,
            offline_model=offline_model,
            model=known[names[key]],
            tool_gravity=tool_gravity,
            true_tool_gravity=true_tool_gravity,
            seed=options.seed,
            progress=report.slice(share + i * width, width),
            cancel=report.cancelled,
        )
    summary = _milling_summary(names, chapter, lund, runs, quick=options.quick)
    arrays: dict[str, np.ndarray] = {}
    for key, group in runs.items():
        for mode, run in group.items():
            arrays[f"{key}_{mode}_error_u_m"] = run.error_u_m
            arrays[f"{key}_{mode}_error_m"] = run.error_m
    files: list[Path] = []
    if out_dir is not None:
        out = Path(out_dir)
        files += _write_run_files(out, runs, chapter, lund)
        robot, chapter_model = robots["chapter"], known[names["chapter"]]
        table = _compensated_targets_table(robot, chapter, chapter_model)
        files.append(_write_compensated_targets(out, robot, chapter_model, table))
        if options.rapid:
            files.append(
                _write_compensated_rapid(out, robot, tool, chapter, chapter_model, table, options)
            )
    report(1.0)
    return StudyResult("milling", summary, arrays, tuple(files), {"runs": runs, "models": known})


def _identified(
    options: StudyOptions,
    names: dict[str, str],
    known: dict[str, JointCompliance],
    tool_gravity: ToolGravity | None,
    true_tool_gravity: ToolGravity | None,
    report: _Progress,
) -> tuple[float, ToolGravity, ToolGravity]:
    """What the compensations need and were not given: the stiffness of each study arm
    without one in ``known`` (the CMM campaign, added to ``known``) and the tool's gravity
    (the gravity study); the true tool gravity defaults to the nominal tool with the
    sensor's bias. Returns the share of the progress spent and the two tool gravities."""
    share = 0.0
    for name in dict.fromkeys(names.values()):
        if name not in known:
            known[name] = identified_model(options, name, report.slice(share, 0.05))
            share += 0.05
    if tool_gravity is None:
        g = run_gravity_study(options, progress=report.slice(share, 0.02)).objects
        tool_gravity, true_tool_gravity = g["tool_gravity"], g["true_tool_gravity"]
        share += 0.02
    if true_tool_gravity is None:
        true_tool_gravity = ToolGravity.from_tool(
            Tool(), force_bias_N=SENSOR_FORCE_BIAS_N, torque_bias_Nm=SENSOR_TORQUE_BIAS_NM
        )
    return share, tool_gravity, true_tool_gravity


def _milling_summary(
    names: dict[str, str],
    chapter: MillingScenario,
    lund: MillingScenario,
    runs: dict[str, dict[str, MillingRun]],
    *,
    quick: bool,
) -> dict[str, object]:
    """The study's figures: the chapter block's over-cut depth (max, mean, std) per
    compensation and the reduction of its max, and the Lund pass's lateral error [um]."""
    ch, lu = runs["chapter"], runs["lund"]
    linear, nonlinear = (variant_name("offline", m) for m in OFFLINE_MODELS)

    def um(x: float) -> float:
        return float(x * 1e6)

    def reduction(before: MillingRun, after: MillingRun) -> float:
        return float(100.0 * (1.0 - after.error_max_m / before.error_max_m))

    return {
        "milling_robot": names["chapter"],
        "face_milling_robot": names["lund"],
        "chapter_scenario": chapter.name,
        "error_max_uncompensated_um": um(ch["off"].error_max_m),
        "error_mean_uncompensated_um": um(ch["off"].error_mean_m),
        "error_std_uncompensated_um": um(ch["off"].error_std_m),
        "error_max_compensated_linear_um": um(ch[linear].error_max_m),
        "error_max_compensated_nonlinear_um": um(ch[nonlinear].error_max_m),
        "error_max_compensated_online_um": um(ch["online"].error_max_m),
        "error_mean_compensated_online_um": um(ch["online"].error_mean_m),
        "error_std_compensated_um": um(ch[linear].error_std_m),
        "error_std_compensated_nonlinear_um": um(ch[nonlinear].error_std_m),
        "error_std_compensated_online_um": um(ch["online"].error_std_m),
        "error_max_reduction_linear_percent": reduction(ch["off"], ch[linear]),
        "error_max_reduction_nonlinear_percent": reduction(ch["off"], ch[nonlinear]),
        "error_max_reduction_online_percent": reduction(ch["off"], ch["online"]),
        "face_scenario": lund.name,
        "face_error_max_uncompensated_um": um(lu["off"].error_max_m),
        "face_error_std_uncompensated_um": um(lu["off"].error_std_m),
        "face_error_max_compensated_um": um(lu["online"].error_max_m),
        "face_error_std_compensated_um": um(lu["online"].error_std_m),
        "face_error_max_compensated_offline_um": um(lu[linear].error_max_m),
        "face_error_std_compensated_offline_um": um(lu[linear].error_std_m),
        "quick": quick,
    }


def _write_run_files(
    out: Path,
    runs: dict[str, dict[str, MillingRun]],
    chapter: MillingScenario,
    lund: MillingScenario,
) -> list[Path]:
    """The runs' CSVs (the chapter block's surface per compensation, the Lund pass's lateral
    error, the chapter runs' time series) and the two plots."""
    ch, lu = runs["chapter"], runs["lund"]
    linear, nonlinear = (variant_name("offline", m) for m in OFFLINE_MODELS)
    files: list[Path] = []
    modes = list(ch)
    files.append(
        _write_csv(
            out / "milling_chapter_surface.csv",
            ["u_mm"] + [f"{m}_overcut_um" for m in modes],
            np.column_stack([ch["off"].error_u_m * 1e3] + [ch[m].error_m * 1e6 for m in modes]),
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
    return files


def _write_compensated_targets(
    out: Path,
    robot: Robot,
    model: JointCompliance,
    table: tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray],
) -> Path:
    """``milling_targets_compensated.csv``: the chapter program's targets
    (``_compensated_targets_table``), where the linear and the non-linear offline compensation
    (t_0 - C W, and the iteration of eq. 32) move them, and the non-linear one's orientation."""
    u, Ts, joints, wrenches = table
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
    return _write_csv(
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


def _write_compensated_rapid(
    out: Path,
    robot: Robot,
    tool: Tool,
    chapter: MillingScenario,
    model: JointCompliance,
    table: tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray],
    options: StudyOptions,
) -> Path:
    """``milling_compensated.mod``: the chapter program with offline-compensated robtargets
    (the options' offline model) at the block's feed."""
    _, Ts, joints, wrenches = table
    program = compensated_rapid_program(
        robot,
        tool,
        Ts,
        joints,
        wrenches,
        model,
        options.offline_model,
        speed_mm_s=chapter.feed_speed_m_s * 1e3,
        module_name="CompensatedMilling",
    )
    return write_rapid_module(program, out / RAPID_FILE)
