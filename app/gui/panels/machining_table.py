"""The machining comparison as an HTML table a person can read at sidebar width and large.

One renderer for the sidebar (a few columns, scrolling) and the wide modal (every column): the
rows sortable by any figure, the rule's pick highlighted with its reason under the table,
configurations the cell cannot run greyed with what they need on hover, stopped and refused
runs marked. Plain HTML and CSS (viser's ``add_html`` runs no script): sorting is the panel's
dropdown re-rendering the table.
"""

from __future__ import annotations

import html
from typing import Any

from robomach_core.machining import table_notes

# (key, header, format) of the sidebar's columns; the wide table adds WIDE_COLUMNS.
COMPACT_COLUMNS: tuple[tuple[str, str, str], ...] = (
    ("cycle_time_s", "cycle s", "{:.1f}"),
    ("force_peak_N", "peak N", "{:.0f}"),
    ("wall_error_max_mm", "wall mm", "{:.3f}"),
)
VARIATION_COLUMNS: tuple[tuple[str, str, str], ...] = (
    ("cycle_time_p95_s", "cycle p95", "{:.1f}"),
    ("force_peak_p95_N", "peak p95", "{:.0f}"),
    ("wall_error_max_p95_mm", "wall p95", "{:.3f}"),
    ("within_limit_share", "in limit", "{:.0%}"),
)
WIDE_COLUMNS: tuple[tuple[str, str, str], ...] = (
    ("faster_than_constant_pct", "vs const %", "{:+.0f}"),
    ("force_limit_N", "F lim N", "{:.0f}"),
    ("force_rms_error_N", "F rms err N", "{:.1f}"),
    ("wall_error_max_at_path_mm", "at mm", "{:.0f}"),
    ("wall_error_rms_mm", "wall rms mm", "{:.3f}"),
    ("material_left_max_mm", "left mm", "{:.3f}"),
    ("overcut_max_mm", "overcut mm", "{:.3f}"),
    ("mrr_mean_mm3_s", "MRR mm3/s", "{:.1f}"),
    ("cycle_time_p50_s", "cycle p50", "{:.1f}"),
    ("force_peak_p50_N", "peak p50", "{:.0f}"),
    ("wall_error_max_p50_mm", "wall p50", "{:.3f}"),
    ("realtime_factor", "x real time", "{:.0f}"),
)
# Sort choices of the panel: label -> (row key, descending).
SORT_KEYS: dict[str, tuple[str, bool]] = {
    "configuration": ("", False),
    "cycle time": ("cycle_time_s", False),
    "peak force": ("force_peak_N", False),
    "wall error": ("wall_error_max_mm", False),
    "cycle p95": ("cycle_time_p95_s", False),
    "peak p95": ("force_peak_p95_N", False),
    "wall p95": ("wall_error_max_p95_mm", False),
}
STYLE = """<style>
.rm-mt-wrap {max-height: 360px; overflow: auto; border: 1px solid #dee2e6; border-radius: 4px}
.rm-mt-wrap.wide {max-height: 70vh}
.rm-mt {border-collapse: collapse; width: 100%; font-size: 11px;
  font-variant-numeric: tabular-nums}
.rm-mt th {position: sticky; top: 0; background: #f1f3f5; padding: 2px 4px;
  text-align: right; white-space: nowrap; font-weight: 600}
.rm-mt td {padding: 1px 4px; text-align: right; white-space: nowrap;
  border-top: 1px solid #f1f3f5}
.rm-mt th:first-child, .rm-mt td:first-child {text-align: left}
.rm-mt tr.chosen td {background: #d3f9d8; font-weight: 700}
.rm-mt tr.unrunnable td {color: #adb5bd}
.rm-mt tr.stopped td.status {color: #c92a2a}
.rm-why {font-size: 11px; margin: 4px 0 0 0; line-height: 1.35}
.rm-why b {color: #2b8a3e}
</style>"""


def _cell(row: dict[str, Any], key: str, fmt: str) -> str:
    value = row.get(key)
    if value is None:
        return "-"
    try:
        return fmt.format(value)
    except (TypeError, ValueError):
        return html.escape(str(value))


def sorted_rows(rows: list[dict[str, Any]], sort_by: str) -> list[tuple[int, dict[str, Any]]]:
    """(index, row) in the order ``sort_by`` (a ``SORT_KEYS`` label) asks for; rows without
    the figure (stopped, refused) last."""
    key, descending = SORT_KEYS.get(sort_by, ("", False))
    indexed = list(enumerate(rows))
    if not key:
        return indexed
    have = [(i, r) for i, r in indexed if r.get(key) is not None]
    lack = [(i, r) for i, r in indexed if r.get(key) is None]
    have.sort(key=lambda ir: ir[1][key], reverse=descending)
    return have + lack


def table_html(
    rows: list[dict[str, Any]],
    chosen: int | None,
    reason: str,
    *,
    sort_by: str = "configuration",
    wide: bool = False,
) -> str:
    """The comparison as HTML (module docstring)."""
    varied = any("cycle_time_p95_s" in r for r in rows)
    columns = list(COMPACT_COLUMNS) + (list(VARIATION_COLUMNS) if varied else [])
    if wide:
        columns += [c for c in WIDE_COLUMNS if varied or "_p50_" not in c[0]]
    head = "".join(f"<th>{html.escape(h)}</th>" for _, h, _ in columns)
    body = []
    for i, row in sorted_rows(rows, sort_by):
        classes = []
        if i == chosen:
            classes.append("chosen")
        if row.get("runnable") is False:
            classes.append("unrunnable")
        if not row.get("completed"):
            classes.append("stopped")
        title = ""
        if row.get("needs"):
            title = "the cell lacks " + " and ".join(row["needs"])
        elif row.get("refused"):
            title = str(row["refused"])
        elif not row.get("completed"):
            title = f"stopped: {row.get('stop_reason') or 'stopped'}"
        status = (
            "refused" if row.get("refused") else ("stopped" if not row.get("completed") else "")
        )
        name = f"{row['controller']} / {row['compensation']}"
        cells = [f"<td>{'&#9733; ' if i == chosen else ''}{html.escape(name)}</td>"]
        for key, _, fmt in columns:
            text = _cell(row, key, fmt)
            if key == "cycle_time_s" and status:
                cells.append(f'<td class="status">{status}</td>')
            else:
                cells.append(f"<td>{text}</td>")
        attrs = f' class="{" ".join(classes)}"' if classes else ""
        if title:
            attrs += f' title="{html.escape(title)}"'
        body.append(f"<tr{attrs}>{''.join(cells)}</tr>")
    pick = (
        "none"
        if chosen is None
        else f"{rows[chosen]['controller']} / {rows[chosen]['compensation']}"
    )
    why = (
        f'<p class="rm-why">Rule\'s pick: <b>{html.escape(pick)}</b>. {html.escape(reason)} '
        "Greyed: the cell cannot run them (hover for what they need).</p>"
    )
    why += "".join(f'<p class="rm-why">{html.escape(note)}</p>' for note in table_notes(rows))
    wrap = "rm-mt-wrap wide" if wide else "rm-mt-wrap"
    return (
        f'{STYLE}<div class="{wrap}"><table class="rm-mt"><thead><tr><th>configuration</th>'
        f"{head}</tr></thead><tbody>{''.join(body)}</tbody></table></div>{why}"
    )
