"""Constants, errors and the plain records the session hands out (SI units)."""

from __future__ import annotations

import logging
import re
from dataclasses import dataclass
from pathlib import Path
from typing import Literal

import numpy as np

from robomach_core.cell import GuidePoint
from robomach_core.errors import ConflictError as ConflictError
from robomach_core.errors import InvalidInputError, RobomachError
from robomach_core.errors import NotFoundError as NotFoundError
from robomach_core.project import RECORDING_FIELDS, ProcessedPath
from robomach_core.project import CellSettings as CellSettings
from robomach_core.transforms import quaternion_from_matrix

log = logging.getLogger(__name__)

Topic = Literal[
    "robot",
    "compliance",
    "cell",
    "guide_points",
    "recording",
    "postprocess",
    "job",
    "project",
    "exports",
    "machining",
    "placement",
    "calibration",
]
JobStatus = Literal["queued", "running", "done", "failed", "cancelled"]

DEFAULT_PROJECT_NAME = "default"
PROJECT_NAME_MAX = 80
EXPORT_NAME_RE = re.compile(r"^[A-Za-z0-9][A-Za-z0-9_.-]{0,63}$")
LIVE_TRACE_EVERY = 5  # live force sample every 5 periods (20 ms simulated)
LIVE_TRACE_MAX = 20_000
LIVE_NOTIFY_S = 0.05  # robot-pose notifications during a job: at most 20 per second
MAX_GUIDE_POINTS = 200
RECORDING_ARRAYS = RECORDING_FIELDS  # the recording's arrays, saved one by one


# --- errors of the session (the API maps them by their builtin base) -------------------------


class QueueFullError(RobomachError, RuntimeError):
    """Too many jobs are queued or running: wait for one to end or cancel one (429)."""


class BusyError(ConflictError):
    """A job is moving the robot; wait for it or cancel it first."""


# --- values the session returns (SI units) ---------------------------------------------------


@dataclass(frozen=True)
class RobotSnapshot:
    """The robot as the controller sees it.

    Attributes:
        time_s: Simulated time.
        joints_rad: (6,) motor-side joints.
        T_base_tcp: 4x4 TCP pose (metres).
        wrench: (6,) measured, gravity-compensated contact wrench at the TCP, base axes
            [N, N*m].
        in_contact: The tool touches the workpiece.
        busy: A job is moving the robot (pushes and jogs are refused).
    """

    time_s: float
    joints_rad: np.ndarray
    T_base_tcp: np.ndarray
    wrench: np.ndarray
    in_contact: bool
    busy: bool

    @property
    def position_m(self) -> np.ndarray:
        return self.T_base_tcp[:3, 3]

    @property
    def quaternion_wxyz(self) -> np.ndarray:
        return quaternion_from_matrix(self.T_base_tcp[:3, :3])


@dataclass(frozen=True)
class GuidePointEntry:
    """A guide point and its (0-based) index in the list."""

    index: int
    point: GuidePoint


# Where a force trace comes from (``ForceTrace.source``).
ForceSource = Literal["live", "recording", "none"]


@dataclass(frozen=True)
class ForceTrace:
    """Force against time for plots, decimated.

    Attributes:
        source: ``"live"`` (a job is running: |F| measured every 20 ms, time since the job
            started), ``"recording"`` (the last recording's force normal to the edge) or ``"none"``.
        time_s: (k,)
        force_N: (k,)
        force_reference_N: (k,) the reference (NaN when live).
        samples_total: Samples before decimation.
        force_min_N: (k,) smallest force of the samples each plotted point stands for (so
            spikes show however far the trace is decimated); None: not computed.
        force_max_N: (k,) largest force of those samples.
    """

    source: ForceSource
    time_s: np.ndarray
    force_N: np.ndarray
    force_reference_N: np.ndarray
    samples_total: int
    force_min_N: np.ndarray | None = None
    force_max_N: np.ndarray | None = None


# The last post-processing: its settings, result, and score (the core stage's value).
PostprocessOutcome = ProcessedPath


@dataclass(frozen=True)
class JobInfo:
    """A background job's public state."""

    id: str
    kind: str
    status: JobStatus
    progress: float
    error: str | None
    created_s: float
    started_s: float | None
    finished_s: float | None


@dataclass(frozen=True)
class ProjectInfo:
    """A stored project."""

    id: int
    name: str
    created_s: float
    updated_s: float
    is_open: bool
    notice: str = ""  # what the user must know about the open project ("" when nothing)


@dataclass(frozen=True)
class ExportInfo:
    """A saved export: its files in the store and, when the session has a data folder, on disk."""

    name: str
    created_s: float
    files: list[str]
    folder: Path | None


# --- the job runner ----------------------------------------------------------------------


def check_project_name(name: str) -> str:
    """``name`` stripped, when it is a valid project name (1-80 characters, no control
    characters)."""
    if not isinstance(name, str) or not name.strip():
        raise InvalidInputError("a project name must not be empty")
    name = name.strip()
    if len(name) > PROJECT_NAME_MAX:
        raise InvalidInputError(f"a project name is at most {PROJECT_NAME_MAX} characters")
    if any(ord(ch) < 32 for ch in name):
        raise InvalidInputError("a project name must not contain control characters")
    return name
