"""Options, results, progress and constants shared by the compensation studies."""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Literal, get_args

import numpy as np

from ...cell import Robot
from ...errors import CancelledError
from ...transforms import make_transform, rotation_about
from ..milling import CHAPTER_END_MILLING
from ..modes import DEFAULT_OFFLINE_MODEL, Compensation, OfflineModel

StudyName = Literal["identify", "gravity", "milling", "ilc", "compliance", "all"]
STUDIES: tuple[str, ...] = tuple(s for s in get_args(StudyName) if s != "all")
Progress = Callable[[float], None]
Cancel = Callable[[], bool]

SUMMARY_FILE = "compensation_summary.json"
SETTINGS_FILE = "compensation_settings.json"
RAPID_FILE = "milling_compensated.mod"
# Share of the whole run each study takes, for one progress bar over "all".
STUDY_WEIGHTS = {
    "identify": 0.15,
    "gravity": 0.05,
    "milling": 0.5,
    "ilc": 0.15,
    "compliance": 0.15,
}
# Each paper's experiment on its own arm (``StudyOptions.robot`` None): the chapter's cell was
# an IRB 6400, whose kinematics are not published (robots/abb.py), so the chapter's studies
# run on the IRB 6640 that replaced it; the Lund papers (face milling, ILC) used an IRB 2400;
# the compliance-error paper a KUKA KR 270.
PAPER_ARMS: dict[str, str] = {
    "identify": "irb6640",
    "gravity": "irb6640",
    "milling": "irb6640",
    "face_milling": "irb2400",
    "ilc": "irb2400",
    "compliance": "kr270",
}
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
        robot: Robot model for every study; None runs each study on its paper's arm
            (``PAPER_ARMS``).
        seed: Seeds every random element.
        cmm_noise_um: CMM noise per axis and reading (the chapter's 10-50 um).
        identification_poses: Poses of the CMM campaign.
        test_poses: Poses where the identified model's prediction is scored.
        gravity_configurations: Configurations of the gravity calibration (the chapter: 15).
        ilc_iterations: ILC runs after the first.
        mode: Compensation written to the settings file (``modes.Compensation``).
        offline_model: Its offline model, written with it and used by the RAPID export.
        rapid: Also write the offline-compensated milling program as RAPID.
        quick: Shorter cuts and fewer poses (tests, previews).
    """

    robot: str | None = None
    seed: int = 0
    cmm_noise_um: float = 20.0
    identification_poses: int = 30
    test_poses: int = 30
    gravity_configurations: int = 15
    ilc_iterations: int = 6
    mode: Compensation = "online"
    offline_model: OfflineModel = DEFAULT_OFFLINE_MODEL
    rapid: bool = False
    quick: bool = False


# A frozen value, so one instance serves as every runner's default.
DEFAULT_OPTIONS = StudyOptions()


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


def study_robot(options: StudyOptions, part: str) -> str:
    """The arm a study (or a part of one: ``"face_milling"``) runs on: ``options.robot``, else
    its paper's (``PAPER_ARMS``). The compliance study always runs on the KR 270: Table 1's
    pose and stiffness are that arm's."""
    if part == "compliance":
        return PAPER_ARMS[part]
    return (options.robot or PAPER_ARMS[part]).lower()


def work_position_m(robot_name: str) -> np.ndarray:
    """Where the studies cut and measure, tool down (``identification.arm_work_position_m``:
    in front of a UR arm, else beside the built-in part's placement for the arm). Shape (3,)."""
    from ..identification import arm_work_position_m

    return arm_work_position_m(robot_name)


def _work_joints(robot: Robot) -> np.ndarray:
    T = make_transform(np.diag([1.0, -1.0, -1.0]), work_position_m(robot.name))
    return robot.ik(T)


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
