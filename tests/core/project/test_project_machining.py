"""The project's machining stage: the choice rule, the choice as one setting with the CMRR and
compensation slots, staleness, and the project file."""

from __future__ import annotations

from dataclasses import replace

import pytest

from robomach_core import project as core
from robomach_core.cmrr import CmrrSettings
from robomach_core.cmrr.controllers import settings_for
from robomach_core.machining import MachiningSettings
from robomach_core.project._machining import best_row
from tests.demo_project import block_demo_dir


def _row(controller, compensation, cycle, peak, wall, completed=True):
    return {
        "controller": controller,
        "compensation": compensation,
        "cycle_time_s": cycle if completed else None,
        "force_peak_N": peak,
        "force_limit_N": 150.0,
        "wall_error_max_mm": wall,
        "completed": completed,
    }


def test_the_rule_takes_the_fastest_runs_within_the_limit_then_the_best_wall():
    rows = [
        _row("constant", "off", 240.0, 146.0, 0.12),
        _row("fuzzy", "off", 140.0, 149.0, 0.13),
        _row("fuzzy", "online", 142.0, 150.0, 0.011),  # within 5 % of 140 s: best wall
        _row("adaptive-pi", "online", 136.0, 150.2, 0.010),  # faster, 0.2 N over the limit
        _row("adaptive-lq", "off", 130.0, 219.0, 0.001),  # fastest, 46 % over the limit
        _row("two-stage", "off", 100.0, 150.0, 0.0, completed=False),  # stopped
    ]
    assert best_row(rows) == 2
    assert best_row([rows[0], rows[4]]) == 0
    assert best_row([rows[5]]) is None  # nothing completed: nothing to choose
    # Nothing within the limit: nothing chosen, and the reason says which came closest.
    from robomach_core.machining.choice import CellCapabilities, choose

    pick = choose(
        [rows[3], rows[4]], CellCapabilities(frozenset({"fc_speed_change", "path_correction"}))
    )
    assert pick.index is None and "150.2 N, adaptive-pi / online" in pick.reason


def test_the_rule_chooses_only_what_the_cell_can_run_and_says_why():
    from robomach_core.machining.choice import CellCapabilities, choose, mark_runnable

    rows = [
        _row("constant", "off", 240.0, 146.0, 0.12),
        _row("adaptive-pi", "offline", 137.0, 145.0, 0.03),
        _row("adaptive-pi", "online", 136.0, 147.0, 0.011),  # best, needs path correction
        _row("fixed-pi", "online", 136.0, 149.0, 0.007),
    ]
    abb = CellCapabilities.for_language("rapid")
    assert abb.options == {"fc_speed_change"}
    pick = choose(rows, abb)
    assert pick.index == 1
    assert "adaptive-pi / offline" in pick.reason and "2 configurations need options" in pick.reason
    marked = mark_runnable(rows, abb)
    assert [r["runnable"] for r in marked] == [True, True, False, False]
    assert marked[2]["needs"] == ["an online path-correction interface"]
    # A KUKA controller gets no feed override from robomach: the row says so.
    kuka = CellCapabilities.for_language("krl")
    assert "robomach writes none for a KUKA" in mark_runnable(rows, kuka)[1]["needs"][0]
    full = CellCapabilities(frozenset({"fc_speed_change", "path_correction"}))
    assert choose(rows, full).index == 3
    # A cell with no option at all can still run the constant feed.
    assert choose(rows, CellCapabilities()).index == 0
    assert CellCapabilities.for_language("urscript").options == {"force_mode"}
    assert CellCapabilities.for_language("a language not listed").options == frozenset()
    # With a variation sweep the rule reads the 95th percentiles and needs every stock done.
    p95 = [
        dict(r, cycle_time_p95_s=r["cycle_time_s"], force_peak_p95_N=r["force_peak_N"],
             wall_error_max_p95_mm=r["wall_error_max_mm"], completed_share=1.0)
        for r in rows
    ]  # fmt: skip
    p95[1]["force_peak_p95_N"] = 200.0  # trips the limit on one stock in twenty
    assert choose(p95, abb).index == 0
    assert "95th percentiles" in choose(p95, abb).reason


@pytest.fixture(scope="module")
def block_project() -> core.Project:
    return core.load_project_file(block_demo_dir() / "project.npz")


