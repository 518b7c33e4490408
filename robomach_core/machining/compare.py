"""Compare before choosing: the greatest safe constant feed and each CMRR controller, with
compensation off, offline and online, on the same program, stock and noise.

The constant feed is the greatest that keeps the force limit at the deepest cut of the stock,
f = (F_lim / (K d_max^alpha))^(1/beta) (inverse of eq. 5); every CMRR controller gets the same
limit and the same reference. One stiffness identification serves every compensated run.
"""

from __future__ import annotations

import csv
from collections.abc import Callable, Sequence
from dataclasses import dataclass, replace
from pathlib import Path
from typing import Any, cast

import numpy as np

from ..cell import Robot
from ..errors import InvalidInputError
from ..postprocess import Targets
from ..stiffness.modes import COMPENSATIONS, Compensation
from .run import (
    CancelFlag,
    CompensationModel,
    FeedSource,
    MachiningRun,
    ProgressCallback,
    run_machining,
    stiffness_model,
)
from .settings import MACHINING_CONTROLLERS, MachiningSettings
from .stock import Stock

MM = 1e-3
# Columns of the side-by-side table: (key of the row, header, format).
TABLE_COLUMNS: tuple[tuple[str, str, str], ...] = (
    ("controller", "controller", "{}"),
    ("compensation", "comp.", "{}"),
    ("cycle_time_s", "cycle [s]", "{:.1f}"),
    ("faster_than_constant_pct", "vs const [%]", "{:+.0f}"),
    ("force_peak_N", "F peak [N]", "{:.1f}"),
    ("force_limit_N", "F lim [N]", "{:.0f}"),
    ("force_rms_error_N", "F rms err [N]", "{:.1f}"),
    ("wall_error_max_mm", "wall max [mm]", "{:.3f}"),
    ("wall_error_max_at_path_mm", "at [mm]", "{:.0f}"),
    ("wall_error_rms_mm", "wall rms [mm]", "{:.3f}"),
    ("material_left_max_mm", "left [mm]", "{:.3f}"),
    ("overcut_max_mm", "overcut [mm]", "{:.3f}"),
    ("mrr_mean_mm3_s", "MRR [mm3/s]", "{:.1f}"),
    ("realtime_factor", "x real time", "{:.0f}"),
)
# The variation sweep's columns (``variation.variation_rows``), shown when a sweep ran.
VARIATION_TABLE_COLUMNS: tuple[tuple[str, str, str], ...] = (
    ("cycle_time_p95_s", "cycle p95 [s]", "{:.1f}"),
    ("force_peak_p95_N", "F peak p95 [N]", "{:.1f}"),
    ("wall_error_max_p95_mm", "wall p95 [mm]", "{:.3f}"),
    ("within_limit_share", "in limit", "{:.0%}"),
)
# Per-sample CSV columns: (header, trace attribute, scale to the header's unit).
CSV_COLUMNS: tuple[tuple[str, str, float], ...] = (
    ("time_s", "time_s", 1.0),
    ("path_mm", "path_m", 1 / MM),
    ("feed_mm_s", "feed_m_s", 1 / MM),
    ("commanded_feed_mm_s", "commanded_feed_m_s", 1 / MM),
    ("speed_ratio", "speed_ratio", 1.0),
    ("depth_mm", "depth_m", 1 / MM),
    ("force_N", "force_N", 1.0),
    ("measured_force_N", "measured_force_N", 1.0),
    ("reference_N", "reference_N", 1.0),
    ("limit_N", "limit_N", 1.0),
    ("deflection_mm", "deflection_m", 1 / MM),
    ("tool_normal_mm", "tool_normal_m", 1 / MM),
    ("wall_error_mm", "wall_error_m", 1 / MM),
)


@dataclass(frozen=True, eq=False)
class Comparison:
    """The runs of the matrix in order, one row per run, and the text table."""

    runs: list[MachiningRun]
    rows: list[dict[str, Any]]
    table_text: str


def comparison_rows(
    runs: Sequence[MachiningRun],
    *,
    refused: dict[tuple[str, str], str] | None = None,
    order: Sequence[tuple[str, str]] | None = None,
) -> list[dict[str, Any]]:
    """One dict per configuration with the table's keys (in ``order`` when given);
    ``faster_than_constant_pct`` compares the cycle time with the constant-feed run of the
    same compensation (None without one). A ``refused`` configuration's row holds its
    message under ``refused`` and no figures."""
    refused = refused or {}
    constant = {
        r.compensation: r.summary["cycle_time_s"] for r in runs if r.controller == "constant"
    }
    by_pair = {(r.controller, r.compensation): r for r in runs}
    pairs = list(order) if order is not None else list(by_pair)
    rows = []
    for pair in pairs:
        r = by_pair.get(pair)
        if r is None:
            if pair in refused:
                rows.append(
                    {key: None for key, _, _ in TABLE_COLUMNS}
                    | {"controller": pair[0], "compensation": pair[1], "completed": False,
                       "refused": refused[pair], "stop_reason": "refused"}
                )  # fmt: skip
            continue
        row = {key: r.summary.get(key) for key, _, _ in TABLE_COLUMNS}
        base, own = constant.get(r.compensation), r.summary["cycle_time_s"]
        row["faster_than_constant_pct"] = (
            100.0 * (1.0 - own / base) if base and own is not None else None
        )
        row["completed"] = r.summary["completed"]
        row["stop_reason"] = r.summary.get("stop_reason")
        row["feed"] = r.summary.get("feed", "controller")
        row["refused"] = None
        rows.append(row)
    return rows


