"""What a study writes: the trace as CSV, the summary as JSON, a comparison table, the figure
and the controller settings (mm, N, s at this boundary, units in the column and key names)."""

from __future__ import annotations

import csv
import json
import math
from collections.abc import Sequence
from pathlib import Path
from typing import Any

import numpy as np

from .plots import plot_comparison, plot_study
from .settings import cmrr_settings_for, settings_to_dict
from .simulation import StudyResult

CSV_NAME = "cmrr.csv"
SUMMARY_NAME = "cmrr_summary.json"
PLOT_NAME = "cmrr.png"
SETTINGS_NAME = "cmrr_settings.json"

# Estimate name -> (CSV column, scale from SI).
ESTIMATE_COLUMNS = {
    "force_gain_N": ("force_gain_estimate_N", 1.0),
    "feed_exponent": ("feed_exponent_estimate", 1.0),
    "removal_N_s_m": ("removal_estimate_N_s_mm", 1e-3),
}
TABLE_COLUMNS = (
    ("controller", "controller", "{}"),
    ("stable", "stable", "{}"),
    ("peak_force_N", "peak F [N]", "{:.0f}"),
    ("force_rms_error_N", "rms err [N]", "{:.1f}"),
    ("cycle_time_s", "cycle [s]", "{:.2f}"),
    ("baseline_cycle_time_s", "baseline [s]", "{:.2f}"),
    ("cycle_time_gain", "gain", "{:.2f}"),
    ("protection_stop", "stop", "{}"),
)


def jsonable(value: Any) -> Any:
    """Plain JSON types; floats rounded to 6 decimals, NaN/inf as null."""
    if isinstance(value, dict):
        return {str(k): jsonable(v) for k, v in value.items()}
    if isinstance(value, list | tuple):
        return [jsonable(v) for v in value]
    if isinstance(value, bool | np.bool_):
        return bool(value)
    if isinstance(value, int | np.integer):
        return int(value)
    if isinstance(value, float | np.floating):
        v = float(value)
        return round(v, 6) if math.isfinite(v) else None
    return value


def trace_rows(result: StudyResult) -> tuple[list[str], np.ndarray]:
    """Header and rows (n, m) of one study's CSV columns."""
    tr = result.trace
    columns: list[tuple[str, np.ndarray]] = [
        ("time_s", tr.time_s),
        ("position_mm", 1e3 * tr.position_m),
        ("depth_mm", 1e3 * tr.depth_m),
        ("commanded_feed_mm_s", 1e3 * tr.commanded_feed_m_s),
        ("actual_feed_mm_s", 1e3 * tr.actual_feed_m_s),
        ("speed_ratio", tr.speed_ratio),
        ("force_N", tr.force_N),
        ("measured_force_N", tr.measured_force_N),
        ("spindle_current_A", tr.spindle_current_A),
        ("reference_force_N", tr.reference_N),
        ("engaged", tr.engaged.astype(float)),
    ]
    for name, values in tr.estimates.items():
        column, scale = ESTIMATE_COLUMNS.get(name, (name, 1.0))
        columns.append((column, scale * values))
    return [c for c, _ in columns], np.column_stack([v for _, v in columns])


def write_trace_csv(results: Sequence[StudyResult], path: str | Path) -> Path:
    """The trace(s) as CSV; with several studies, a leading ``controller`` column and the union
    of the estimate columns (empty where a controller has no such estimate)."""
    out = Path(path)
    tables = [trace_rows(r) for r in results]
    header: list[str] = []
    for cols, _ in tables:
        header += [c for c in cols if c not in header]
    multi = len(results) > 1
    with out.open("w", newline="") as fh:
        writer = csv.writer(fh)
        writer.writerow((["controller"] if multi else []) + header)
        for result, (cols, rows) in zip(results, tables, strict=True):
            index = [cols.index(c) if c in cols else -1 for c in header]
            for row in rows:
                cells = [_cell(row[i]) if i >= 0 else "" for i in index]
                writer.writerow(([result.controller_name] if multi else []) + cells)
    return out


def _cell(value: float) -> str:
    return "" if not math.isfinite(value) else f"{value:.6g}"


def comparison_table(results: Sequence[StudyResult]) -> str:
    """A fixed-width text table of the main figures, one row per controller."""
    header = [title for _, title, _ in TABLE_COLUMNS]
    rows = []
    for r in results:
        cells = []
        for key, _, fmt in TABLE_COLUMNS:
            value = r.summary.get(key)
            cells.append("-" if value is None else fmt.format(value))
        rows.append(cells)
    widths = [max(len(h), *(len(row[i]) for row in rows)) for i, h in enumerate(header)]
    lines = ["  ".join(h.ljust(w) for h, w in zip(header, widths, strict=True))]
    lines += ["  ".join(c.ljust(w) for c, w in zip(row, widths, strict=True)) for row in rows]
    return "\n".join(lines)


def summary_document(results: Sequence[StudyResult]) -> dict[str, Any]:
    """The summary JSON: one study's summary, or ``controller: "all"`` with one per study."""
    if len(results) == 1:
        return jsonable(results[0].summary)
    first = results[0].summary
    return jsonable(
        {
            "controller": "all",
            "scenario": first["scenario"],
            "description": first["description"],
            "results": [r.summary for r in results],
        }
    )


def write_study_outputs(results: Sequence[StudyResult], out_dir: str | Path) -> dict[str, Path]:
    """Write CSV, summary JSON, PNG and settings JSON for one or several studies."""
    if not results:
        raise ValueError("no study results to write")
    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    paths = {"csv": write_trace_csv(results, out / CSV_NAME)}
    summary_path = out / SUMMARY_NAME
    summary_path.write_text(json.dumps(summary_document(results), indent=2) + "\n")
    paths["summary"] = summary_path
    if len(results) == 1:
        paths["plot"] = plot_study(results[0], out / PLOT_NAME)
        settings: Any = settings_to_dict(
            cmrr_settings_for(results[0].scenario, results[0].settings)
        )
    else:
        paths["plot"] = plot_comparison(results, out / PLOT_NAME)
        settings = [settings_to_dict(cmrr_settings_for(r.scenario, r.settings)) for r in results]
    settings_path = out / SETTINGS_NAME
    settings_path.write_text(json.dumps(jsonable(settings), indent=2) + "\n")
    paths["settings"] = settings_path
    return paths