@pytest.mark.slow  # the shared block demo run (tests/demo_project.py)
def test_the_project_file_reopens_current_with_the_same_program(block_project):
    from robomach_core.cell import Robot

    p = block_project
    assert p.status() == {
        "guide_points": "current",
        "recording": "current",
        "postprocess": "current",
        "machining": "none",
    }
    workpiece = core.build_workpiece(p.cell, p.mesh)
    robot = Robot(p.cell.robot, p.tool().T_flange_tcp)
    files = core.program_files(p, workpiece, robot)
    assert files["program.mod"] == (block_demo_dir() / "program.mod").read_text()
    again = core.project_from_file_bytes(core.project_file_bytes(p))
    assert core.processed_inputs_key(again.learned, again.post_settings) == (p.processed.inputs)
    with pytest.raises(core.ProjectFileError, match="not a robomach project"):
        core.project_from_file_bytes(b"PK\x03\x04 nope")


@pytest.mark.slow  # the shared block demo run (tests/demo_project.py)
def test_the_choice_is_the_cmrr_and_compensation_settings(block_project):
    p = core.with_machining_setup(block_project, core.MachiningSetup())
    assert p.cmrr.controller.kind == "adaptive-pi" and p.compensation is None
    assert p.cmrr.reference_force_N == pytest.approx(105.0)
    p = core.choose(p, "constant", "offline")
    assert p.cmrr is None and p.compensation.mode == "offline"
    assert p.compensation.offline_model == "linear"
    setup = core.machining_setup_of(p)
    assert (setup.settings.controller, setup.settings.compensation) == ("constant", "offline")
    # A CMRR controller set another way (a study) is the machining controller.
    study = CmrrSettings(settings_for("fuzzy"), 80.0, 0.01, 0.1)
    p = replace(p, cmrr=study, compensation=None)
    setup = core.machining_setup_of(p)
    assert (setup.settings.controller, setup.settings.compensation) == ("fuzzy", "off")


@pytest.mark.slow  # the shared block demo run (tests/demo_project.py)
def test_choosing_keeps_a_result_current_and_a_process_change_dates_it(block_project):
    p = core.with_machining_setup(block_project, core.MachiningSetup())
    key = core.machining_inputs_key(p)
    for controller, compensation in (("fuzzy", "online"), ("constant", "off")):
        assert core.machining_inputs_key(core.choose(p, controller, compensation)) == key
    changed = core.MachiningSetup(MachiningSettings(process_gain_N=30.0))
    assert core.machining_inputs_key(core.with_machining_setup(p, changed)) != key
    profile = core.MachiningSetup(stock_source="profile", stock_profile_mm=((0.0, 1.0),))
    assert core.machining_inputs_key(core.with_machining_setup(p, profile)) != key


@pytest.mark.slow  # the shared block demo run (tests/demo_project.py)
def test_compensation_settings_of_another_arm_are_re_derived_not_blocking_the_export(
    block_project,
):
    """Issue 16: after switching the arm, the old arm's compensation settings blocked the
    export ("identified on ur10, the cell has irb4400"); they are stale, re-derived for the
    cell's arm, and the program says so in its header."""
    from robomach_core.cell import Robot
    from robomach_core.stiffness import CompensationSettings

    p = core.with_machining_setup(block_project, core.MachiningSetup())
    p = core.choose(p, "constant", "offline")
    other = CompensationSettings("ur5", (1e5,) * 6, mode="offline", offline_model="nonlinear")
    p = replace(p, compensation=other)
    assert "ur5" in core.stale_settings(p)["compensation"]
    workpiece = core.build_workpiece(p.cell, p.mesh)
    robot = Robot(p.cell.robot, p.tool().T_flange_tcp)
    files = core.program_files(p, workpiece, robot)
    assert (
        "identified on ur5" in files["program.mod"]
        and "re-derives it for ur10" in files["program.mod"]
    )
    # The CMRR choice and the mode are kept (no "Remove" needed), and the offline model.
    assert (p.compensation.mode, p.compensation.offline_model) == ("offline", "nonlinear")
    # Choosing again (here online, then offline) re-derives for the cell's arm and keeps the
    # user's offline model: one word for the choice, the model a setting of its own.
    again = core.choose(core.choose(p, "constant", "online"), "constant", "offline")
    assert again.compensation.robot == "ur10"
    assert (again.compensation.mode, again.compensation.offline_model) == ("offline", "nonlinear")


