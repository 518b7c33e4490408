"""The project's values: cell settings, stage results, and the fingerprints that date them."""

from __future__ import annotations

import hashlib
import json
from dataclasses import asdict, dataclass, field
from functools import cached_property
from typing import TYPE_CHECKING, Any, Literal

import numpy as np

from ..cell import GuidePoint, Tool
from ..errors import RobomachError
from ..learning.run import Recording
from ..learning.settings import PathLearningSettings
from ..part import PartDeviation
from ..postprocess import PostprocessResult, PostprocessSettings
from ..scoring import PathScore
from ..teaching import WobjRegistration

if TYPE_CHECKING:  # the slots' types; their modules import this one
    from ..cmrr import CmrrSettings
    from ..learning.checks import TaughtWallCheck
    from ..scoring import CadComparison
    from ..stiffness import CompensationSettings
    from ._machining import MachiningResult, MachiningSetup

StageStatus = Literal["none", "current", "stale"]
STAGE_NAMES = ("guide_points", "recording", "postprocess", "machining")
DEFAULT_MODULE_NAME = "LearnedPath"
OVERCUT_MARGIN_M = 0.1e-3  # beyond the reduction's tolerance, a program's overcut is a fault: the
# learned samples' own spread at 10-20 N (0.05-0.1 mm) is not (a program 0.3 mm from the wall at the
# default 0.2 mm is a good one, issue 28)


class StaleResultError(RobomachError, RuntimeError):
    """A result is out of date with the project's inputs; re-run its stage before exporting."""


class MissingResultError(RobomachError, RuntimeError):
    """A stage has not run yet, so what depends on it cannot be produced."""


# --- the values ------------------------------------------------------------------------------


@dataclass(frozen=True)
class CellSettings:
    """The user's cell settings.

    Attributes:
        robot: A built-in arm (``robot.ROBOT_NAMES``: UR and ABB) or an uploaded URDF's
            name (``robots.custom``).
        tool_radius_m: Ball cutter radius.
        workpiece: Built-in name, or the stem of the uploaded mesh file.
        workpiece_builtin: False for an uploaded mesh (the project holds its bytes).
        seed: Seed of the sensor noise and the example operator.
        wobj_mm_deg: Work-object frame placing the workpiece (x, y, z [mm] in the robot base
            frame, then an optional rz, or rx, ry, rz [deg] about the fixed base axes x, then
            y, then z: ``robomach demo --wobj``'s numbers); None for the built-in placement in
            front of the arm. Where the part is meant to be; the real part may stand off it
            (``part_deviation``) until a calibration measures where it is.
        part_deviation: How the part in the cell differs from its mesh (``real_part``: a
            fixture error and casting deviations; ``PartDeviation.realistic()`` is the
            ``realistic`` preset); None: the part is its mesh. A dict (a saved document) is
            read as one.
        registration: The accepted work-object calibration (``registration``): the CAD is
            placed where touches of the real part found it, for teaching, the checks and the
            CAD-only program; None: at ``wobj_mm_deg``. A dict is read as one.
    """

    robot: str = "ur10"
    tool_radius_m: float = Tool.radius_m
    workpiece: str = "water_pump"
    workpiece_builtin: bool = True
    seed: int = 0
    wobj_mm_deg: tuple[float, ...] | None = None
    part_deviation: PartDeviation | None = None
    registration: WobjRegistration | None = None

    def __post_init__(self) -> None:
        if not (self.part_deviation is None or isinstance(self.part_deviation, PartDeviation)):
            object.__setattr__(
                self, "part_deviation", PartDeviation.from_value(self.part_deviation)
            )
        if not (self.registration is None or isinstance(self.registration, WobjRegistration)):
            object.__setattr__(self, "registration", WobjRegistration.from_value(self.registration))


@dataclass(frozen=True)
class LearnedPath:
    """The path-learning stage's result: the recording and what it was learned from.

    Attributes:
        recording: The 4 ms samples.
        guide_quaternions_wxyz: (n, 4) orientations of the guide points it followed.
        settings: The path-learning settings.
        inputs: Fingerprint of the cell and guide points it was learned from.
    """

    recording: Recording
    guide_quaternions_wxyz: np.ndarray
    settings: PathLearningSettings
    inputs: str

    @cached_property
    def key(self) -> str:
        """Fingerprint of this result (its inputs, settings and samples)."""
        rec = self.recording
        return _digest(
            self.inputs,
            _settings_json(self.settings),
            rec.time_s,
            rec.position_m,
            rec.force_normal_N,
            self.guide_quaternions_wxyz,
        )


