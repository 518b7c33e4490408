"""PNG figures of the compensation studies (matplotlib ``Figure`` objects, no pyplot state).

Each function takes study data in SI units, draws in µm/mm/N, saves one PNG and returns its path.
"""

from __future__ import annotations

from collections.abc import Mapping
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np

from ..cell import CONTROL_PERIOD_S
from ..plots import agg_figure
from .ilc import IlcResult
from .milling import MillingRun
from .modes import variant_name

if TYPE_CHECKING:
    from matplotlib.figure import Figure

DPI = 110
# Legend words of the milling study's runs, by ``modes.variant_name``.
MODE_LABELS = {
    variant_name("off"): "uncompensated",
    variant_name("online"): "online (fig. 15)",
    variant_name("offline", "linear"): "offline, linear",
    variant_name("offline", "nonlinear"): "offline, non-linear (eq. 32)",
}


def _save(fig: Figure, path: Path) -> Path:
    fig.tight_layout()
    fig.savefig(path, dpi=DPI)
    return path


def plot_identification(
    path: Path,
    stiffness_true_Nm_rad: np.ndarray,
    stiffness_identified_Nm_rad: np.ndarray,
    stiffness_std_Nm_rad: np.ndarray,
    prediction_error_m: np.ndarray,
    *,
    bound_mm: float = 0.04,
) -> Path:
    """Identified vs true Kq per joint, and the prediction error over the workspace."""
    fig = agg_figure(figsize=(10, 4))
    ax1, ax2 = fig.subplots(1, 2)
    joints = np.arange(1, 7)
    ax1.bar(joints - 0.2, np.asarray(stiffness_true_Nm_rad) / 1e3, 0.4, label="true (hidden)")
    ax1.bar(
        joints + 0.2,
        np.asarray(stiffness_identified_Nm_rad) / 1e3,
        0.4,
        yerr=2 * np.asarray(stiffness_std_Nm_rad) / 1e3,
        label="identified ± 2σ",
    )
    ax1.set_xlabel("joint")
    ax1.set_ylabel("stiffness [kN·m/rad]")
    ax1.set_title("Joint stiffness, eq. (23)")
    ax1.legend()
    errors_mm = np.sort(np.asarray(prediction_error_m) * 1e3)
    ax2.plot(np.arange(1, len(errors_mm) + 1), errors_mm, "o-", ms=3)
    ax2.axhline(bound_mm, color="r", ls="--", label=f"chapter: < {bound_mm} mm")
    ax2.set_xlabel("workspace pose (sorted)")
    ax2.set_ylabel("|predicted - true| deflection [mm]")
    ax2.set_title("Prediction error under the milling load")
    ax2.legend()
    return _save(fig, path)


def plot_nonlinear(
    path: Path,
    load_N: np.ndarray,
    model_gap_m: np.ndarray,
    landing_linear_m: np.ndarray,
    landing_nonlinear_m: np.ndarray,
) -> Path:
    """Non-linear minus linear deflection, and the landing error of each compensation."""
    fig = agg_figure(figsize=(10, 4))
    ax1, ax2 = fig.subplots(1, 2)
    ax1.loglog(load_N, np.maximum(model_gap_m, 1e-15) * 1e6, "o-")
    ax1.set_xlabel("load [N]")
    ax1.set_ylabel("|non-linear - linear| TCP deflection [µm]")
    ax1.set_title("Change of geometry under load")
    ax1.grid(True, which="both", alpha=0.3)
    ax2.loglog(load_N, np.maximum(landing_linear_m, 1e-15) * 1e6, "o-", label="linear (t0 - C W)")
    ax2.loglog(
        load_N, np.maximum(landing_nonlinear_m, 1e-15) * 1e6, "s-", label="non-linear, eq. (32)"
    )
    ax2.set_xlabel("load [N]")
    ax2.set_ylabel("TCP error after compensation [µm]")
    ax2.set_title("Offline target correction, exact model")
    ax2.grid(True, which="both", alpha=0.3)
    ax2.legend()
    return _save(fig, path)


def plot_gravity(path: Path, residual_N: np.ndarray, noise_N: float) -> Path:
    """Residual force after gravity compensation at random poses."""
    fig = agg_figure(figsize=(6, 4))
    ax = fig.subplots()
    ax.plot(np.arange(1, len(residual_N) + 1), residual_N, "o")
    ax.axhline(noise_N * np.sqrt(3), color="r", ls="--", label="sensor noise (RMS norm)")
    ax.set_xlabel("random pose")
    ax.set_ylabel("|compensated force| without contact [N]")
    ax.set_title("Gravity compensation residual")
    ax.legend()
    return _save(fig, path)


