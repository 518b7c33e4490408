"""Post-processing panel: force thresholds and tolerance that re-run at once, and the result.

The scene shows the raw samples (grey), the samples kept by the force filter and the reduced
targets; "Colour by deviation" paints the last two by their distance from the true tool path
(built-in workpieces), green at 0 to red at the colour scale.
"""

from __future__ import annotations

import threading

import numpy as np
import viser

from app.session import Session
from robomach_core import limits
from robomach_core.errors import RobomachError
from robomach_core.scoring import true_tool_path_distance

from ..scene import CellScene
from .feedback import guarded
from .inputs import set_value

OUT_OF_DATE = "\u26a0 Out of date"


class PostprocessPanel:
    """Fmin/Fmax and tolerance; every change re-runs the filter and the reduction."""

    def __init__(self, server: viser.ViserServer, session: Session, scene: CellScene) -> None:
        self.session = session
        self.scene = scene
        s = session.project().post_settings
        with server.gui.add_folder("Post-processing"):
            self.force_min = server.gui.add_slider(
                "Fmin (N)",
                limits.FORCE_THRESHOLD_N.min,
                limits.LEARNING_FORCE_N.max,
                0.5,
                s.force_min_N,
                hint="Samples with less contact force are dropped (lost contact)",
            )
            self.force_max = server.gui.add_slider(
                "Fmax (N)",
                limits.LEARNING_FORCE_N.min,
                1.5 * limits.LEARNING_FORCE_N.max,  # the band that follows the force
                0.5,
                s.force_max_N,
                hint="Samples with more contact force are dropped (corner spikes)",
            )
            self.tolerance = server.gui.add_slider(
                "Tolerance (mm)",
                limits.TOLERANCE_MM.min,
                limits.TOLERANCE_MM.max,
                0.01,
                s.tolerance_m * 1e3,
                hint="Deviation height of the reduction (the chapter: 0.2 mm, ~300 targets)",
            )
            self.colour = server.gui.add_checkbox("Colour by deviation", True)
            self.scale = server.gui.add_slider("Colour scale (mm)", 0.05, 2.0, 0.05, 0.5)
            self.run = server.gui.add_button("Run post-processing", hint="With the values above")
            self.summary = server.gui.add_markdown("")
        self.run.on_click(guarded("Post-processing", lambda e: self.rerun()))
        for slider in (self.force_min, self.force_max, self.tolerance):
            slider.on_update(guarded("Post-processing", lambda e: self.rerun()))
        for control in (self.colour, self.scale):
            control.on_update(lambda e: self.show_in_scene())
        # A slider drag sends many values: one re-run at a time, the last value wins.
        self._rerun_lock = threading.Lock()
        self._rerun_pending = False
        self.refresh()

    def rerun(self) -> None:
        """Post-process with the panel's values (coalescing updates that arrive meanwhile)."""
        self._rerun_pending = True
        if not self._rerun_lock.acquire(blocking=False):
            return
        try:
            while self._rerun_pending:
                self._rerun_pending = False
                self.session.learning.run_postprocess(
                    force_min_N=self.force_min.value,
                    force_max_N=self.force_max.value,
                    tolerance_m=self.tolerance.value * 1e-3,
                )
        finally:
            self._rerun_lock.release()

    def refresh(self) -> None:
        """Mirror the session's settings and outcome in the sliders, the summary and the scene."""
        s = self.session.project().post_settings
        set_value(self.force_min, s.force_min_N)
        set_value(self.force_max, s.force_max_N)
        set_value(self.tolerance, round(s.tolerance_m * 1e3, 3))
        self.summary.content = self._summary()
        self.show_in_scene()

    def _summary(self) -> str:
        outcome = self.session.project().processed
        if outcome is None:
            if self.session.project().recording is None:
                return "*No recording yet.*"
            return "*Not post-processed yet: press Run (or move a slider).*"
        r = outcome.result
        lines = []
        reason = self.session.project().stale_reasons().get("postprocess")
        if reason is not None:
            lines += [f"**{OUT_OF_DATE}**: {reason}.", ""]
        lines += [
            "| | |",
            "|---|---:|",
            f"| raw samples | {outcome.samples_raw:,} |",
            f"| kept by the force filter | {r.samples_filtered:,} |",
            f"| targets | {len(r.targets):,} |",
        ]
        if outcome.score is not None:
            lines += [
                f"| max deviation | {outcome.score.max_m * 1e3:.3f} mm |",
                f"| RMS deviation | {outcome.score.rms_m * 1e3:.3f} mm |",
            ]
        else:
            lines.append("| deviation | no ground truth |")
        mesh = outcome.mesh_score
        if mesh is not None:  # every part: against its walls, signed
            lines += [
                f"| max deviation from the walls | {mesh.max_m * 1e3:.3f} mm |",
                f"| RMS deviation from the walls | {mesh.rms_m * 1e3:.3f} mm |",
                f"| overcut (into the wall) | {mesh.overcut_m * 1e3:.3f} mm |",
                f"| air (off the wall) | {mesh.air_m * 1e3:.3f} mm |",
            ]
        if outcome.taught_wall is not None:
            lines += [
                "",
                ("\u2714 " if outcome.taught_wall.follows else "\u26d4 ")
                + outcome.taught_wall.message,
            ]
        for problem in outcome.problems():
            lines += ["", f"\u26d4 **Not fit to machine**: {problem}"]
        return "\n".join(lines)

    def show_in_scene(self) -> None:
        """Draw raw, filtered and reduced points (coloured by deviation when asked)."""
        rec = self.session.project().recording
        outcome = self.session.project().processed
        if rec is None:
            self.scene.paths.set_samples(None)
            return
        if outcome is None:
            self.scene.paths.set_samples(drawn(rec.position_m))
            return
        r = outcome.result
        filtered = drawn(r.surface_m[r.keep_mask])
        targets = r.targets.position_m
        dev_f = dev_t = dense = None
        if self.colour.value:
            wp, radius = self.session.robot.workpiece, self.session.robot.cell.tool.radius_m
            try:
                dev_f = true_tool_path_distance(wp, radius, filtered)
                dev_t = true_tool_path_distance(wp, radius, targets)
                # The straight moves between the targets too, not only their ends.
                along = densified(targets, SEGMENT_SAMPLE_M)
                dense = (along, true_tool_path_distance(wp, radius, along))
            except RobomachError:  # an uploaded mesh has no true wall
                dev_f = dev_t = dense = None
        self.scene.paths.set_samples(
            drawn(rec.position_m),
            filtered,
            targets,
            filtered_deviation_m=dev_f,
            targets_deviation_m=dev_t,
            segments_deviation=dense,
            deviation_scale_m=self.scale.value * 1e-3,
            stale=self.session.project().status()["postprocess"] == "stale",
        )