@dataclass(frozen=True)
class ProcessedPath:
    """The post-processing stage's result: filter + reduction, and its score.

    Attributes:
        settings: The post-processing settings used.
        result: Keep mask, surface points and targets.
        samples_raw: Samples of the recording.
        score: Deviation from the true tool path (built-in workpieces), else None.
        inputs: Fingerprint of the recording and settings it was computed from.
        moves: The program's move sequence (``arcs.Move``) when arcs are fitted
            (``settings.arcs``); None for a straight move to every target.
        mesh_score: Deviation of the program from the workpiece mesh (every part).
        straight_targets: Targets of the straight (deviation-height) program, to compare the
            arc program's instruction count with; None when no arcs are fitted.
        taught_wall: Whether the program follows the wall the guide points were taught on
            (``mesh_score.TaughtWallCheck``); None when not checked.
        completed: Whether the recording it was made from reached its last guide point.
        cad_comparison: The program a CAD/CAM tool would make from the mesh alone and the
            learned one, both scored against the real wall (``cad_program``); None when the
            path follows no wall of the mesh.
        loop_ridge_m: For a closed loop, the ridge its end leaves short of its start
            (``postprocess.loop_ridge_m``); None for an open route.
    """

    settings: PostprocessSettings
    result: PostprocessResult
    samples_raw: int
    score: PathScore | None
    inputs: str
    moves: tuple[Any, ...] | None = None
    mesh_score: PathScore | None = None
    straight_targets: int | None = None
    taught_wall: TaughtWallCheck | None = None
    completed: bool = True
    cad_comparison: CadComparison | None = None
    loop_ridge_m: float | None = None

    def problems(self) -> list[str]:
        """What makes this program unfit to machine with, one line each (empty: none):
        learning ended early, another wall than the taught one, the cutter into the wall or
        off it beyond the reduction's tolerance (+ ``OVERCUT_MARGIN_M``), or a closed loop
        whose end stops short of its start by more than that."""
        out = []
        if not self.completed:
            out.append("path learning ended before the last guide point: the program is partial")
        if self.taught_wall is not None and not self.taught_wall.follows:
            out.append(self.taught_wall.message)
        mesh = self.mesh_score
        limit = self.settings.tolerance_m + OVERCUT_MARGIN_M
        if mesh is not None and mesh.overcut_m > limit:
            out.append(
                f"the program cuts {mesh.overcut_m * 1e3:.2f} mm into the part's wall (more "
                f"than the {self.settings.tolerance_m * 1e3:g} mm tolerance): an overcut"
            )
        if mesh is not None and self.completed and mesh.air_m > limit:
            out.append(
                f"the program leaves the part's wall by {mesh.air_m * 1e3:.2f} mm (more than the "
                f"{self.settings.tolerance_m * 1e3:g} mm tolerance): learn slower there, or add a "
                "guide point where it leaves the wall"
            )
        ridge = self.loop_ridge_m
        if self.completed and ridge is not None and ridge > limit:
            p = self.result.targets.position_m
            short = float(np.linalg.norm(p[-1] - p[0])) if len(p) else 0.0
            out.append(
                f"the loop ends short of its start, {short * 1e3:.1f} mm from it, and leaves "
                f"a {ridge * 1e3:.2f} mm ridge of wall uncut there (more than the "
                f"{self.settings.tolerance_m * 1e3:g} mm tolerance): learn it again"
            )
        return out


