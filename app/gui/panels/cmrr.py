"""CMRR panel: choose a scenario and a feed controller, run the study with progress and cancel,
read its figures, see its plot and download the controller settings.

The study runs as a job of the session (``app.studies.StudyService``); when it is done it is
saved to the open project (as the reserved export ``_study-cmrr``) by the service, so there
is no save button.
``StudyPanel`` and its ``StudyJobFollower`` are shared with the compensation panel: session and
service events only set a flag, and the follower's thread refreshes the panel at most
``REFRESH_HZ`` times a second.
"""

from __future__ import annotations

import io
import logging
import math
import threading
from collections.abc import Callable
from typing import TYPE_CHECKING, Generic, TypeVar

import numpy as np
import viser

from app.session import JobInfo, Session
from app.studies import CMRR_CONTROLLER_CHOICES, CMRR_JOB_KIND, CmrrOutcome, StudyService
from robomach_core.cmrr import SCENARIO_NAMES
from robomach_core.limits import SEED

from .feedback import guarded
from .inputs import set_value

if TYPE_CHECKING:
    from viser._gui_handles import GuiProgressBarHandle  # not exported by viser

OutcomeT = TypeVar("OutcomeT")  # a study's outcome (CmrrOutcome, CompensationOutcome)
REFRESH_HZ = 4.0
_NOTHING_SHOWN = object()  # the panel has shown no study, not even "none yet"
PLOT_WIDTH_PX = 720  # the sidebar is narrower: a smaller image is sent faster
SCENARIO_HINTS = {
    "milling-steps": "End milling 1 -> 2 -> 3 mm deep, 250 N (chapter figs. 11-12)",
    "deburr-burrs": "Grinding over two burrs, 100 mm/s, spindle limit 300 N (chapter fig. 13)",
    "lund-df": "Lund's milling: removal Df steps and a ramp (Lund fig. 5)",
    "learned-path": "Deburring a synthetic block edge with three random burrs",
}


def png_to_image(png: bytes, width_px: int = PLOT_WIDTH_PX) -> np.ndarray:
    """RGB pixels (h, w, 3) uint8 of a PNG, scaled down to at most ``width_px`` wide."""
    from PIL import Image

    with Image.open(io.BytesIO(png)) as im:
        rgb = im.convert("RGB")
        if rgb.width > width_px:
            rgb = rgb.resize(
                (width_px, round(rgb.height * width_px / rgb.width)), Image.Resampling.LANCZOS
            )
        return np.asarray(rgb)


def fmt(value: object, spec: str = ".1f", unit: str = "") -> str:
    """A number for the panel, or a dash when the study has none (None, NaN)."""
    if value is None or (isinstance(value, float) and not math.isfinite(value)):
        return "-"
    if isinstance(value, bool):
        return "yes" if value else "no"
    return f"{value:{spec}}{unit}"


def show_job_progress(
    job: JobInfo | None,
    *,
    run: viser.GuiButtonHandle,
    cancel: viser.GuiButtonHandle,
    progress: GuiProgressBarHandle,
    status: viser.GuiMarkdownHandle,
) -> None:
    """A study panel's controls for ``job``: run/cancel enabled, progress bar, status line.

    While the job runs the run button is disabled and the bar shows its progress; when it has
    just ended the status line keeps its outcome until the next job.
    """
    running = job is not None and job.status in ("queued", "running")
    run.disabled = running
    cancel.disabled = not running
    progress.animated = running
    if job is None:
        return
    if running:
        set_value(progress, round(job.progress * 100.0, 1))
        state = "Queued" if job.status == "queued" else "Running"
        status.content = f"{state}: {job.progress:.0%}"
    else:
        status.content = "" if job.status == "done" else f"**{job.status}**: {job.error}"