SEGMENT_SAMPLE_M = 0.0005
# At most this many samples per drawn cloud: a recording learned at 0.5 mm/s holds 311k samples
# 2 um apart, far below what the 0.8 mm points show; every one of them cost the server's
# interpreter (colours, messages) and the browser's memory on each redraw.
MAX_DRAWN_SAMPLES = 40_000


def drawn(points_m: np.ndarray) -> np.ndarray:
    """Every k-th row of ``points_m`` (n, 3), k chosen so at most ``MAX_DRAWN_SAMPLES`` stay."""
    step = max(1, -(-len(points_m) // MAX_DRAWN_SAMPLES))
    return points_m[::step]


def densified(points_m: np.ndarray, spacing_m: float) -> np.ndarray:
    """(k, 3) points along the polyline through ``points_m`` (n, 3), at most ``spacing_m``
    apart, keeping every vertex."""
    pts = np.asarray(points_m, dtype=float)
    if len(pts) < 2:
        return pts.copy()
    out = [pts[:1]]
    for a, b in zip(pts[:-1], pts[1:], strict=True):
        n = max(1, int(np.ceil(np.linalg.norm(b - a) / spacing_m)))
        t = np.linspace(0.0, 1.0, n + 1)[1:, None]
        out.append(a + (b - a) * t)
    return np.concatenate(out)
