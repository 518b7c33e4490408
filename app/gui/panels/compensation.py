"""Compensation panel: run the stiffness identification, gravity, milling or ILC study (or all)
with progress and cancel, read its figures next to the papers', page through its plots and
download the compensation settings.

The study runs as a job of the session (``app.studies.StudyService``), which saves it to the
open project (as the reserved export ``_study-compensation``) when it is done.
"""

from __future__ import annotations

import numpy as np
import viser

from app.session import Session
from app.studies import (
    COMPENSATION_JOB_KIND,
    COMPENSATION_STUDIES,
    CompensationOutcome,
    StudyService,
)
from robomach_core.stiffness import COMPENSATIONS, OFFLINE_MODELS, StudyOptions

from .cmrr import StudyPanel, fmt, png_to_image
from .inputs import set_value

STUDY_HINTS = {
    "identify": "Joint stiffness from CMM measurements under known loads (chapter 5.2)",
    "gravity": "Tool mass, centre of mass and sensor bias from 15 poses (chapter 5.3)",
    "milling": "Block and face milling with and without deflection compensation",
    "ilc": "Iterative learning control on a milled square (Lund ILC paper)",
    "all": "Every study in turn; the milling and ILC use the identified model",
}
NO_PLOT = "(none)"


class CompensationPanel(StudyPanel[CompensationOutcome]):
    """Study, quick preview, compensation mode; run, cancel, progress; figures, plots, settings.

    Args:
        server: The viser server.
        session: The workbench session (its job runner shows the progress).
        service: The study service that runs and keeps the studies.
    """

    NAME, JOB_KIND = "Compensation", COMPENSATION_JOB_KIND
    SETTINGS_FILE = "compensation_settings.json"

    def __init__(self, server: viser.ViserServer, session: Session, service: StudyService) -> None:
        self.session = session
        self.service = service
        last = service.compensation_result()
        with server.gui.add_folder("Compensation study", expand_by_default=False):
            self.study = server.gui.add_dropdown(
                "Study", COMPENSATION_STUDIES, initial_value=last.study if last else "identify"
            )
            self.quick = server.gui.add_checkbox(
                "Quick preview",
                last.quick if last else True,
                hint="Shorter cuts and fewer poses: seconds instead of about a minute",
            )
            self.mode = server.gui.add_dropdown(
                "Mode",
                COMPENSATIONS,
                initial_value=StudyOptions.mode,
                hint="Compensation written to the settings: off, offline (targets corrected "
                "before the run) or online (needs the gravity study)",
            )
            self.offline_model = server.gui.add_dropdown(
                "Offline model",
                OFFLINE_MODELS,
                initial_value=StudyOptions.offline_model,
                hint="How offline compensation corrects the targets: linear (t0 - C W) or "
                "non-linear (the compliance paper's eq. 32)",
            )
            self._add_run_controls(server, "Run compensation study")
            self.plot_name = server.gui.add_dropdown("Plot", (NO_PLOT,), initial_value=NO_PLOT)
            self.plot = server.gui.add_image(np.full((2, 2, 3), 255, np.uint8), format="png")
            self.download = server.gui.add_button(
                "Download settings JSON", icon=viser.Icon.DOWNLOAD, disabled=True
            )
        self.study.on_update(lambda e: self._show_hint())
        # The model matters only to offline compensation.
        self.offline_model.disabled = self.mode.value != "offline"
        self.mode.on_update(
            lambda e: setattr(self.offline_model, "disabled", self.mode.value != "offline")
        )
        self.plot_name.on_update(lambda e: self._show_plot())
        self._follow_jobs(
            session, service, service.compensation_result, service.compensation_settings_json
        )

    def _submit(self) -> str:
        return self.service.start_compensation(
            self.study.value,
            quick=bool(self.quick.value),
            mode=self.mode.value,
            offline_model=self.offline_model.value,
        )

    def _show_hint(self) -> None:
        self.run.hint = STUDY_HINTS.get(self.study.value)

    def _show(self, outcome: CompensationOutcome | None) -> None:
        self.download.disabled = outcome is None or outcome.settings is None
        if outcome is None:
            set_value(self.progress, 0.0)
            self.figures.content = "*No compensation study in this project yet.*"
            self.plot_name.options = (NO_PLOT,)
            set_value(self.plot_name, NO_PLOT)
            self._show_plot()
            return
        set_value(self.progress, 100.0)
        self.figures.content = compensation_figures(outcome)
        names = tuple(sorted(outcome.plots)) or (NO_PLOT,)
        keep = self.plot_name.value if self.plot_name.value in names else names[0]
        self.plot_name.options = names
        set_value(self.plot_name, keep)
        self._show_plot()

    def _show_plot(self) -> None:
        outcome = self._shown
        png = None
        if isinstance(outcome, CompensationOutcome):
            png = outcome.plots.get(self.plot_name.value)
        self.plot.image = png_to_image(png) if png else np.full((2, 2, 3), 255, np.uint8)


def compensation_figures(outcome: CompensationOutcome) -> str:
    """Markdown: the study's main numbers, each next to the paper's."""
    s = outcome.summary
    lines = [
        f"**{outcome.study}**{' (quick)' if outcome.quick else ''}, seed {outcome.seed}; saved "
        "to the project",
        "",
    ]
    if "stiffness_rel_error_max" in s:
        rel = s["stiffness_rel_error_max"]
        lines.append(
            f"- Stiffness: max relative error {fmt(None if rel is None else rel * 100)} %; "
            f"deflection prediction error max {fmt(s.get('prediction_error_max_mm'), '.3f')} mm "
            "(chapter: < 0.04 mm)"
        )
    if "gravity_residual_max_N" in s:
        lines.append(
            f"- Gravity: tool mass {fmt(s.get('tool_mass_identified_kg'), '.3f')} kg (true "
            f"{fmt(s.get('tool_mass_true_kg'), '.3f')}); residual max "
            f"{fmt(s['gravity_residual_max_N'], '.2f')} N"
        )
    if "error_max_uncompensated_um" in s:
        lines.append(
            f"- Block milling: max error {fmt(s['error_max_uncompensated_um'], '.0f')} um -> "
            f"{fmt(s.get('error_max_compensated_online_um'), '.0f')} online, "
            f"{fmt(s.get('error_max_compensated_linear_um'), '.0f')} offline "
            "(chapter: 400 -> < 100 um)"
        )
    if "face_error_max_uncompensated_um" in s:
        lines.append(
            f"- Face milling: max {fmt(s['face_error_max_uncompensated_um'])} -> "
            f"{fmt(s.get('face_error_max_compensated_um'))} um (Lund: 273.9 -> 51.4)"
        )
    if "ilc_arm_error_per_iteration" in s:
        arm = ", ".join(fmt(e, ".0f") for e in s["ilc_arm_error_per_iteration"])
        lines.append(f"- ILC arm-side mean error per iteration: {arm} um (paper: about -85 %)")
    if outcome.settings is None:
        lines += ["", "*No settings yet: the identify study (or all) makes them.*"]
    return "\n".join(lines)
