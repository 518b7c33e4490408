"""CSV tables of a recording and of the targets (mm, N, s, degrees at the boundary)."""

from __future__ import annotations

import numpy as np

from ..learning.run import Recording
from ..postprocess import Targets

CSV_BLOCK_ROWS = 2048  # rows formatted together (``_csv_text``)
SAMPLE_COLUMNS = (
    ["time_s"]
    + [f"joint{i}_motor_deg" for i in range(1, 7)]
    + ["x_mm", "y_mm", "z_mm", "qw", "qx", "qy", "qz"]
    + [f"sensor_{c}" for c in ("fx_N", "fy_N", "fz_N", "tx_Nm", "ty_Nm", "tz_Nm")]
    + [f"tool_{c}" for c in ("fx_N", "fy_N", "fz_N", "tx_Nm", "ty_Nm", "tz_Nm")]
    + ["force_normal_N", "force_reference_N", "in_contact", "segment", "kept_by_filter"]
)

TARGET_COLUMNS = (
    ["index", "sample", "x_mm", "y_mm", "z_mm", "qw", "qx", "qy", "qz"]
    + [f"joint{i}_deg" for i in range(1, 7)]
    + ["speed_mm_s", "curvature_1_mm"]
)


def samples_csv(recording: Recording, keep_mask: np.ndarray | None = None) -> str:
    """Every 4 ms sample as CSV text with a header row that names the units."""
    rec = recording
    n = len(rec)
    keep = np.ones(n, dtype=bool) if keep_mask is None else np.asarray(keep_mask, dtype=bool)
    table = np.column_stack(
        [
            rec.time_s,
            np.degrees(rec.joints_rad),
            rec.position_m * 1e3,
            rec.quaternion_wxyz,
            rec.wrench_sensor,
            rec.wrench_tool,
            rec.force_normal_N,
            rec.force_reference_N,
            rec.in_contact.astype(int),
            rec.segment,
            keep.astype(int),
        ]
    )
    fmt = (
        ["%.3f"]
        + ["%.5f"] * 6
        + ["%.4f"] * 3
        + ["%.7f"] * 4
        + ["%.3f"] * 12
        + ["%.3f", "%.3f", "%d", "%d", "%d"]
    )
    return _csv_text(table, fmt, SAMPLE_COLUMNS)


def targets_csv(targets: Targets) -> str:
    """The reduced targets as CSV text with a header row that names the units."""
    m = len(targets)
    table = np.column_stack(
        [
            np.arange(1, m + 1),
            targets.sample_index,
            targets.position_m * 1e3,
            targets.quaternion_wxyz,
            np.degrees(targets.joints_rad),
            targets.speed_m_s * 1e3,
            targets.curvature_1_m * 1e-3,
        ]
    )
    fmt = ["%d", "%d"] + ["%.4f"] * 3 + ["%.7f"] * 4 + ["%.5f"] * 6 + ["%.2f", "%.5f"]
    return _csv_text(table, fmt, TARGET_COLUMNS)


def _csv_text(table: np.ndarray, fmt: list[str], columns: list[str]) -> str:
    """The text ``np.savetxt(table, fmt, delimiter=",", header=columns, comments="")``
    writes, byte for byte: the header line, then one line per row, each value formatted
    with its ``%`` format. A block of rows is formatted in one ``%`` operation (savetxt
    formats row by row: twice as long for a long recording's samples.csv)."""
    row = ",".join(fmt) + "\n"
    parts = [",".join(columns) + "\n"]
    for start in range(0, len(table), CSV_BLOCK_ROWS):
        block = table[start : start + CSV_BLOCK_ROWS]
        parts.append((row * len(block)) % tuple(block.ravel().tolist()))
    return "".join(parts)