class StudyJobFollower:
    """Follows the study jobs of one kind and calls ``refresh(job)`` from its own thread when
    a session or study event arrived (``job`` is the running job, or the one that just ended,
    or None)."""

    def __init__(
        self,
        session: Session,
        service: StudyService,
        kind: str,
        refresh: Callable[[JobInfo | None], None],
    ) -> None:
        self.session = session
        self.kind = kind
        self._refresh = refresh
        self.job_id: str | None = None  # the job shown (running, or ended and not shown yet)
        self._dirty = threading.Event()
        self._stop = threading.Event()
        self._unsubscribe = (
            session.subscribe(self._on_event),
            service.subscribe(self._on_event),
        )
        self._thread = threading.Thread(target=self._run, name=f"panel-{kind}", daemon=True)
        self._dirty.set()
        self._thread.start()

    def follow(self, job_id: str) -> None:
        """Show this job (just submitted) at the next refresh."""
        self.job_id = job_id
        self._dirty.set()

    def cancel(self) -> None:
        """Cancel the job being shown, if any."""
        if self.job_id is not None:
            self.session.jobs.cancel(self.job_id)

    def close(self) -> None:
        self._stop.set()
        self._dirty.set()
        for unsubscribe in self._unsubscribe:
            unsubscribe()
        self._thread.join(timeout=2.0)

    def _on_event(self, topic: str) -> None:
        if topic in ("job", "project", "cmrr", "compensation"):
            self._dirty.set()

    def _run(self) -> None:
        period = 1.0 / REFRESH_HZ
        while not self._stop.is_set():
            self._dirty.wait()
            if self._stop.is_set():
                return
            self._dirty.clear()
            try:
                self._refresh(self._current_job())
            except Exception:
                logging.getLogger(__name__).exception("%s panel refresh failed", self.kind)
            self._stop.wait(period)

    def _current_job(self) -> JobInfo | None:
        active = self.session.jobs.active((self.kind,))
        if active:
            self.job_id = active[0].id
            return active[0]
        if self.job_id is None:
            return None
        job_id, self.job_id = self.job_id, None
        try:
            return self.session.jobs.get(job_id)
        except KeyError:  # forgotten by the runner
            return None


class StudyPanel(Generic[OutcomeT]):
    """What the CMRR and compensation panels share: run/cancel/progress/status/figures, the
    settings download and the job follower. A panel names itself (``NAME``, ``JOB_KIND``,
    ``SETTINGS_FILE``), adds its ``download`` button, submits its job in ``_submit`` and shows
    a new study (of outcome type ``OutcomeT``) in ``_show``."""

    NAME: str
    JOB_KIND: str
    SETTINGS_FILE: str
    download: viser.GuiButtonHandle

    def _submit(self) -> str:
        """Submit the panel's study as a job; returns its id."""
        raise NotImplementedError

    def _show_hint(self) -> None:
        """Show the hint of the chosen study on the run button."""
        raise NotImplementedError

    def _show(self, outcome: OutcomeT | None) -> None:
        """Show the project's last study (None: none yet)."""
        raise NotImplementedError

    def _add_run_controls(self, server: viser.ViserServer, run_label: str) -> None:
        self.run = server.gui.add_button(run_label, icon=viser.Icon.PLAYER_PLAY, color="green")
        self.cancel = server.gui.add_button(
            "Cancel", icon=viser.Icon.PLAYER_STOP, color="red", disabled=True
        )
        self.progress = server.gui.add_progress_bar(0.0)
        self.status = server.gui.add_markdown("")
        self.figures = server.gui.add_markdown("")

    def _follow_jobs(
        self,
        session: Session,
        service: StudyService,
        result: Callable[[], OutcomeT | None],
        settings_json: Callable[[], str],
    ) -> None:
        """Wire run, cancel and download, then follow the panel's jobs (refreshing it)."""
        self._result, self._settings_json = result, settings_json
        self.run.on_click(guarded(f"{self.NAME} study", lambda e: self.start()))
        self.cancel.on_click(guarded("Cancel", lambda e: self.follower.cancel()))
        self.download.on_click(guarded(f"{self.NAME} settings", self._send_settings))
        self._shown: object = _NOTHING_SHOWN
        self._show_hint()
        self.follower = StudyJobFollower(session, service, self.JOB_KIND, self.refresh)

    def _send_settings(self, event) -> None:
        event.client.send_file_download(
            self.SETTINGS_FILE, self._settings_json().encode("utf-8"), save_immediately=True
        )

    def start(self) -> str:
        """Run the study the panel's controls describe; returns the job id."""
        job_id = self._submit()
        self.follower.follow(job_id)
        return job_id

    def close(self) -> None:
        """Stop following the session and the service."""
        self.follower.close()

    def refresh(self, job: JobInfo | None) -> None:
        """Show the job's progress (or how it ended) and the project's last study."""
        show_job_progress(
            job, run=self.run, cancel=self.cancel, progress=self.progress, status=self.status
        )
        outcome = self._result()
        if outcome is not self._shown:
            self._shown = outcome
            self._show(outcome)