# The table's first column ("cell"): the rule's pick, what the cell can and cannot run.
MARK_CHOSEN = "chosen"
MARK_RUNNABLE = "can run"
MARK_NOT_RUNNABLE = "cannot"
# The line under the table naming the rows whose feed is a stage schedule planned offline.
MARK_SCHEDULE = "schedule"


def format_table(rows: Sequence[dict[str, Any]], *, chosen: int | None = None) -> str:
    """The rows as a fixed-width text table ("stopped" for a cut that did not finish). When
    the rows were marked for a cell (``choice.mark_runnable``) or a row is ``chosen``, a first
    column ("cell") says which is chosen and what the cell can and cannot run; what it lacks
    is said below the table."""
    columns = TABLE_COLUMNS
    if any("cycle_time_p95_s" in row for row in rows):
        columns = TABLE_COLUMNS[:-1] + VARIATION_TABLE_COLUMNS + TABLE_COLUMNS[-1:]
    marked = chosen is not None or any("runnable" in row for row in rows)
    header = [h for _, h, _ in columns]
    body = []
    for row in rows:
        cells = []
        for key, _, fmt in columns:
            value = row.get(key)
            if value is None:
                stopped = "refused" if row.get("refused") else "stopped"
                cells.append(stopped if key == "cycle_time_s" else "-")
            else:
                cells.append(fmt.format(value))
        body.append(cells)
    if marked:
        header = ["cell", *header]
        for k, (row, cells) in enumerate(zip(rows, body, strict=True)):
            mark = MARK_RUNNABLE
            if k == chosen:
                mark = MARK_CHOSEN
            elif row.get("runnable") is False:
                mark = MARK_NOT_RUNNABLE
            cells.insert(0, mark)
    widths = [max(len(h), *(len(c[i]) for c in body)) for i, h in enumerate(header)]
    lines = ["  ".join(h.rjust(w) for h, w in zip(header, widths, strict=True))]
    lines += ["  ".join(c.rjust(w) for c, w in zip(cells, widths, strict=True)) for cells in body]
    for note in table_notes(rows):
        lines += ["", note]
    return "\n".join(lines)


def table_notes(rows: Sequence[dict[str, Any]]) -> list[str]:
    """The sentences under the table, as every page shows them: the rows whose feed is a
    stage schedule, what the other stage plan cuts, what the cell lacks."""
    notes = []
    planned = [row for row in rows if row.get("feed") == "program"]
    if planned:
        names = ", ".join(f"{row['controller']} / {row['compensation']}" for row in planned)
        notes.append(
            f"{MARK_SCHEDULE}: {names} run the stage schedule their controller planned offline "
            "for this stock (the lowest stage of its cuts of the nominal wall at each 0.1 mm, "
            "as the program's speeds): no online switching and no feed control, so a casting "
            "with burrs elsewhere meets them at the planned speeds (--variations shows it)"
        )
    notes += _other_stages_notes(rows)
    lacking = [row for row in rows if row.get("runnable") is False]
    if lacking:
        needs = sorted({n for row in lacking for n in row.get("needs") or ()})
        notes.append(
            f"{MARK_NOT_RUNNABLE}: {len(lacking)} of {len(rows)} configurations need what this "
            f"cell lacks: {'; '.join(needs)}"
        )
    return notes


# The line under the table with what the staged controllers' offline rows cut with the other
# stage plan (``MachiningSettings.stages``), on the same stock.
MARK_OTHER_STAGES = "stages"


