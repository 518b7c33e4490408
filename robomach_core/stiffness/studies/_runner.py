"""``run_studies``: one study or all of them, with the summary JSON and the settings file."""

from __future__ import annotations

import json
from pathlib import Path
from typing import Any

from ..errors import UnknownStudyError
from ..identification import (
    StiffnessIdentification,
)
from ..settings import CompensationSettings, save_settings
from ._common import (
    DEFAULT_OPTIONS,
    PAPER_REFERENCES,
    SETTINGS_FILE,
    STUDIES,
    STUDY_WEIGHTS,
    SUMMARY_FILE,
    Cancel,
    Progress,
    StudyName,
    StudyOptions,
    StudyResult,
    _Progress,
    study_robot,
)
from ._compliance import run_compliance_study
from ._gravity import run_gravity_study
from ._identify import run_identification_study
from ._ilc import run_ilc_study
from ._milling import run_milling_study


def run_studies(
    study: StudyName = "all",
    out_dir: Path | str | None = None,
    options: StudyOptions = DEFAULT_OPTIONS,
    *,
    progress: Progress | None = None,
    cancel: Cancel | None = None,
) -> dict[str, StudyResult]:
    """Run one study or all of them, each on its paper's arm unless ``options.robot`` names
    one; with a folder, also write the summary JSON and the settings of the arm identified.
    A stiffness identified on an arm is reused by the later studies on that arm.

    Raises:
        UnknownStudyError: ``study`` is not one of identify, gravity, milling, ilc,
            compliance, all.
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
    models: dict = {}  # arm name -> identified JointCompliance
    tool_gravity = true_tool = None
    for name in names:
        part = report.slice(start / total, STUDY_WEIGHTS[name] / total)
        start += STUDY_WEIGHTS[name]
        if name == "identify":
            results[name] = run_identification_study(options, out, progress=part)
            models[study_robot(options, "identify")] = results[name].objects["identification"].model
        elif name == "gravity":
            results[name] = run_gravity_study(options, out, progress=part)
            tool_gravity = results[name].objects["tool_gravity"]
            true_tool = results[name].objects["true_tool_gravity"]
        elif name == "milling":
            results[name] = run_milling_study(
                options,
                out,
                models=models,
                tool_gravity=tool_gravity,
                true_tool_gravity=true_tool,
                progress=part,
            )
            models.update(results[name].objects["models"])
        elif name == "ilc":
            results[name] = run_ilc_study(
                options, out, model=models.get(study_robot(options, "ilc")), progress=part
            )
        else:
            results[name] = run_compliance_study(
                options, out, model=models.get(study_robot(options, "compliance")), progress=part
            )
    if out is not None:
        summary: dict[str, Any] = {
            "studies": list(names),
            "seed": options.seed,
            "robots": {n: study_robot(options, n) for n in names},
            "paper_references": PAPER_REFERENCES,
        }
        for result in results.values():
            summary.update(result.summary)
        (out / SUMMARY_FILE).write_text(json.dumps(summary, indent=2) + "\n", encoding="utf-8")
        if "identify" in results:
            ident: StiffnessIdentification = results["identify"].objects["identification"]
            mode = options.mode
            if mode == "online" and tool_gravity is None:
                mode = "offline"  # online needs the tool gravity of the gravity study
            save_settings(
                CompensationSettings(
                    robot=study_robot(options, "identify"),
                    joint_stiffness_Nm_rad=ident.model.stiffness_Nm_rad,
                    mode=mode,
                    offline_model=options.offline_model,
                    joint_stiffness_std_Nm_rad=tuple(ident.standard_error_Nm_rad.tolist()),
                    tool_gravity=tool_gravity,
                ),
                out / SETTINGS_FILE,
            )
    report(1.0)
    return results
