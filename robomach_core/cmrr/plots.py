"""PNG figures of CMRR studies (matplotlib, Agg backend: no display needed).

One study: force (true, measured, reference, limit), feed (commanded, actual) with the depth of
cut, speed ratio, and the on-line estimates against their true values. Several studies on one
scenario: force, speed ratio and feed of each controller on shared axes.
"""

from __future__ import annotations

from collections.abc import Sequence
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np

if TYPE_CHECKING:
    from .simulation import StudyResult

ESTIMATE_LABELS = {
    "force_gain_N": ("Kf [N/(mm/s)^beta]", 1.0),
    "feed_exponent": ("beta", 1.0),
    "removal_N_s_m": ("Df [N s/mm]", 1e-3),
}


def _pyplot():
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    return plt


def plot_study(result: StudyResult, path: str | Path) -> Path:
    """Write the four-panel figure of one study to ``path`` (PNG); returns the path."""
    plt = _pyplot()
    tr, sc, s = result.trace, result.scenario, result.summary
    has_est = bool(tr.estimates)
    rows = 4 if has_est else 3
    fig, axes = plt.subplots(rows, 1, figsize=(10, 2.4 * rows + 0.6), sharex=True)
    t = tr.time_s

    ax = axes[0]
    ax.plot(t, tr.measured_force_N, color="0.7", lw=0.8, label="measured (filtered)")
    ax.plot(t, tr.force_N, color="C0", lw=1.2, label="process force")
    ax.plot(t, tr.reference_N, "k--", lw=1.0, label="reference")
    if sc.force_limit_N is not None:
        ax.axhline(sc.force_limit_N, color="C3", ls=":", lw=1.2, label="limit")
    ax.set_ylabel("force [N]")
    ax.legend(loc="upper left", fontsize=8, ncol=4)
    verdict = "stable" if s["stable"] else "NOT stable (sustained oscillation)"
    if s["protection_stop"]:
        verdict += ", protection stop"
    ax.set_title(
        f"{sc.name} / {result.controller_name}: {verdict}; peak {s['peak_force_N']:.0f} N, "
        f"cycle {_fmt(s['cycle_time_s'])} s vs baseline {s['baseline_cycle_time_s']:.1f} s",
        fontsize=10,
    )

    ax = axes[1]
    ax.plot(t, 1e3 * tr.commanded_feed_m_s, color="C1", lw=1.0, label="commanded")
    ax.plot(t, 1e3 * tr.actual_feed_m_s, color="C2", lw=1.2, label="actual")
    ax.set_ylabel("feed [mm/s]")
    ax.legend(loc="upper left", fontsize=8, ncol=2)
    depth_ax = ax.twinx()
    depth_ax.plot(t, 1e3 * tr.depth_m, color="0.4", lw=1.0, ls="-.")
    depth_ax.set_ylabel("depth [mm]", color="0.4")

    ax = axes[2]
    ax.plot(t, tr.speed_ratio, color="C4", lw=1.2)
    ax.axhline(sc.min_speed_ratio, color="0.5", ls=":", lw=1.0)
    ax.set_ylim(-0.05, 1.08)
    ax.set_ylabel("speed_ratio")
    if not np.all(tr.engaged):
        ax.fill_between(t, 0, 1.08, where=~tr.engaged, color="0.9", step="mid", label="not engaged")
        ax.legend(loc="lower left", fontsize=8)

    if has_est:
        ax = axes[3]
        for i, (name, values) in enumerate(tr.estimates.items()):
            label, scale = ESTIMATE_LABELS.get(name, (name, 1.0))
            target = ax if i == 0 else ax.twinx()
            color = f"C{i}"
            target.plot(t, scale * values, color=color, lw=1.2, label=f"{label} estimate")
            if name in tr.truths:
                target.plot(t, scale * tr.truths[name], color=color, ls="--", lw=1.0)
            target.set_ylabel(label + " (dashed: true)", color=color, fontsize=8)
        ax.set_title("on-line estimates", fontsize=9)
    axes[-1].set_xlabel("time [s]")
    fig.tight_layout()
    out = Path(path)
    fig.savefig(out, dpi=110)
    plt.close(fig)
    return out


def plot_comparison(results: Sequence[StudyResult], path: str | Path) -> Path:
    """Write force, speed ratio and feed of several controllers on one scenario to ``path``."""
    plt = _pyplot()
    fig, axes = plt.subplots(3, 1, figsize=(10, 8), sharex=True)
    sc = results[0].scenario
    for i, r in enumerate(results):
        tr = r.trace
        tag = "" if r.summary["stable"] else " (unstable)"
        color = f"C{i}"
        axes[0].plot(tr.time_s, tr.force_N, color=color, lw=1.0, label=r.controller_name + tag)
        axes[1].plot(tr.time_s, tr.speed_ratio, color=color, lw=1.0)
        axes[2].plot(tr.time_s, 1e3 * tr.actual_feed_m_s, color=color, lw=1.0)
    axes[0].axhline(sc.reference_force_N, color="k", ls="--", lw=1.0, label="reference")
    if sc.force_limit_N is not None:
        axes[0].axhline(sc.force_limit_N, color="C3", ls=":", lw=1.2, label="limit")
    axes[0].set_ylabel("force [N]")
    axes[0].legend(fontsize=8, ncol=4, loc="upper left")
    axes[0].set_title(f"{sc.name}: {sc.description}", fontsize=10)
    axes[1].set_ylabel("speed_ratio")
    axes[2].set_ylabel("actual feed [mm/s]")
    axes[2].set_xlabel("time [s]")
    fig.tight_layout()
    out = Path(path)
    fig.savefig(out, dpi=110)
    plt.close(fig)
    return out


def _fmt(value: float | None) -> str:
    return "n/a" if value is None else f"{value:.1f}"