def _other_stages_notes(rows: Sequence[dict[str, Any]]) -> list[str]:
    """ "stages planned: fuzzy / offline 144.4 s, 145.4 N, wall max 0.004 mm (97 % less than
    off) ..." for the rows that carry ``other_stages`` (``project.machine`` cuts them), and
    how to choose them."""
    off = {r["controller"]: r.get("wall_error_max_mm") for r in rows if r["compensation"] == "off"}
    parts, plan = [], None
    for row in rows:
        other = row.get("other_stages")
        if not other:
            continue
        plan = other["stages"]
        if not other.get("completed"):
            parts.append(f"{row['controller']} / {row['compensation']} stopped")
            continue
        wall, base = other["wall_error_max_mm"], off.get(row["controller"])
        cut = f" ({100.0 * (1.0 - wall / base):.0f} % less than off)" if base else ""
        parts.append(
            f"{row['controller']} / {row['compensation']} {other['cycle_time_s']:.1f} s, "
            f"peak {other['force_peak_N']:.1f} N, wall max {wall:.3f} mm{cut}"
        )
    if not parts:
        return []
    how = (
        "the program runs the planned schedule as its speeds with no feed control"
        if plan == "planned"
        else "the stages switch in the cell by the force"
    )
    return [
        f"{MARK_OTHER_STAGES} {plan}: {'; '.join(parts)}; {how} (on this stock; set stages "
        f"to {plan}, --stages {plan}, and run again to choose them)",
    ]


def compare_configurations(
    robot: Robot,
    targets: Targets,
    wall_normals_m: np.ndarray | None,
    stock: Stock,
    settings: MachiningSettings,
    *,
    controllers: Sequence[str] = MACHINING_CONTROLLERS,
    compensations: Sequence[str] = COMPENSATIONS,
    compensation_model: CompensationModel | None = None,
    progress: ProgressCallback | None = None,
    cancel: CancelFlag | Callable[[], bool] | None = None,
) -> Comparison:
    """Run every (controller, compensation) pair with otherwise equal ``settings``.

    The constant feed (when ``settings.constant_feed_m_s`` is None) is the greatest safe one
    for the stock; ``controller_settings`` of ``settings`` apply only to its own controller.
    ``progress`` spans the whole matrix; ``cancel`` stops it with ``CancelledError``.
    """
    pairs = [(c, m) for c in controllers for m in compensations]
    model = compensation_model
    if any(m != "off" for _, m in pairs):
        model = stiffness_model(robot.name, settings, compensation_model)
    runs: list[MachiningRun] = []
    refused: dict[tuple[str, str], str] = {}
    for i, (controller, compensation) in enumerate(pairs):

        def sub_progress(fraction: float, i: int = i) -> None:
            if progress is not None:
                progress((i + fraction) / len(pairs))

        try:
            runs.append(
                run_configuration(
                    robot, targets, wall_normals_m, stock, settings, controller, compensation,
                    compensation_model=model, progress=sub_progress, cancel=cancel,
                )
            )  # fmt: skip
        except InvalidInputError as exc:
            # A configuration these settings cannot run (no feed keeps the limit, a cut that
            # would never end) is a row of the comparison, not the end of it.
            refused[controller, compensation] = str(exc)
    rows = comparison_rows(runs, refused=refused, order=pairs)
    return Comparison(runs, rows, format_table(rows))


def run_configuration(
    robot: Robot,
    targets: Targets,
    wall_normals_m: np.ndarray | None,
    stock: Stock,
    settings: MachiningSettings,
    controller: str,
    compensation: str,
    *,
    compensation_model: CompensationModel | None = None,
    progress: ProgressCallback | None = None,
    cancel: CancelFlag | Callable[[], bool] | None = None,
    program_frame: np.ndarray | None = None,
    corrected: tuple[Targets, Targets, FeedSource] | None = None,
) -> MachiningRun:
    """One configuration of the matrix: ``settings`` with this controller and compensation
    (the settings' own controller settings only for their own controller); ``corrected``
    (program, nominal targets, its feed: ``run.FeedSource``, "program" for a stage schedule
    planned offline) is an offline correction already planned: cut as it is."""
    own = settings.controller_settings
    run_settings = replace(
        settings,
        controller=controller,
        compensation=cast("Compensation", compensation),  # MachiningSettings checks it
        controller_settings=own if own is not None and own.kind == controller else None,
    )
    if corrected is not None and compensation == "offline":
        from .program import as_written
        from .run import cut_program

        program, nominal, feed = corrected
        return cut_program(
            robot, as_written(program, program_frame), None, stock, run_settings,
            cancel=cancel, progress=progress, nominal=nominal,
            feed=feed,
            compensation_model_for_record=stiffness_model(
                robot.name, run_settings, compensation_model
            ),
        )  # fmt: skip
    return run_machining(
        robot,
        targets,
        wall_normals_m,
        stock,
        run_settings,
        compensation_model=compensation_model,
        progress=progress,
        cancel=cancel,
        program_frame=program_frame,
    )


def write_run_csv(run: MachiningRun, path: str | Path) -> Path:
    """The run's trace as CSV, one row per 4 ms sample, units in the headers."""
    out = Path(path)
    columns = [getattr(run.trace, attr) * scale for _, attr, scale in CSV_COLUMNS]
    with out.open("w", newline="") as f:
        writer = csv.writer(f)
        writer.writerow([h for h, _, _ in CSV_COLUMNS])
        writer.writerows(np.column_stack(columns).tolist())
    return out
