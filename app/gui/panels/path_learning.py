"""Path-learning panel: force and speed, run with progress and cancel, live force plot."""

from __future__ import annotations

import numpy as np
import viser
import viser.uplot

from app.session import JobInfo, Session
from robomach_core import limits
from robomach_core.learning.settings import (
    WALL_SIDE_CHOICES,
    PathLearningSettings,
    WallSideSetting,
)

from .feedback import guarded
from .inputs import set_value
from .postprocess import OUT_OF_DATE

# The core's ranges, the ones the API and CLI take: a project learned at 0.5 mm/s (through the
# API) must open in the workbench, whose sliders refuse an initial value outside their range.
FORCE_RANGE_N = (limits.LEARNING_FORCE_N.min, limits.LEARNING_FORCE_N.max)
SPEED_RANGE_MM_S = (limits.LEARNING_SPEED_MM_S.min, limits.LEARNING_SPEED_MM_S.max)
PLOT_POINTS = 600


class PathLearningPanel:
    """Follow the wall along the guide points at constant contact force (path learning).

    The plot shows the contact force against the setpoint: live (|F| every 20 ms of simulated
    time) while a run goes on, then the recorded force normal to the edge.
    """

    def __init__(self, server: viser.ViserServer, session: Session, scene=None) -> None:
        self.session = session
        self.scene = scene
        learned = session.project().learned
        last = learned.settings if learned else PathLearningSettings()  # the defaults, once
        with server.gui.add_folder("Path learning"):
            self.force = server.gui.add_slider(
                "Force (N)",
                *FORCE_RANGE_N,
                0.5,
                last.force_N,
                hint="Contact force reference, normal to the wall (held along Yp)",
            )
            self.speed = server.gui.add_slider(
                "Speed (mm/s)",
                *SPEED_RANGE_MM_S,
                0.5,
                last.speed_m_s * 1e3,
                hint="Learning speed along the path",
            )
            self.closed = server.gui.add_checkbox(
                "Closed contour",
                last.closed,
                hint="Return from the last guide point to the first",
            )
            self.wall_side = server.gui.add_dropdown(
                "Wall side",
                WALL_SIDE_CHOICES,
                initial_value=last.wall_side,
                hint="The wall to follow: left or right of travel, looking along the tool into "
                "the part. auto: from a push at the guide points or the part's mesh; refused "
                "when neither tells (the scene shows the wall it will follow)",
            )
            self.floor_clearance = server.gui.add_slider(
                "Floor clearance (mm)",
                limits.FLOOR_CLEARANCE_MM.min,
                limits.FLOOR_CLEARANCE_MM.max,
                0.1,
                last.floor_clearance_m * 1e3,
                hint="Machining height: the cutter this far above a floor the run meets or a "
                "guide point rests on",
            )
            self.wall_note = server.gui.add_markdown("")
            self.check = server.gui.add_markdown("")  # the check before the run (its findings)
            self.run = server.gui.add_button(
                "Run path learning", icon=viser.Icon.PLAYER_PLAY, color="green"
            )
            self.cancel = server.gui.add_button(
                "Cancel", icon=viser.Icon.PLAYER_STOP, color="red", disabled=True
            )
            self.progress = server.gui.add_progress_bar(0.0)
            self.status = server.gui.add_markdown("")
            self.plot = server.gui.add_uplot(
                (np.zeros(2), np.zeros(2), np.full(2, self.force.value), np.zeros(2), np.zeros(2)),
                (
                    viser.uplot.Series(label="t (s)"),
                    viser.uplot.Series(label="contact force (N)", stroke="#d62728", width=1.0),
                    viser.uplot.Series(
                        label="setpoint (N)", stroke="#1d3557", width=2.5, dash=(8, 4)
                    ),
                    viser.uplot.Series(label="min (N)", stroke="#f4a3a3", width=0.8),
                    viser.uplot.Series(label="max (N)", stroke="#f4a3a3", width=0.8),
                ),
                title="Contact force",
                scales={
                    "x": viser.uplot.Scale(time=False, auto=True),
                    "y": viser.uplot.Scale(auto=True),
                },
                legend=viser.uplot.Legend(show=True),
                aspect=1.6,
            )
        self.run.on_click(
            guarded(
                "Path learning",
                lambda e: self.session.learning.start_path_learning(
                    self.force.value,
                    self.speed.value * 1e-3,
                    closed=self.closed.value,
                    wall_side=self.wall_side.value,
                    floor_clearance_m=self.floor_clearance.value * 1e-3,
                ),
            )
        )
        self.cancel.on_click(guarded("Cancel", lambda e: self._cancel()))
        self.job_id: str | None = None
        self.refresh_plot()

    def route_settings(self) -> tuple[WallSideSetting, bool]:
        """(wall side, closed) as set in the panel: the operator check and the preview use
        them."""
        return self.wall_side.value, self.closed.value

    def on_route_change(self, callback) -> None:
        """Call ``callback`` when the wall side or the closed setting changes."""
        self.wall_side.on_update(lambda e: callback())
        self.closed.on_update(lambda e: callback())

    def refresh_wall(self) -> None:
        """Highlight the wall the next run will follow (or say why it cannot tell)."""
        if self.scene is None:
            return
        points, text = self.session.learning.taught_wall_preview(
            self.wall_side.value, closed=self.closed.value
        )
        self.scene.paths.set_taught_wall(points, "" if not points else "wall to follow")
        self.wall_note.content = text

    def show_check(self, findings_markdown: str) -> None:
        """The check before the run (the Guide-point rules' findings), above Run."""
        self.check.content = f"**Check before the run**\n\n{findings_markdown}"

    def refresh_stop(self, *, old_cell: bool = False) -> None:
        """Mark where the last run stopped early, if it did (``old_cell``: the recording
        belongs to a cell no longer there, and its mark is not drawn over the new part)."""
        if self.scene is None:
            return
        rec = self.session.project().recording
        stop = None if rec is None or old_cell else rec.stop
        if stop is None:
            self.scene.paths.set_stop(None)
        else:
            self.scene.paths.set_stop(stop.position_m, f"stopped: {stop.cause}")

    def _cancel(self) -> None:
        if self.job_id is not None:  # none while no job runs (the button is disabled then)
            self.session.jobs.cancel(self.job_id)

    def show_job(self, job: JobInfo | None) -> None:
        """Reflect a path-learning job (running or just ended) in the buttons and the status."""
        if job is None:
            self.status.content = self._recording_summary()
            return
        running = job.status in ("queued", "running")
        self.job_id = job.id if running else None
        self.run.disabled = running
        self.cancel.disabled = not running
        set_value(self.progress, round(job.progress * 100.0, 1))
        self.progress.animated = running
        if running:
            self.status.content = f"Running: {job.progress:.0%}"
        elif job.status == "done":
            self.status.content = self._recording_summary()
        else:
            self.status.content = f"**{job.status}**: {job.error or ''}"

    def _recording_summary(self) -> str:
        rec = self.session.project().recording
        if rec is None:
            return "*No recording yet.*"
        duration = float(rec.time_s[-1]) if len(rec) else 0.0
        text = f"{len(rec):,} samples over {duration:.1f} s; {rec.stop_reason}" + (
            "" if rec.completed else " (**incomplete**)"
        )
        reason = self.session.project().stale_reasons().get("recording")
        if reason is not None:
            text = f"**{OUT_OF_DATE}**: {reason}.\n\n{text}"
        return text

    def refresh_plot(self) -> None:
        """Redraw the force plot from the session's force trace."""
        trace = self.session.learning.force_trace(PLOT_POINTS)
        if trace.source == "none" or len(trace.time_s) < 2:
            t = np.zeros(2)
            self.plot.data = (t, t, np.full(2, float(self.force.value)), t, t)
            return
        ref = trace.force_reference_N
        if np.all(np.isnan(ref)):  # live: the reference of the run in progress
            ref = np.full(len(trace.time_s), float(self.force.value))
        f = np.asarray(trace.force_N, dtype=float)
        self.plot.data = (
            np.asarray(trace.time_s, dtype=float),
            f,
            np.asarray(ref, dtype=float),
            f if trace.force_min_N is None else np.asarray(trace.force_min_N, dtype=float),
            f if trace.force_max_N is None else np.asarray(trace.force_max_N, dtype=float),
        )