def plot_milling(
    path: Path, runs: Mapping[str, MillingRun], *, title: str, error_label: str
) -> Path:
    """Error along the cut for each compensation mode, and the process force."""
    fig = agg_figure(figsize=(10, 6))
    ax1, ax2 = fig.subplots(2, 1, sharex=False)
    for mode, run in runs.items():
        label = f"{MODE_LABELS.get(mode, mode)}: max {run.error_max_m * 1e6:.0f} µm"
        ax1.plot(run.error_u_m * 1e3, run.error_m * 1e6, label=label, lw=1)
    ax1.axhline(0.0, color="k", lw=0.5)
    first = next(iter(runs.values()))
    ax1.set_ylabel(error_label)
    ax1.set_xlabel("position along the cut [mm]")
    ax1.set_title(title)
    ax1.legend(fontsize=8)
    force = np.linalg.norm(first.wrench[:, :3], axis=1)
    ax2.plot(first.time_s, force, lw=0.8)
    ax2.set_xlabel("time [s]")
    ax2.set_ylabel("|process force| [N] (uncompensated)")
    return _save(fig, path)


def plot_ilc(path: Path, arm: IlcResult, force: IlcResult) -> Path:
    """Error per iteration for both ILC variants, and the error along the path."""
    fig = agg_figure(figsize=(10, 7))
    (ax1, ax2), (ax3, ax4) = fig.subplots(2, 2)
    it = np.arange(len(arm.error_mean_um))
    ax1.plot(it, arm.error_mean_um, "o-", label="arm-side ILC")
    ax1.plot(it, force.error_mean_um, "s-", label="force ILC")
    ax1.plot(it, force.deviation_mean_um, "^--", label="force ILC, around offset")
    ax1.set_xlabel("iteration k")
    ax1.set_ylabel("mean |error| [µm]")
    ax1.set_title("Error per iteration")
    ax1.legend(fontsize=8)
    ax2.plot(it, arm.error_normalized, "o-", label="arm-side (Fig. 11)")
    dev = force.deviation_mean_um / force.deviation_mean_um[0]
    ax2.plot(it, dev, "^--", label="force, around offset (Fig. 13)")
    ax2.set_xlabel("iteration k")
    ax2.set_ylabel("normalised magnitude")
    ax2.set_ylim(bottom=0)
    ax2.legend(fontsize=8)
    for ax, result, name in ((ax3, arm, "arm-side"), (ax4, force, "force")):
        t = np.arange(result.errors_m.shape[1]) * CONTROL_PERIOD_S
        for k in (0, len(result.errors_m) - 1):
            for axis, color in zip("xyz", ("C0", "C1", "C2"), strict=True):
                i = "xyz".index(axis)
                ls = "-" if k else ":"
                ax.plot(
                    t,
                    result.errors_m[k, :, i] * 1e6,
                    ls,
                    color=color,
                    lw=0.8,
                    label=f"{axis}, k={k}",
                )
        ax.set_xlabel("time [s]")
        ax.set_ylabel("error [µm]")
        ax.set_title(f"{name} ILC: first and last run")
        ax.legend(fontsize=7, ncol=2)
    return _save(fig, path)


def plot_compliance_paper(
    path: Path, time_s: np.ndarray, runs: Mapping[str, np.ndarray], engaged: np.ndarray
) -> Path:
    """The compliance paper's Figs. 13 and 15: the deviation across the feed over the line,
    uncompensated and compensated, the fully engaged part shaded."""
    fig = agg_figure(figsize=(9, 4))
    ax = fig.subplots()
    labels = {
        "uncompensated": "uncompensated",
        "paper_model": "compensated, eq. (32), Table 1 stiffness",
        "identified_model": "compensated, eq. (32), identified stiffness",
    }
    for key, deviation in runs.items():
        ax.plot(time_s, np.asarray(deviation) * 1e6, label=labels.get(key, key))
    t_engaged = np.asarray(time_s)[np.asarray(engaged)]
    if t_engaged.size:
        ax.axvspan(t_engaged[0], t_engaged[-1], color="0.9", zorder=0, label="fully engaged")
    ax.set_xlabel("time [s]")
    ax.set_ylabel("deviation across the feed [µm]")
    ax.set_title("KR 270 at Table 1's pose, 80 mm at 4 m/min")
    ax.legend(fontsize=8)
    return _save(fig, path)