class CmrrPanel(StudyPanel[CmrrOutcome]):
    """Scenario, controller (or all), seed; run, cancel, progress; figures, plot, settings.

    Args:
        server: The viser server.
        session: The workbench session (its job runner shows the progress).
        service: The study service that runs and keeps the studies.
    """

    NAME, JOB_KIND, SETTINGS_FILE = "CMRR", CMRR_JOB_KIND, "cmrr_settings.json"

    def __init__(self, server: viser.ViserServer, session: Session, service: StudyService) -> None:
        self.session = session
        self.service = service
        last = service.cmrr_result()
        with server.gui.add_folder("CMRR study", expand_by_default=False):
            self.scenario = server.gui.add_dropdown(
                "Scenario",
                SCENARIO_NAMES,
                initial_value=last.scenario if last else "milling-steps",
                hint="The cut to simulate",
            )
            self.controller = server.gui.add_dropdown(
                "Controller",
                ("default", *CMRR_CONTROLLER_CHOICES),
                initial_value=last.controller if last else "default",
                hint="Feed controller; default: the paper's for the scenario; all: compare",
            )
            self.seed = server.gui.add_number(
                "Seed", last.seed if last else 0, min=0, max=int(SEED.max), step=1
            )
            self._add_run_controls(server, "Run CMRR study")
            self.plot = server.gui.add_image(np.full((2, 2, 3), 255, np.uint8), format="png")
            self.enlarge = server.gui.add_button(
                "Open the figure large", disabled=last is None, hint="Full size, in a window"
            )
            self.download = server.gui.add_button(
                "Download settings JSON", icon=viser.Icon.DOWNLOAD, disabled=last is None
            )
        self.enlarge.on_click(guarded("CMRR figure", self._open_large))
        self.scenario.on_update(lambda e: self._show_hint())
        self._follow_jobs(session, service, service.cmrr_result, service.cmrr_settings_json)

    def _submit(self) -> str:
        return self.service.start_cmrr(
            self.scenario.value, self.controller.value, seed=int(self.seed.value)
        )

    def _open_large(self, event) -> None:
        """The last study's figure at full size in a wide modal of the user's browser."""
        from .large import open_large, png_html

        outcome = self.service.cmrr_result()
        if outcome is None or outcome.plot_png is None:
            return
        open_large(
            event.client,
            "CMRR study figure",
            png_html(outcome.plot_png, alt="CMRR study figure"),
            download=("cmrr_study.png", outcome.plot_png),
        )

    def _show_hint(self) -> None:
        self.run.hint = SCENARIO_HINTS.get(self.scenario.value)

    def _show(self, outcome: CmrrOutcome | None) -> None:
        self.download.disabled = outcome is None
        self.enlarge.disabled = outcome is None or outcome.plot_png is None
        if outcome is None:
            set_value(self.progress, 0.0)
            self.figures.content = "*No CMRR study in this project yet.*"
            self.plot.image = np.full((2, 2, 3), 255, np.uint8)
            return
        set_value(self.progress, 100.0)
        self.figures.content = cmrr_figures(outcome)
        if outcome.plot_png is not None:
            self.plot.image = png_to_image(outcome.plot_png)


def cmrr_figures(outcome: CmrrOutcome) -> str:
    """Markdown: one row per controller (stable, peak force, RMS error, cycle time, gain)."""
    summary = outcome.summary
    rows = summary.get("results", [summary])
    lines = [
        f"**{summary.get('scenario', outcome.scenario)}**, seed {outcome.seed}; saved to the "
        "project",
        "",
        "| controller | stable | peak F (N) | rms err (N) | cycle (s) | gain |",
        "| --- | --- | --- | --- | --- | --- |",
    ]
    for r in rows:
        stop = " (stopped)" if r.get("protection_stop") else ""
        lines.append(
            f"| {r.get('controller')}{stop} | {fmt(r.get('stable'))} | "
            f"{fmt(r.get('peak_force_N'), '.0f')} | {fmt(r.get('force_rms_error_N'))} | "
            f"{fmt(r.get('cycle_time_s'), '.2f')} | {fmt(r.get('cycle_time_gain'), '.2f')} |"
        )
    baseline = rows[0].get("baseline_cycle_time_s")
    if baseline is not None:
        lines += ["", f"Greatest safe constant feed: cycle {fmt(baseline, '.2f')} s."]
    return "\n".join(lines)
