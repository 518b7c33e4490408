"""The comparison matrix: every pair run once, progress over the matrix, cancel, the table,
the CSV and the figure."""

from __future__ import annotations

import csv
import threading

import numpy as np
import pytest

from robomach_core.errors import CancelledError
from robomach_core.machining import (
    MachiningSettings,
    builtin_stock,
    compare_configurations,
    plot_runs,
    write_run_csv,
)


@pytest.fixture(scope="module")
def matrix(robot, short_program):
    stock = builtin_stock(short_program.position_m, seed=0)
    seen: list[float] = []
    result = compare_configurations(
        robot,
        short_program,
        None,
        stock,
        MachiningSettings(),
        controllers=("constant", "adaptive-pi", "two-stage"),
        progress=seen.append,
    )
    return result, seen, stock


def test_every_pair_runs_once_in_order_with_progress_over_the_whole_matrix(matrix):
    result, seen, _ = matrix
    pairs = [(r.controller, r.compensation) for r in result.runs]
    controllers = ("constant", "adaptive-pi", "two-stage")
    assert pairs == [(c, m) for c in controllers for m in ("off", "offline", "online")]
    assert seen[-1] == pytest.approx(1.0) and bool(np.all(np.diff(seen) >= 0.0))
    assert any(0.3 < f < 0.7 for f in seen)


def test_rows_compare_each_controller_with_the_constant_feed(matrix):
    result, _, _ = matrix
    rows = {(r["controller"], r["compensation"]): r for r in result.rows}
    assert rows["constant", "off"]["faster_than_constant_pct"] == pytest.approx(0.0)
    pi = rows["adaptive-pi", "off"]
    expected = 100.0 * (1.0 - pi["cycle_time_s"] / rows["constant", "off"]["cycle_time_s"])
    assert pi["faster_than_constant_pct"] == pytest.approx(expected)
    assert pi["wall_error_max_mm"] > rows["adaptive-pi", "online"]["wall_error_max_mm"]
    lines = result.table_text.splitlines()
    assert len(lines) == 1 + len(result.runs)
    assert "cycle [s]" in lines[0] and "adaptive-pi" in result.table_text


def test_cancel_stops_the_matrix(robot, short_program, matrix):
    _, _, stock = matrix
    flag = threading.Event()
    flag.set()
    with pytest.raises(CancelledError):
        compare_configurations(robot, short_program, None, stock, MachiningSettings(), cancel=flag)


def test_csv_and_figure_are_written(matrix, tmp_path):
    result, _, _ = matrix
    run = result.runs[1]
    path = write_run_csv(run, tmp_path / "machining_constant_offline.csv")
    with path.open() as f:
        rows = list(csv.reader(f))
    for column in ("time_s", "path_mm", "feed_mm_s", "depth_mm", "force_N", "deflection_mm",
                   "wall_error_mm"):  # fmt: skip
        assert column in rows[0]
    assert len(rows) == len(run.trace) + 1
    png = plot_runs(result.runs[:3], tmp_path / "machining.png", title="water pump")
    assert png.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"


def test_the_notes_say_what_the_other_stage_plan_cuts():
    """``table_notes``: the other stage plan's figures per row, the share of the off row's
    wall error it cuts, a stop said as a stop, and nothing when no row carries one."""
    from robomach_core.machining import table_notes

    def row(controller, compensation, wall, other=None):
        out = {"controller": controller, "compensation": compensation}
        out |= {"wall_error_max_mm": wall, "completed": True}
        return out | ({"other_stages": other} if other else {})

    planned = {"stages": "planned", "completed": True, "cycle_time_s": 144.4}
    planned |= {"force_peak_N": 145.4, "wall_error_max_mm": 0.004}
    stopped = {"stages": "planned", "completed": False, "refused": None}
    rows = [
        row("fuzzy", "off", 0.1),
        row("fuzzy", "offline", 0.02, planned),
        row("two-stage", "offline", 0.04, stopped),
    ]
    (note,) = table_notes(rows)
    assert note.startswith("stages planned: fuzzy / offline 144.4 s, peak 145.4 N")
    assert "wall max 0.004 mm (96 % less than off)" in note
    assert "two-stage / offline stopped" in note and "--stages planned" in note
    assert table_notes(rows[:1]) == []
