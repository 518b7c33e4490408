"""The project's transitions: each change a user makes to a job, as a pure function.

PROBLEM   The workbench (viser, REST, pendant) and the CLI change the same ``Project``: the
          cell, an uploaded mesh or arm, the guide points, the result of a stage, the process
          settings. Written inside the workbench's session, each rule (a cell change clears
          the guide points; a learning force outside the filter's band moves the band) lived
          in one caller only, and the CLI built its projects another way.
STRATEGY  One function per change, ``Project -> Project``, checking its input and raising the
          core's errors; no I/O, no live state. What a change makes stale is left to the
          fingerprints (``Project.status``).
SOLUTION  ``with_cell``, ``with_registration``, ``with_uploaded_mesh`` (``mesh_file_name``),
          ``with_robot_file``,
          ``with_guide_points``, ``with_guide_point_added``, ``without_guide_point``,
          ``with_guide_point_at``, ``with_learned``,
          ``post_settings_with``, ``with_processed``, ``with_process_settings``. The session
          applies them under its lock and saves; ``robomach demo`` builds its project with them
          and ``pipeline.run_demo`` applies the stages' in order.
"""

from __future__ import annotations

import re
from collections.abc import Iterable
from dataclasses import replace
from pathlib import Path
from typing import TYPE_CHECKING, Any

from ..cell import GuidePoint
from ..errors import ConflictError, InvalidInputError, NotFoundError
from ..limits import GUIDE_POINTS_MAX
from ..postprocess import PostprocessSettings
from ..teaching import WobjRegistration
from ._value import LearnedPath, ProcessedPath, Project, processed_inputs_key

if TYPE_CHECKING:
    from ..cmrr import CmrrSettings
    from ..stiffness import CompensationSettings

KEEP: Any = object()  # ``with_cell``: leave this setting as it is
UPLOAD_STEM_CHARS = 40


def upload_stem(filename: str, default: str = "uploaded") -> str:
    """The name an uploaded file is known by: its stem, letters, digits, ``_`` and ``-``."""
    return re.sub(r"[^A-Za-z0-9_-]", "_", Path(filename).stem)[:UPLOAD_STEM_CHARS] or default


def with_cell(
    project: Project,
    *,
    robot: str | None = None,
    tool_radius_m: float | None = None,
    workpiece: str | None = None,
    part_deviation: Any = KEEP,
    wobj_mm_deg: Any = KEEP,
    seed: int | None = None,
) -> Project:
    """The project in another cell; None keeps a setting (``part_deviation``: a
    ``real_part.PartDeviation``, None for a part that is its mesh; ``wobj_mm_deg``: the
    work-object placement, x, y, z [mm] and an optional rz or rx, ry, rz [deg], None for the
    built-in placement; ``KEEP`` keeps either). ``workpiece`` is a built-in name or the
    uploaded mesh's own. A change clears the guide points (poses of the old cell) and a
    built-in arm drops the uploaded arm's file; a change of arm, part, placement or deviation
    drops the work-object calibration (it measured the part where it was); the results stay,
    stale by their fingerprints. No change returns ``project`` itself."""
    from ..part import WORKPIECE_NAMES
    from ..robots.custom import is_custom, uploaded_file
    from ._file_check import check_wobj

    cur, mesh = project.cell, project.mesh
    if wobj_mm_deg is not KEEP and wobj_mm_deg is not None:
        wobj_mm_deg = tuple(check_wobj(list(wobj_mm_deg)))
    new = replace(
        cur,
        robot=cur.robot if robot is None else robot.lower(),
        tool_radius_m=cur.tool_radius_m if tool_radius_m is None else float(tool_radius_m),
        part_deviation=cur.part_deviation if part_deviation is KEEP else part_deviation,
        wobj_mm_deg=cur.wobj_mm_deg if wobj_mm_deg is KEEP else wobj_mm_deg,
        seed=cur.seed if seed is None else int(seed),
    )
    if workpiece in WORKPIECE_NAMES:
        new, mesh = replace(new, workpiece=workpiece, workpiece_builtin=True), None
    elif workpiece is not None and not (mesh is not None and workpiece == cur.workpiece):
        uploaded = f", or {cur.workpiece!r} (uploaded)" if mesh is not None else ""
        raise InvalidInputError(
            f"unknown workpiece {workpiece!r}; use one of {', '.join(WORKPIECE_NAMES)}"
            f"{uploaded}, or upload a mesh file"
        )
    if new == cur and mesh == project.mesh:
        return project
    moved = (new.robot, new.workpiece, new.wobj_mm_deg, new.part_deviation) != (
        cur.robot,
        cur.workpiece,
        cur.wobj_mm_deg,
        cur.part_deviation,
    ) or mesh != project.mesh
    if moved:
        new = replace(new, registration=None)
    # A user's arm carries its own file: the project's when the arm stays, else the file that
    # arm was uploaded from (another upload of this process).
    urdf = None
    if is_custom(new.robot):
        same = new.robot == cur.robot and project.robot_urdf is not None
        urdf = project.robot_urdf if same else uploaded_file(new.robot)
    return replace(project, cell=new, mesh=mesh, guide_points=(), robot_urdf=urdf)


def mesh_file_name(filename: str) -> str:
    """The name an uploaded mesh file is kept under (``upload_stem`` and its type).

    Raises:
        InvalidInputError: not a mesh type the workbench reads (STL, OBJ, PLY).
    """
    from ..part import MESH_SUFFIXES

    suffix = Path(filename).suffix.lower()
    if suffix not in MESH_SUFFIXES:
        raise InvalidInputError(
            f"{filename!r}: unsupported mesh type; upload one of {', '.join(MESH_SUFFIXES)}"
        )
    return upload_stem(filename) + suffix


