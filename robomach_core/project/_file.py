"""A project as one file (``project.npz``): what ``robomach demo`` leaves for ``robomach machine
--from`` and for the workbench to open.

The file holds the inputs of every stage and the recording (arrays), plus one JSON document
(cell, learning, post-processing, CMRR, compensation and machining settings). The
post-processing is recomputed on load (deterministic, so its fingerprint and the program come
out the same); machining results are not stored (they are re-run).
"""

from __future__ import annotations

import io
import json
import math
from dataclasses import asdict, replace
from pathlib import Path
from typing import Any

import numpy as np

from ..cell import GuidePoint
from ..learning.run import LearningStop, Recording
from ..learning.settings import PathLearningSettings
from ..postprocess import PostprocessSettings
from ._file_check import RECORDING_FIELDS, ProjectFileError, check_project, read_project_arrays
from ._machining import MachiningSetup
from ._machining_documents import machining_setup_document, machining_setup_from_document
from ._stages import build_cell_workpiece, process
from ._value import CellSettings, LearnedPath, Project, cmrr_document, compensation_document

PROJECT_FILE = "project.npz"
FORMAT = "robomach-project"
VERSION = 1


def project_file_bytes(project: Project) -> bytes:
    """The project as ``project.npz`` bytes (stage inputs, recording, settings)."""
    doc: dict[str, Any] = {
        "format": FORMAT,
        "version": VERSION,
        "cell": asdict(project.cell),
        "mesh_name": None if project.mesh is None else project.mesh[0],
        "robot_urdf_name": None if project.robot_urdf is None else project.robot_urdf[0],
        "guide_times_s": [g.time_s for g in project.guide_points],
        "post_settings": asdict(project.post_settings),
        "processed": project.processed is not None,
        "applied_settings": None
        if project.processed is None
        else asdict(project.processed.settings),
        "cmrr": cmrr_document(project),
        "compensation": compensation_document(project),
        "machining": None
        if not isinstance(project.machining_settings, MachiningSetup)
        else machining_setup_document(project.machining_settings),
    }
    arrays: dict[str, np.ndarray] = {}
    if project.guide_points:
        arrays["guide_T_base_tcp"] = np.array([g.T_base_tcp for g in project.guide_points])
        arrays["guide_joints_rad"] = np.array([g.joints_rad for g in project.guide_points])
        arrays["guide_force_N"] = np.array([g.force_N for g in project.guide_points])
    if project.mesh is not None:
        arrays["mesh_bytes"] = np.frombuffer(project.mesh[1], dtype=np.uint8)
    if project.robot_urdf is not None:
        arrays["robot_urdf_bytes"] = np.frombuffer(project.robot_urdf[1], dtype=np.uint8)
    learned = project.learned
    if learned is not None:
        for name in RECORDING_FIELDS:
            arrays[f"rec_{name}"] = np.asarray(getattr(learned.recording, name))
        arrays["guide_quaternions_wxyz"] = learned.guide_quaternions_wxyz
        doc["recording"] = recording_document(learned)
    setup = project.machining_settings
    if isinstance(setup, MachiningSetup) and setup.stock_mesh is not None:
        arrays["stock_mesh_bytes"] = np.frombuffer(setup.stock_mesh[1], dtype=np.uint8)
    arrays["document"] = np.frombuffer(json.dumps(doc).encode(), dtype=np.uint8)
    buffer = io.BytesIO()
    # numpy's stub: a ** mapping could hold allow_pickle, so it must be bool as well.
    np.savez_compressed(buffer, **arrays)  # type: ignore[arg-type]
    return buffer.getvalue()


def recording_document(learned: LearnedPath) -> dict[str, Any]:
    """A learned path's recording document, JSON-ready (its arrays, ``RECORDING_FIELDS`` and
    the guide quaternions, are kept apart): the project file's and the workbench store's."""
    rec = learned.recording
    return {
        "stop_reason": rec.stop_reason,
        "completed": rec.completed,
        "stop": None if rec.stop is None else rec.stop.document(),
        "wall_side": rec.wall_side,
        "wall_side_reason": rec.wall_side_reason,
        "wall_side_source": rec.wall_side_source,
        "guide_lift_m": list(rec.guide_lift_m),
        "guide_travel": [list(t) for t in rec.guide_travel],
        "learning": asdict(learned.settings),
        "inputs": learned.inputs,
    }


def recording_from_document(info: dict[str, Any], fields: dict[str, np.ndarray]) -> Recording:
    """The ``Recording`` of a ``recording_document`` and its ``RECORDING_FIELDS`` arrays."""
    return Recording(
        **fields,
        stop_reason=str(info["stop_reason"]),
        completed=bool(info["completed"]),
        stop=LearningStop.from_document(info.get("stop")),
        wall_side=str(info.get("wall_side", "")),
        wall_side_reason=str(info.get("wall_side_reason", "")),
        wall_side_source=str(info.get("wall_side_source", "")),
        guide_lift_m=_finite_floats(info.get("guide_lift_m")),
        guide_travel=_directions(info.get("guide_travel")),
    )


def save_project_file(project: Project, path: str | Path) -> Path:
    """Write ``project_file_bytes`` to ``path``."""
    out = Path(path)
    out.write_bytes(project_file_bytes(project))
    return out


def load_project_file(path: str | Path) -> Project:
    """The project of a ``project.npz`` (its post-processing recomputed).

    Raises:
        ProjectFileError: no such file, not a robomach project, or an unknown version.
    """
    p = Path(path)
    if not p.is_file():
        raise ProjectFileError(f"{p}: no such file")
    return project_from_file_bytes(p.read_bytes(), str(p))


