"""A ``Project`` to and from the SQLite store's rows (``app.store``), one part at a time.

The store's format is unchanged; the fingerprints that make staleness survive a restart and
the CMRR / compensation settings ride in the JSON documents it already has (``recordings.
info_json`` gets ``inputs``; ``projects.post_json`` gets ``inputs``, ``cmrr`` and
``compensation``). A project saved before these fields existed opens with its results taken as
current (nothing recorded what they were computed from).
"""

from __future__ import annotations

from dataclasses import asdict, replace
from typing import TYPE_CHECKING, Any, Literal

import numpy as np

from robomach_core import project as core
from robomach_core.cell import GuidePoint
from robomach_core.errors import RobomachError
from robomach_core.learning.settings import PathLearningSettings
from robomach_core.part import Workpiece
from robomach_core.postprocess import PostprocessSettings
from robomach_core.project import (
    CellSettings,
    LearnedPath,
    Project,
    cmrr_document,
    compensation_document,
    recording_inputs_key,
)

from ..store import GuidePointRow, ProjectData
from .machining import machining_document, machining_from_document
from .records import RECORDING_ARRAYS, log

if TYPE_CHECKING:
    from robomach_core.cmrr import CmrrSettings
    from robomach_core.stiffness import CompensationSettings

Part = Literal["cell", "guides", "recording", "post"]


def save_kwargs(project: Project, *parts: Part) -> dict[str, Any]:
    """Keyword arguments of ``Store.save`` writing these parts of the project."""
    out: dict[str, Any] = {}
    if "cell" in parts:
        out["cell"] = asdict(project.cell)
        out["mesh"] = project.mesh
        if project.robot_urdf is not None:  # the user's arm file rides in the cell document
            import base64

            name, data = project.robot_urdf
            out["cell"]["robot_urdf"] = [name, base64.b64encode(data).decode("ascii")]
    if "guides" in parts:
        out["guide_points"] = [
            GuidePointRow(g.T_base_tcp, g.joints_rad, g.time_s, g.force_N)
            for g in project.guide_points
        ]
    if "recording" in parts:
        out["recording"] = _recording_doc(project.learned)
    if "post" in parts:
        processed = project.processed
        out["post"] = {
            "settings": asdict(project.post_settings),
            "applied": processed is not None,
            "applied_settings": None if processed is None else asdict(processed.settings),
            "inputs": None if processed is None else processed.inputs,
            "cmrr": cmrr_document(project),
            "compensation": compensation_document(project),
            "machining": machining_document(project),
        }
    return out


def _recording_doc(learned: LearnedPath | None) -> tuple[dict, dict[str, np.ndarray]] | None:
    if learned is None:
        return None
    info = core.recording_document(learned)
    arrays = {k: getattr(learned.recording, k) for k in RECORDING_ARRAYS}
    arrays["guide_quaternions_wxyz"] = learned.guide_quaternions_wxyz
    return info, arrays


def cell_from_doc(doc: dict[str, Any]) -> CellSettings:
    """Cell settings from ``cell_json`` (unknown keys ignored, missing ones default)."""
    known = set(CellSettings.__dataclass_fields__)
    values = {k: v for k, v in doc.items() if k in known}
    urdf = robot_urdf_from_doc(doc)
    if urdf is not None:  # register the user's arm again so Robot(name) builds it
        from robomach_core.robots.custom import register_urdf

        register_urdf(*urdf)
    if values.get("wobj_mm_deg") is not None:
        values["wobj_mm_deg"] = tuple(float(v) for v in values["wobj_mm_deg"])
    return CellSettings(**values)


def robot_urdf_from_doc(doc: dict[str, Any]) -> tuple[str, bytes] | None:
    """(filename, bytes) of the user's arm file stored in ``cell_json``, or None."""
    import base64

    stored = doc.get("robot_urdf")
    return None if not stored else (stored[0], base64.b64decode(stored[1]))


def project_from_data(data: ProjectData, workpiece: Workpiece) -> Project:
    """The stored project; its post-processing is recomputed on ``workpiece`` (deterministic)."""
    pid = data.row.id
    cell = cell_from_doc(data.cell)
    mesh = data.mesh if not cell.workpiece_builtin else None
    guides = tuple(
        GuidePoint(g.T_base_tcp, g.joints_rad, g.time_s, g.force_N) for g in data.guide_points
    )
    project = Project(
        cell=cell, mesh=mesh, guide_points=guides, robot_urdf=robot_urdf_from_doc(data.cell)
    )
    post = data.post or {}
    try:
        project = replace(project, post_settings=PostprocessSettings(**post.get("settings", {})))
    except (TypeError, ValueError) as exc:
        log.error("project %s: post-processing settings unreadable (%s)", pid, exc)
    project = replace(project, learned=_learned(data, project))
    project = _process_settings(project, post, pid)
    project = machining_from_document(project, post.get("machining"))
    if post.get("applied") and project.learned is not None:
        try:
            applied = PostprocessSettings(**(post.get("applied_settings") or post["settings"]))
            processed = core.process(
                project.learned,
                applied,
                workpiece,
                cell.tool_radius_m,
                guides=project.learned_guides(),
            )
        except (RobomachError, TypeError, ValueError, KeyError) as exc:
            log.warning("project %s: stored post-processing no longer applies: %s", pid, exc)
        else:
            stored = post.get("inputs")
            if stored is None or stored == processed.inputs:
                project = replace(project, processed=processed)
            else:  # computed from a recording that is gone: it cannot be rebuilt
                log.warning("project %s: post-processing of an earlier recording dropped", pid)
    return project


def _learned(data: ProjectData, project: Project) -> LearnedPath | None:
    info = data.recording_info
    if info is None:
        return None
    arrays = data.recording_arrays
    try:
        recording = core.recording_from_document(info, {k: arrays[k] for k in RECORDING_ARRAYS})
        return LearnedPath(
            recording,
            arrays["guide_quaternions_wxyz"],
            PathLearningSettings(**info["learning"]),
            # Saved before fingerprints existed: take it as learned from what is stored.
            str(info.get("inputs") or recording_inputs_key(project)),
        )
    except (KeyError, TypeError, ValueError) as exc:  # written by another version
        log.error("project %s: cannot read its recording (%s); dropped", data.row.id, exc)
        return None


def _process_settings(project: Project, post: dict[str, Any], pid: int) -> Project:
    """The CMRR and compensation settings stored with the project (unreadable ones dropped)."""
    cmrr: CmrrSettings | None = None
    compensation: CompensationSettings | None = None
    if post.get("cmrr") is not None:
        from robomach_core.cmrr import settings_from_dict as cmrr_from_dict

        try:
            cmrr = cmrr_from_dict(post["cmrr"])
        except (RobomachError, TypeError, ValueError, KeyError) as exc:
            log.error("project %s: CMRR settings unreadable (%s); dropped", pid, exc)
    if post.get("compensation") is not None:
        from robomach_core.stiffness.settings import settings_from_dict as compensation_from_dict

        try:
            compensation = compensation_from_dict(post["compensation"])
        except (RobomachError, TypeError, ValueError, KeyError) as exc:
            log.error("project %s: compensation settings unreadable (%s); dropped", pid, exc)
    return replace(project, cmrr=cmrr, compensation=compensation)
