"""Figures of a pipeline run (matplotlib, Agg backend: no screen needed)."""

from __future__ import annotations

from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np

if TYPE_CHECKING:
    from matplotlib.figure import Figure


def agg_figure(**kwargs) -> Figure:
    """A matplotlib ``Figure`` on the Agg canvas, no pyplot state (safe in a worker thread).
    matplotlib is imported here, on the first figure, not when a module that draws is
    imported: it was 0.4 s of every process's start."""
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.figure import Figure

    fig = Figure(**kwargs)
    FigureCanvasAgg(fig)
    return fig


def demo_figure(result, path: str | Path) -> Path:
    """Contact force over time, and the learned path coloured by its deviation from the truth."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    rec = result.recording
    post = result.project.post_settings  # the band the filter kept (``project.with_learned``)
    kept = result.processed.keep_mask
    comparison = result.project.processed.cad_comparison
    if comparison is not None and comparison.part_deviates:
        fig, (ax_f, ax_p, ax_c) = plt.subplots(
            1, 3, figsize=(19, 5), gridspec_kw={"width_ratios": [1.1, 1, 1.1]}
        )
    else:
        comparison = None
        fig, (ax_f, ax_p) = plt.subplots(
            1, 2, figsize=(13, 5), gridspec_kw={"width_ratios": [1.2, 1]}
        )
    ax_f.plot(
        rec.time_s, rec.force_normal_N, lw=0.6, color="0.3", label="measured (normal to the edge)"
    )
    ax_f.plot(
        rec.time_s[~kept],
        rec.force_normal_N[~kept],
        ".",
        ms=2,
        color="tab:red",
        label="dropped by the filter",
    )
    ax_f.axhline(
        result.project.learned.settings.force_N, color="tab:green", lw=1.2, label="setpoint"
    )
    ax_f.axhspan(
        post.force_min_N,
        post.force_max_N,
        color="tab:green",
        alpha=0.08,
        label=f"filter [{post.force_min_N:g}, {post.force_max_N:g}] N",
    )
    ax_f.set_xlabel("time [s]")
    ax_f.set_ylabel("contact force [N]")
    ax_f.set_title("Path learning: contact force")
    ax_f.legend(loc="upper right", fontsize=8)
    T = result.workpiece.T_base_wobj

    def to_wobj(p: np.ndarray) -> np.ndarray:
        return ((p - T[:3, 3]) @ T[:3, :3]) * 1e3

    wall = result.workpiece.wall
    if wall is not None:
        w = wall.sample(0.0005) * 1e3
        ax_p.plot(
            np.append(w[:, 0], w[0, 0]),
            np.append(w[:, 1], w[0, 1]),
            color="0.6",
            lw=1,
            label="true wall",
        )
    guides = to_wobj(np.array([g.position_m for g in result.guides]))
    if result.score is None:
        ax_p.set_title(f"{len(result.processed.targets)} targets (no true geometry to score)")
    closed = np.vstack([guides, guides[:1]])
    ax_p.plot(closed[:, 0], closed[:, 1], "--", color="tab:orange", lw=0.8, label="test program")
    ax_p.plot(guides[:, 0], guides[:, 1], "o", color="tab:orange", ms=4)
    tg = to_wobj(result.processed.targets.position_m)
    if result.score is not None:
        from .scoring import true_tool_path_distance

        dev = (
            true_tool_path_distance(
                result.workpiece,
                result.project.cell.tool_radius_m,
                result.processed.targets.position_m,
            )
            * 1e3
        )
        sc = ax_p.scatter(tg[:, 0], tg[:, 1], c=dev, s=6, cmap="viridis", zorder=3)
        fig.colorbar(sc, ax=ax_p, label="target deviation [mm]")
        ax_p.set_title(
            f"{len(tg)} targets; path max {result.score.max_m * 1e3:.3f} mm, "
            f"RMS {result.score.rms_m * 1e3:.3f} mm"
        )
    ax_p.plot(tg[:, 0], tg[:, 1], "-", color="tab:blue", lw=0.6, label="learned program")
    if comparison is not None:
        cad = result.workpiece.cad().wall
        if cad is not None:
            c = cad.sample(0.0005) * 1e3
            ax_p.plot(np.append(c[:, 0], c[0, 0]), np.append(c[:, 1], c[0, 1]), ":",
                      color="tab:purple", lw=0.8, label="CAD wall")  # fmt: skip
        ax_p.lines[0].set_label("real wall")
        _comparison_axis(ax_c, comparison)
    ax_p.set_aspect("equal")
    ax_p.set_xlabel("x (work object) [mm]")
    ax_p.set_ylabel("y (work object) [mm]")
    ax_p.legend(loc="lower right", fontsize=7)
    fig.tight_layout()
    out = Path(path)
    fig.savefig(out, dpi=110)
    plt.close(fig)
    return out


def _comparison_axis(ax, comparison) -> None:
    """The signed error along both programs against the real wall (+ air, - overcut)."""
    for score, name, color in (
        (comparison.cad_only, "CAD-only program", "tab:purple"),
        (comparison.learned, "learned program", "tab:blue"),
    ):
        along = score.along_m / max(score.along_m[-1], 1e-12) * 100.0
        step = max(1, len(along) // 5000)
        ax.plot(
            along[::step],
            score.deviation_m[::step] * 1e3,
            lw=0.8,
            color=color,
            label=f"{name}: max {score.max_m * 1e3:.2f} mm, RMS {score.rms_m * 1e3:.2f} mm",
        )
    ax.axhline(0.0, color="0.4", lw=0.8)
    ax.axhspan(-1e3, 0.0, color="tab:red", alpha=0.06)
    low = min(comparison.cad_only.deviation_m.min(), comparison.learned.deviation_m.min())
    high = max(comparison.cad_only.deviation_m.max(), comparison.learned.deviation_m.max())
    ax.set_ylim(low * 1e3 - 0.2, high * 1e3 + 0.2)
    ax.text(1, low * 1e3 - 0.1, "overcut (into the material)", fontsize=8, color="tab:red")
    ax.set_xlabel("along the program [%]")
    ax.set_ylabel("error against the real wall [mm]")
    ax.set_title("What learning buys: the same wall, from the CAD or learned")
    ax.legend(loc="upper right", fontsize=8)
