"""Issue 29's acceptance: the program that leaves is the cut that was simulated. On the UR10,
the IRB 4400 and the KR 270 (the pump demo, seed 0), every configuration the cell can run is
chosen, its program files are written as the CLI writes them, read back in each language of
the arm (targets, speeds, feed control) and cut again: cycle, peak force and finished-wall
error within 2 % of the comparison table's. The feed control the program carries is the one
the configuration needs (FC SpeedChange in RAPID, the feed loop in URScript, none for the
constant feed and for a staged controller's offline row with its stages planned, whose stage
schedule is the program's speeds); what a KUKA controller cannot be given is not runnable
there, and says why (the planned-stage rows run there: they need nothing but the program).
(Slow: three demos and three 18-run comparisons.)"""

from __future__ import annotations

import functools
from dataclasses import replace

import numpy as np
import pytest

from robomach_core import project as core
from robomach_core.errors import InvalidInputError
from robomach_core.export.languages import languages_for
from robomach_core.export.read_back import read_program
from robomach_core.machining import MACHINING_CONTROLLERS, STAGE_PLANS
from robomach_core.machining.run import cut_program
from robomach_core.machining.schedule import STAGED_CONTROLLERS
from robomach_core.project._machining import compensation_model
from tests.shared_machining import machined as shared_machined

pytestmark = pytest.mark.slow
MM = 1e-3
# Every option each arm's controller can have, so every configuration it can run is checked.
CELLS = {
    "ur10": ("force_mode", "path_correction"),
    "irb4400": ("fc_speed_change", "path_correction"),
    "kr270": ("path_correction",),
}
FEED_CONTROL = {"rapid": "FC SpeedChange", "urscript": "URScript feed loop", "krl": None}
FIGURES = ("cycle_time_s", "force_peak_N", "wall_error_max_mm")


@functools.cache
def _machined(arm: str, stages: str):
    """The arm's 18-run comparison with the stages switched online (the default; the UR10's
    is tests/core/machining/test_acceptance.py's too: tests/shared_machining.py); with the
    stages planned (``machining.schedule``) the staged controllers' offline rows alone."""
    planned = stages == "planned"
    m = shared_machined(
        arm, CELLS[arm],
        STAGED_CONTROLLERS if planned else MACHINING_CONTROLLERS,
        ("offline",) if planned else ("off", "offline", "online"), stages,
    )  # fmt: skip
    return arm, core.with_machining_result(m.project, m.result), m.workpiece, m.robot, m.result


@pytest.fixture(scope="module", params=sorted(CELLS))
def machined(request):
    return _machined(request.param, "online")


@pytest.fixture(
    scope="module",
    params=[(arm, stages) for stages in STAGE_PLANS for arm in sorted(CELLS)],
    ids=lambda p: "-".join(p),
)
def machined_either(request):
    """``machined``, and the same arms with the staged controllers' stages planned."""
    return _machined(*request.param)


def test_every_runnable_configuration_cuts_from_its_files_what_the_table_shows(
    machined_either,
):
    arm, project, workpiece, robot, result = machined_either
    model = compensation_model(project, robot.name)
    q0 = core.require_processed(project).result.targets.joints_rad[0]
    runnable = [row for row in result.rows if row["runnable"]]
    assert runnable and all(row["completed"] for row in runnable)
    for row in runnable:
        c, m = row["controller"], row["compensation"]
        chosen = core.choose(project, c, m)
        files = core.program_files(chosen, workpiece, robot)
        settings = core.machining_setup_of(chosen).settings
        run = result.run_for(c, m)
        for language in languages_for(robot):
            path = read_program(language.name, files)
            # A staged controller's offline row carries its stage schedule as the speeds and
            # no feed control (``machining.schedule``); the read-back cut runs those speeds.
            scheduled = row.get("feed") == "program"
            expected = None if c == "constant" or scheduled else FEED_CONTROL[language.name]
            assert path.feed_control == expected, (arm, c, m, language.name)
            if expected is not None:
                assert path.reference_N == pytest.approx(settings.reference_N)
            assert path.speed_m_s.max() <= settings.command_speed_cap_m_s + 1e-12
            cut = cut_program(
                robot, path.targets(robot, q0), None, result.stock,
                replace(settings, compensation="online" if m == "online" else "off"),
                model=model if m == "online" else None,
                # A corrected program's offsets are measured from the nominal place of each
                # of its targets (the 1-D cut model's wall normal there).
                nominal=run.nominal if m == "offline" else None,
                feed="program" if scheduled else "controller",
            ).summary  # fmt: skip
            for key in FIGURES:
                assert cut[key] == pytest.approx(row[key], rel=0.02), (
                    arm, c, m, language.name, key, cut[key], row[key],
                )  # fmt: skip


def test_what_a_cell_cannot_run_is_marked_with_the_reason(machined_either):
    arm, project, _, _, result = machined_either
    for row in result.rows:
        needs_feed = row["controller"] != "constant" and row["feed"] != "program"
        if row["controller"] in STAGED_CONTROLLERS and row["compensation"] == "offline":
            planned = core.machining_setup_of(project).settings.stages == "planned"
            assert row["feed"] == ("program" if planned else "controller"), row
        if arm == "kr270" and needs_feed:
            assert not row["runnable"]
            assert "robomach writes none for a KUKA controller" in row["needs"][0]
        else:
            assert row["runnable"], row
    if arm == "kr270":
        with pytest.raises(InvalidInputError, match="fc_speed_change is for ABB"):
            core.with_machining_setup(
                project, core.MachiningSetup(cell_options=("fc_speed_change",))
            )


def test_the_constant_feed_is_written_as_cut_and_stays_within_the_limit(machined):
    arm, project, workpiece, robot, result = machined
    row = next(
        r for r in result.rows if (r["controller"], r["compensation"]) == ("constant", "off")
    )
    files = core.program_files(core.choose(project, "constant", "off"), workpiece, robot)
    feed = row["constant_feed_mm_s"] * MM
    for language in languages_for(robot):
        speeds = read_program(language.name, files).speed_m_s
        assert np.all(speeds <= feed + 1e-12) and np.isclose(speeds.max(), feed)
    assert row["force_peak_N"] <= row["force_limit_N"]