def project_from_file_bytes(data: bytes, name: str = "project.npz") -> Project:
    """``load_project_file`` from bytes (uploads)."""
    arrays = read_project_arrays(data, name)  # headers checked before any array is read
    try:
        doc = json.loads(arrays.pop("document").tobytes().decode())
    except (UnicodeDecodeError, ValueError) as exc:
        raise ProjectFileError(f"{name}: not a robomach project file ({exc})") from None
    if not isinstance(doc, dict) or doc.get("format") != FORMAT or doc.get("version") != VERSION:
        doc = doc if isinstance(doc, dict) else {}
        raise ProjectFileError(
            f"{name}: not a robomach project file of version {VERSION} "
            f"(format {doc.get('format')!r}, version {doc.get('version')!r})"
        )
    check_project(doc, arrays, name)  # lengths, types, finite, in range: before it is used
    try:
        return _project(doc, arrays)
    except (KeyError, TypeError, ValueError, AttributeError, OverflowError) as exc:
        raise ProjectFileError(f"{name}: incomplete or damaged project file ({exc})") from None


def register_robot_file(robot: str, robot_urdf: tuple[str, bytes]) -> None:
    """Register the user's arm a project names (``robots.custom.register_urdf``: a new process
    knows only the built-in arms), under ``robot``: its file's name, or that name with a
    controller family (``<name>_<family>``).

    Raises:
        RobotFileError: the file is not a 6-axis URDF, or not the arm ``robot`` names.
    """
    from ..robots.custom import RobotFileError, is_custom, register_urdf

    name = register_urdf(*robot_urdf)
    variant = robot.startswith(name + "_") and is_custom(robot)  # registers on the way
    if robot != name and not variant:
        raise RobotFileError(
            f"{robot_urdf[0]}: the project's arm is {robot!r}, the file it holds is {name!r}"
        )


def _project(doc: dict[str, Any], arrays: dict[str, np.ndarray]) -> Project:
    cell_doc = dict(doc["cell"])
    if cell_doc.get("wobj_mm_deg") is not None:
        cell_doc["wobj_mm_deg"] = tuple(float(v) for v in cell_doc["wobj_mm_deg"])
    cell = CellSettings(**cell_doc)
    mesh = robot_urdf = None
    if doc.get("mesh_name") is not None:
        mesh = (str(doc["mesh_name"]), arrays["mesh_bytes"].tobytes())
    if doc.get("robot_urdf_name") is not None:
        robot_urdf = (str(doc["robot_urdf_name"]), arrays["robot_urdf_bytes"].tobytes())
        register_robot_file(cell.robot, robot_urdf)
    guides = tuple(
        GuidePoint(T, q, float(t), f)
        for T, q, t, f in zip(
            arrays.get("guide_T_base_tcp", ()),
            arrays.get("guide_joints_rad", ()),
            doc["guide_times_s"],
            arrays.get("guide_force_N", ()),
            strict=True,
        )
    )
    project = Project(
        cell=cell,
        mesh=mesh,
        guide_points=guides,
        post_settings=PostprocessSettings(**doc["post_settings"]),
        robot_urdf=robot_urdf,
    )
    if doc.get("cmrr") is not None:
        from ..cmrr import settings_from_dict

        project = replace(project, cmrr=settings_from_dict(doc["cmrr"]))
    if doc.get("compensation") is not None:
        from ..stiffness.settings import settings_from_dict as compensation_from_dict

        project = replace(project, compensation=compensation_from_dict(doc["compensation"]))
    if doc.get("machining") is not None:
        stock_mesh = None
        if doc["machining"].get("stock_mesh") is not None:
            stock_mesh = (str(doc["machining"]["stock_mesh"]), arrays["stock_mesh_bytes"].tobytes())
        project = replace(
            project, machining_settings=machining_setup_from_document(doc["machining"], stock_mesh)
        )
    info = doc.get("recording")
    if info is None:
        return project
    recording = recording_from_document(
        info, {name: arrays[f"rec_{name}"] for name in RECORDING_FIELDS}
    )
    learned = LearnedPath(
        recording,
        arrays["guide_quaternions_wxyz"],
        PathLearningSettings(**info["learning"]),
        str(info["inputs"]),
    )
    project = replace(project, learned=learned)
    if doc.get("processed"):
        applied = PostprocessSettings(**(doc.get("applied_settings") or doc["post_settings"]))
        workpiece = build_cell_workpiece(cell, mesh)
        processed = process(
            learned, applied, workpiece, cell.tool_radius_m, guides=project.learned_guides()
        )
        project = replace(project, processed=processed)
    return project


def _finite_floats(value: object) -> tuple[float, ...]:
    """A list of finite numbers from a project file as a tuple; anything else as none (an
    older or hand-edited file: the checks then look for the walls at the points' heights)."""
    if not isinstance(value, list) or not all(
        isinstance(v, int | float) and not isinstance(v, bool) and math.isfinite(v) for v in value
    ):
        return ()
    return tuple(float(v) for v in value)


def _directions(value: object) -> tuple[tuple[float, float, float], ...]:
    """A list of (3,) directions from a project file as a tuple; anything else as none (an
    older or hand-edited file: the checks then take each point's side from the chords)."""
    if not isinstance(value, list) or not all(isinstance(v, list) and len(v) == 3 for v in value):
        return ()
    rows = tuple(_finite_floats(v) for v in value)
    if any(len(r) != 3 for r in rows):
        return ()
    return tuple((r[0], r[1], r[2]) for r in rows)
