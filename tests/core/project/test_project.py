"""The project value: staleness by fingerprint, the one settings document, the one header."""

from __future__ import annotations

import json
from dataclasses import replace

import numpy as np
import pytest

from robomach_core import project as core
from robomach_core.cell import GuidePoint, Robot
from robomach_core.learning.run import Recording
from robomach_core.learning.settings import PathLearningSettings
from robomach_core.part import builtin_workpiece
from robomach_core.project._writers import rapid_header, rapid_text

N = 400  # samples: 1.6 s at 4 ms


def _guide(x_m: float) -> GuidePoint:
    T = np.eye(4)
    T[:3, 3] = (x_m, 0.135, 0.03)
    return GuidePoint(T, np.zeros(6), 0.0)


def _recording() -> Recording:
    """A straight pass along the block's front wall at 10 N (synthetic, exact)."""
    x = np.linspace(0.76, 0.84, N)
    position = np.column_stack([x, np.full(N, 0.134), np.full(N, 0.03)])
    quaternion = np.tile([1.0, 0.0, 0.0, 0.0], (N, 1))
    T0 = np.eye(4)
    T0[:3, 3] = position[0]
    # joints on the pose's IK branch, as a real recording's: the writers solve each target's
    # joints from them (export.target_joints) and refuse a jump to another branch
    q0 = Robot("ur10").ik(T0)
    return Recording(
        time_s=np.arange(N) * 0.004,
        joints_rad=np.tile(q0, (N, 1)),
        position_m=position,
        quaternion_wxyz=quaternion,
        wrench_sensor=np.zeros((N, 6)),
        wrench_tool=np.zeros((N, 6)),
        force_normal_N=np.full(N, 10.0),
        force_reference_N=np.full(N, 10.0),
        in_contact=np.ones(N, dtype=bool),
        yp=np.tile([0.0, 1.0, 0.0], (N, 1)),
        segment=np.zeros(N, dtype=int),
        stop_reason="reached the last guide point",
        completed=True,
    )


def learned_block_project() -> core.Project:
    """A project on the block: two guide points and a synthetic 400-sample recording, learned
    (not post-processed). The project, file and API tests start from it."""
    project = core.Project(
        cell=core.CellSettings(workpiece="block"), guide_points=(_guide(0.76), _guide(0.84))
    )
    learned = core.LearnedPath(
        _recording(),
        np.tile([1.0, 0.0, 0.0, 0.0], (2, 1)),
        PathLearningSettings(closed=False),
        core.recording_inputs_key(project),
    )
    return replace(project, learned=learned)


@pytest.fixture(scope="module")
def processed() -> tuple[core.Project, object]:
    workpiece = builtin_workpiece("block")
    project = learned_block_project()
    result = core.process(
        project.learned, project.post_settings, workpiece, project.cell.tool_radius_m
    )
    return replace(project, processed=result), workpiece


def test_status_follows_the_inputs(processed) -> None:
    project, _ = processed
    assert project.status() == {
        "guide_points": "current",
        "recording": "current",
        "postprocess": "current",
        "machining": "none",
    }
    machined = replace(
        project, machining="a run", machining_inputs=core.machining_inputs_key(project)
    )
    assert machined.status()["machining"] == "current"

    moved = replace(machined, guide_points=(_guide(0.76), _guide(0.85)))
    assert moved.status() == {
        "guide_points": "current",
        "recording": "stale",
        "postprocess": "stale",
        "machining": "stale",
    }
    assert set(moved.stale_reasons()) == {"recording", "postprocess", "machining"}
    # The same guide points again: current again (fingerprints, not flags).
    back = replace(moved, guide_points=(_guide(0.76), _guide(0.84)))
    assert back.status()["machining"] == "current"
    for cell in (
        replace(project.cell, seed=1),
        replace(project.cell, tool_radius_m=0.002),
        replace(project.cell, robot="ur5"),
    ):
        assert replace(machined, cell=cell).status()["postprocess"] == "stale", cell
    # The settings the next run will use do not make the last result stale.
    tighter = replace(project.post_settings, tolerance_m=1e-5)
    assert replace(project, post_settings=tighter).status()["postprocess"] == "current"
    # A new recording leaves the old post-processing stale, with the recording current.
    relearned = replace(
        project.learned, settings=PathLearningSettings(closed=False, speed_m_s=0.01)
    )
    status = replace(project, learned=relearned).status()
    assert (status["recording"], status["postprocess"]) == ("current", "stale")
    # Choosing a CMRR controller changes the program: the machining run is stale.
    assert replace(machined, compensation=_compensation()).status()["machining"] == "stale"


def test_writers_refuse_stale_and_missing_results(processed) -> None:
    project, workpiece = processed
    with pytest.raises(core.MissingResultError, match="run path learning"):
        core.require_processed(core.Project())
    with pytest.raises(core.MissingResultError, match="run post-processing"):
        core.require_processed(replace(project, processed=None))
    stale = replace(project, guide_points=project.guide_points[:1])
    with pytest.raises(core.StaleResultError, match="out of date"):
        rapid_text(stale, workpiece, robot=None)
    doc = core.settings_document(stale, workpiece)
    assert doc["status"]["postprocess"] == "stale"


def _compensation():
    from robomach_core.cell.joint_compliance import TRUE_JOINT_STIFFNESS_NM_RAD
    from robomach_core.stiffness import CompensationSettings

    return CompensationSettings("ur10", TRUE_JOINT_STIFFNESS_NM_RAD["ur10"], mode="offline")


def test_one_settings_document_and_one_header(processed) -> None:
    from robomach_core.cmrr import build_scenario, cmrr_settings_for, settings_for
    from robomach_core.export.rapid_check import check_rapid_module

    project, workpiece = processed
    cmrr = cmrr_settings_for(build_scenario("deburr-burrs"), settings_for("two-stage"))
    carried = replace(project, cmrr=cmrr, compensation=_compensation())
    files = core.program_files(carried, workpiece, robot=Robot("ur10"), project_name="p")
    assert set(files) == {
        "program.mod",
        "program_fc.mod",
        "program.script",  # a UR arm's language (project.program_languages)
        "program_fc.script",
        "targets.csv",
        "samples.csv",
        "settings.json",
    }
    doc = json.loads(files["settings.json"])
    assert doc["cmrr"]["controller"] == "two-stage" and doc["compensation"]["mode"] == "offline"
    assert doc["compensation"]["offline_model"] == "linear"
    assert doc["cell"]["workpiece"] == "block" and doc["path_learning"]["closed"] is False
    assert doc["result"]["targets"] == len(carried.processed.result.targets)
    program = files["program.mod"]
    check_rapid_module(program)
    header = "\n".join(rapid_header(carried, workpiece.name))
    assert all(f"! {line}" in program for line in header.splitlines())
    assert "FCSpdChgAct" in program and "CMRR: two-stage" in program
    # Zero learned wrench: compensation moves nothing (zero at zero load).
    correction = "deflection compensation: offline (linear), largest target correction 0.0000 mm"
    assert correction in program
    fc = files["program_fc.mod"]
    check_rapid_module(fc)
    assert fc.startswith("MODULE LearnedPathFC") and "FCSpdChgAct" not in fc