def test_a_result_is_re_chosen_for_another_cell_without_running_again():
    from robomach_core.machining.choice import CellCapabilities

    rows = (
        _row("constant", "off", 240.0, 146.0, 0.12),
        _row("adaptive-pi", "offline", 137.0, 145.0, 0.03),
        _row("adaptive-pi", "online", 136.0, 147.0, 0.011),
    )
    result = core.MachiningResult(rows=rows, table_text="", chosen=None, programs={})
    abb = result.for_cell(CellCapabilities.for_language("rapid"))
    assert abb.chosen == 1 and abb.rows[2]["runnable"] is False
    full = abb.for_cell(CellCapabilities(frozenset({"fc_speed_change", "path_correction"})))
    assert full.chosen == 2 and all(r["runnable"] for r in full.rows)
    bare = full.for_cell(CellCapabilities())
    assert bare.chosen == 0 and "constant / off" in bare.reason
    assert [r["cycle_time_s"] for r in bare.rows] == [r["cycle_time_s"] for r in rows]
    assert bare.table_text.splitlines()[1].lstrip().startswith("chosen")  # marked anew


def test_status_never_runs_the_stiffness_campaign(monkeypatch):
    """``Project.status()`` names the simulated CMM campaign a run would cut with (its arm,
    seed, poses and noise) instead of running it: it is read on every poll."""
    import robomach_core.machining as machining

    def refuse(*args, **kwargs):
        raise AssertionError("status() ran the simulated stiffness identification")

    monkeypatch.setattr(machining, "identify_stiffness", refuse)
    p = core.with_machining_setup(core.Project(), core.MachiningSetup())
    assert p.status()["machining"] == "none"
    key = core.machining_inputs_key(p)
    other_seed = core.MachiningSetup(MachiningSettings(seed=p.cell.seed + 1))
    assert core.machining_inputs_key(core.with_machining_setup(p, other_seed)) != key
    assert core.machining_inputs_key(p) == key


@pytest.mark.slow  # the shared block demo run (tests/demo_project.py)
@pytest.mark.parametrize("kind", ["fixed-pi", "fuzzy", "two-stage"])
def test_a_ur_program_runs_the_cmrr_its_header_names_without_a_machining_setup(block_project, kind):
    """A UR project with CMRR settings (``robomach demo --cmrr-settings``) but no machining
    choice: its program.script said "CMRR: <controller>" and ran plain moves at the learned
    feeds. It now runs the controller's feed loop (issue 29: feed control written, or
    refused)."""
    from robomach_core.cell import Robot

    p = replace(block_project, cmrr=CmrrSettings(settings_for(kind), 80.0, 0.01, 0.1))
    assert p.machining_settings is None and p.cell.robot.startswith("ur")
    workpiece = core.build_workpiece(p.cell, p.mesh)
    robot = Robot(p.cell.robot, p.tool().T_flange_tcp)
    script = core.program_texts(p, workpiece, robot, "urscript")["program.script"]
    assert f"# CMRR: {kind} holding 80" in script
    assert "get_tcp_force()" in script


@pytest.mark.slow  # the shared block demo run (tests/demo_project.py)
def test_a_program_that_carries_no_cmrr_says_so_in_its_header(block_project):
    """The header's CMRR line named the controller in every file, also in KRL (no feed
    control written) and in the force-controlled variant (none either): those say it is not
    in the program; RAPID and URScript, which run it, name it."""
    from robomach_core.cell import Robot

    p = replace(block_project, cmrr=CmrrSettings(settings_for("fuzzy"), 80.0, 0.01, 0.1))
    workpiece = core.build_workpiece(p.cell, p.mesh)
    for arm, language, fc, carried in (
        ("ur10", "urscript", False, True),
        ("ur10", "urscript", True, False),
        ("ur10", "rapid", False, True),
        ("ur10", "krl", False, False),  # the header is the language's, not the arm's
    ):
        robot = Robot(arm, p.tool().T_flange_tcp)
        texts = core.program_texts(p, workpiece, robot, language, force_control=fc)
        text = "\n".join(texts.values())
        line = next(ln for ln in text.splitlines() if "CMRR: fuzzy, reference 80 N" in ln)
        assert ("NOT in this program" not in line) == carried, (arm, language, fc, line)