def with_uploaded_mesh(project: Project, filename: str, data: bytes) -> Project:
    """The project with a mesh file (STL/OBJ/PLY, mm) as its workpiece, known by the file's
    stem (``mesh_file_name``); the guide points are cleared as by a cell change. Parse the
    bytes first (``workpiece.mesh_from_bytes``): this checks only the file type."""
    name = mesh_file_name(filename)
    cell = replace(
        project.cell, workpiece=Path(name).stem, workpiece_builtin=False, registration=None
    )
    return replace(project, cell=cell, mesh=(name, bytes(data)), guide_points=())


def with_robot_file(project: Project, filename: str, data: bytes, robot: str) -> Project:
    """The project on the user's own arm, registered as ``robot``
    (``robots.custom.register_urdf``) from ``(filename, data)``, which the project keeps so
    that it opens again anywhere; the guide points are cleared as by a cell change."""
    cell = replace(project.cell, robot=robot, registration=None)
    return replace(project, cell=cell, robot_urdf=(filename, bytes(data)), guide_points=())


def with_registration(project: Project, registration: WobjRegistration | None) -> Project:
    """The project with its work object calibrated (``registration.WobjRegistration``: the
    CAD placed where touches of the real part found it), or back at its placement (None).
    The guide points stay (they are where the robot stood); what was learned becomes stale
    by the cell's fingerprint. No change returns ``project`` itself."""
    if registration is not None and not isinstance(registration, WobjRegistration):
        registration = WobjRegistration.from_value(registration)
    if registration == project.cell.registration:
        return project
    return replace(project, cell=replace(project.cell, registration=registration))


def with_guide_points(project: Project, guides: Iterable[GuidePoint]) -> Project:
    """New guide points, in order (at most ``limits.GUIDE_POINTS_MAX``); what was learned
    from the old ones becomes stale by its fingerprint."""
    guides = tuple(guides)
    if len(guides) > GUIDE_POINTS_MAX:
        raise ConflictError(f"a project holds at most {GUIDE_POINTS_MAX} guide points")
    return replace(project, guide_points=guides)


def with_guide_point_added(project: Project, point: GuidePoint) -> Project:
    """The guide points with ``point`` after the last."""
    return with_guide_points(project, (*project.guide_points, point))


def with_guide_point_at(project: Project, index: int, point: GuidePoint) -> Project:
    """``point`` in place of guide point ``index`` (from 0)."""
    guides = list(project.guide_points)
    _check_index(index, len(guides))
    guides[index] = point
    return with_guide_points(project, guides)


def without_guide_point(project: Project, index: int) -> Project:
    """The guide points without the one at ``index`` (from 0); later ones move down by one."""
    guides = project.guide_points
    _check_index(index, len(guides))
    return with_guide_points(project, guides[:index] + guides[index + 1 :])


def _check_index(index: int, count: int) -> None:
    if not (0 <= index < count):
        raise NotFoundError(f"no guide point {index}; there are {count} (indexes from 0)")


def with_learned(project: Project, learned: LearnedPath) -> Project:
    """The recording of a path-learning run replaces the last; the last post-processing stays,
    stale by its fingerprint. A force filter band that would not keep samples at the learning
    force moves to 0.5-1.5 x that force (``PostprocessSettings.for_learning_force``)."""
    post = project.post_settings.for_learning_force(learned.settings.force_N)
    return replace(project, learned=learned, post_settings=post)


def post_settings_with(
    project: Project,
    *,
    force_min_N: float | None = None,
    force_max_N: float | None = None,
    tolerance_m: float | None = None,
    arcs: bool | None = None,
    arc_tolerance_m: float | None = None,
) -> PostprocessSettings:
    """The project's post-processing settings with the given ones changed (None keeps one)."""
    cur = project.post_settings
    return replace(
        cur,
        force_min_N=cur.force_min_N if force_min_N is None else float(force_min_N),
        force_max_N=cur.force_max_N if force_max_N is None else float(force_max_N),
        tolerance_m=cur.tolerance_m if tolerance_m is None else float(tolerance_m),
        arcs=cur.arcs if arcs is None else bool(arcs),
        arc_tolerance_m=cur.arc_tolerance_m if arc_tolerance_m is None else arc_tolerance_m,
    )


def with_processed(project: Project, processed: ProcessedPath) -> Project:
    """The post-processing result, and its settings as the ones the user holds now.

    Raises:
        ConflictError: it was computed from another recording than the project's.
    """
    learned = project.learned
    if learned is None or processed.inputs != processed_inputs_key(learned, processed.settings):
        raise ConflictError(
            "the recording or the cell changed while post-processing ran; run it again"
        )
    return replace(project, post_settings=processed.settings, processed=processed)


def with_process_settings(
    project: Project,
    cmrr: CmrrSettings | None,
    compensation: CompensationSettings | None,
) -> Project:
    """The CMRR controller and the compensation the exported program carries (None removes
    one). Compensation identified on another arm is refused."""
    if compensation is not None and compensation.robot != project.cell.robot:
        raise InvalidInputError(
            f"the compensation settings were identified on {compensation.robot}, "
            f"the cell has {project.cell.robot}"
        )
    return replace(project, cmrr=cmrr, compensation=compensation)
