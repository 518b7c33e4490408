"""Figures of machining runs along the path: force, feed and finished-wall error (PNG).

Built on ``matplotlib.figure.Figure`` with the Agg canvas (no pyplot state), so a worker thread
of the workbench can draw while another runs.
"""

from __future__ import annotations

from collections.abc import Sequence
from pathlib import Path

from ..plots import agg_figure
from .run import MachiningRun

MM = 1e-3


def plot_runs(runs: Sequence[MachiningRun], path: str | Path, *, title: str = "") -> Path:
    """Force (with reference and limit), feed and finished-wall error against path [mm]."""
    if not runs:
        raise ValueError("plot_runs needs at least one run")
    fig = agg_figure(figsize=(10, 8), constrained_layout=True)
    ax_f, ax_v, ax_w = fig.subplots(3, 1, sharex=True)
    for run in runs:
        label = f"{run.controller} / {run.compensation}"
        tr = run.trace
        s_mm = tr.path_m / MM
        ax_f.plot(s_mm, tr.force_N, lw=0.8, label=label)
        ax_v.plot(s_mm, tr.feed_m_s / MM, lw=0.8, label=label)
        ax_w.plot(run.wall.s_m / MM, run.wall.error_m / MM, lw=0.8, label=label)
    first = runs[0].trace
    ax_f.axhline(float(first.limit_N[0]), color="k", ls="--", lw=1, label="limit")
    ax_f.axhline(float(first.reference_N[0]), color="0.5", ls=":", lw=1, label="reference")
    ax_f.set_ylabel("force [N]")
    ax_v.set_ylabel("feed [mm/s]")
    ax_w.set_ylabel("wall error [mm]\n(+ left, - overcut)")
    ax_w.axhline(0.0, color="k", lw=0.5)
    ax_w.set_xlabel("path [mm]")
    ax_f.legend(fontsize=7, ncol=3, loc="upper right")
    if title:
        fig.suptitle(title)
    out = Path(path)
    fig.savefig(out, dpi=110)
    return out