@dataclass(frozen=True)
class Project:
    """The state of one job (module docstring). SI units inside.

    Attributes:
        cell: Robot, tool radius, workpiece, seed, work-object placement.
        mesh: (filename, bytes) of an uploaded workpiece mesh (mm), None for a built-in one.
        guide_points: The recorded guide points, in order.
        learned: The last path-learning result.
        post_settings: The post-processing settings the user holds now.
        processed: The last post-processing result.
        cmrr: The chosen feed controller, or None: the program's machining moves are wrapped
            in an FC SpeedChange block.
        compensation: The identified stiffness and mode, or None: in the offline modes each
            target is corrected for the contact wrench learned at it.
        machining_settings: The machining run's settings (``MachiningSetup``), or None.
        machining: The machining run's result, or None.
        machining_inputs: Fingerprint the machining result was computed from
            (``machining_inputs_key`` of the project at the time).
        robot_urdf: (filename, bytes) of the user's own arm (a .urdf, or a .zip with its
            meshes) when ``cell.robot`` names one (``robots.custom.register_urdf``).
    """

    cell: CellSettings = field(default_factory=CellSettings)
    mesh: tuple[str, bytes] | None = None
    guide_points: tuple[GuidePoint, ...] = ()
    learned: LearnedPath | None = None
    post_settings: PostprocessSettings = field(default_factory=PostprocessSettings)
    processed: ProcessedPath | None = None
    cmrr: CmrrSettings | None = None
    compensation: CompensationSettings | None = None
    machining_settings: MachiningSetup | None = None
    machining: MachiningResult | None = None
    machining_inputs: str | None = None
    robot_urdf: tuple[str, bytes] | None = None

    @cached_property
    def cell_key(self) -> str:
        """Fingerprint of the cell (settings, uploaded mesh and robot file bytes)."""
        mesh = () if self.mesh is None else (self.mesh[0], self.mesh[1])
        if self.robot_urdf is not None:
            mesh = (*mesh, *self.robot_urdf)
        return _digest(json.dumps(asdict(self.cell), sort_keys=True), *mesh)

    @property
    def recording(self) -> Recording | None:
        """The last path-learning recording, or None."""
        return None if self.learned is None else self.learned.recording

    @cached_property
    def guides_key(self) -> str:
        """Fingerprint of the guide points (poses and joints)."""
        return _digest(*(a for g in self.guide_points for a in (g.T_base_tcp, g.joints_rad)))

    def tool(self) -> Tool:
        """The cell's tool."""
        return Tool(radius_m=self.cell.tool_radius_m)

    def learned_guides(self) -> tuple[GuidePoint, ...] | None:
        """The guide points the recording was learned from: the project's while the recording
        is current; None once they or the cell changed (a stale recording is judged against no
        guide points rather than others: a point recorded after learning failed
        post-processing with a 503, and a moved one would judge the program by a wall it was
        never taught)."""
        return self.guide_points if self._recording_current() else None

    def _recording_current(self) -> bool:
        """A recording learned from the project's guide points and cell as they are."""
        return self.learned is not None and self.learned.inputs == recording_inputs_key(self)

    def status(self) -> dict[str, StageStatus]:
        """Per stage (``STAGE_NAMES``): ``"none"``, ``"current"`` or ``"stale"``."""
        out: dict[str, StageStatus] = {
            "guide_points": "current" if self.guide_points else "none",
            "recording": "none",
            "postprocess": "none",
            "machining": "none",
        }
        upstream_ok = True
        if self.learned is not None:
            upstream_ok = self._recording_current()
            out["recording"] = "current" if upstream_ok else "stale"
        if self.processed is not None:
            ok = (
                upstream_ok
                and self.learned is not None
                and self.processed.inputs
                == processed_inputs_key(self.learned, self.processed.settings)
            )
            out["postprocess"] = "current" if ok else "stale"
            upstream_ok = ok
        else:
            upstream_ok = False
        if self.machining is not None:
            ok = upstream_ok and self.machining_inputs == machining_inputs_key(self)
            out["machining"] = "current" if ok else "stale"
        return out

    def stale_reasons(self) -> dict[str, str]:
        """A sentence per stale stage saying why (for GUIs and error messages)."""
        status = self.status()
        reasons = {}
        if status["recording"] == "stale":
            reasons["recording"] = (
                "the guide points or the cell changed after path learning: learn the path again"
            )
        if status["postprocess"] == "stale":
            reasons["postprocess"] = (
                "post-processed from an out-of-date recording: "
                + ("learn the path again, then " if status["recording"] == "stale" else "")
                + "run post-processing again"
            )
        if status["machining"] == "stale":
            reasons["machining"] = "its program or settings changed: run the machining again"
        return reasons


# --- fingerprints ----------------------------------------------------------------------------


def _settings_json(settings: Any) -> str:
    return json.dumps(asdict(settings), sort_keys=True, default=str)


def _digest(*parts: Any) -> str:
    h = hashlib.blake2b(digest_size=12)
    for part in parts:
        if isinstance(part, np.ndarray):
            a = np.ascontiguousarray(part)
            h.update(str((a.dtype.str, a.shape)).encode())
            h.update(a.tobytes())
        elif isinstance(part, bytes):
            h.update(part)
        else:
            h.update(str(part).encode())
        h.update(b"\x00")
    return h.hexdigest()


def recording_inputs_key(project: Project) -> str:
    """What a recording of this project must have been learned from (cell + guide points)."""
    return _digest(project.cell_key, project.guides_key)


def processed_inputs_key(learned: LearnedPath, settings: PostprocessSettings) -> str:
    """What a post-processing result of ``learned`` with ``settings`` is computed from."""
    return _digest(learned.key, _settings_json(settings))


def machining_inputs_key(project: Project) -> str:
    """What a machining result of this project is computed from: the processed path, the
    machining, CMRR and compensation settings. Stamp ``Project.machining_inputs`` with it."""
    processed = project.processed.inputs if project.processed is not None else ""
    setup = project.machining_settings
    if setup is not None:  # its settings, stock and the stiffness it cuts with
        return _digest(processed, setup.inputs_key(project))
    return _digest(
        processed,
        json.dumps(cmrr_document(project), sort_keys=True),
        json.dumps(compensation_document(project), sort_keys=True),
    )


def cmrr_document(project: Project) -> dict[str, Any] | None:
    """The CMRR settings as in ``cmrr_settings.json``, or None."""
    if project.cmrr is None:
        return None
    from ..cmrr import settings_to_dict

    return settings_to_dict(project.cmrr)


def compensation_document(project: Project) -> dict[str, Any] | None:
    """The compensation settings as in ``compensation_settings.json``, or None."""
    if project.compensation is None:
        return None
    from ..stiffness.settings import settings_to_dict

    return settings_to_dict(project.compensation)
