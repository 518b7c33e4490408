"""Export panel: the RAPID program's preview and downloads of every export file."""

from __future__ import annotations

import viser

from app.session import ConflictError
from robomach_core.errors import RobomachError
from robomach_core.project import StaleResultError

from .feedback import guarded
from .postprocess import OUT_OF_DATE

PREVIEW_LINES = 60


FILES = ("program.mod", "program_fc.mod", "samples.csv", "targets.csv", "settings.json")


class ExportPanel:
    """Preview the RAPID module and download program.mod, the FC variant, the CSVs and the
    settings JSON (each straight from the session, so it always matches the last result)."""

    def __init__(self, server: viser.ViserServer, session) -> None:
        self.session = session
        with server.gui.add_folder("Export", expand_by_default=False):
            self.process = server.gui.add_markdown("")
            self.controller = server.gui.add_text(
                "CMRR controller",
                "",
                hint="After a CMRR study that compared controllers: the one to use",
            )
            self.adopt = server.gui.add_button_group("Studies' settings", ("Use", "Remove"))
            self.download = server.gui.add_button_group("Download", FILES)
            self.preview = server.gui.add_markdown("")
        self.adopt.on_click(guarded("Export", lambda e: self.use_studies(e.target.value == "Use")))
        self.download.on_click(
            guarded(
                "Export",
                lambda e: e.client.send_file_download(
                    e.target.value,
                    self.file_text(e.target.value).encode("utf-8"),
                    save_immediately=True,
                ),
            )
        )
        self.refresh()

    def file_text(self, name: str) -> str:
        """The text of one export file."""
        if name == "program.mod":
            return self.session.rapid_module()
        if name == "program_fc.mod":
            return self.session.rapid_module(module_name="LearnedPathFC", force_control=True)
        if name == "samples.csv":
            return self.session.samples_csv()
        if name == "targets.csv":
            return self.session.targets_csv()
        return self.session.settings_json()

    def use_studies(self, use: bool) -> None:
        """Carry the last CMRR study's controller and the identified compensation in the
        program (those that have run), or remove both."""
        if not use:
            self.session.set_process_settings(cmrr=None, compensation=None)
            return
        from app.session.process_settings import settings_from_studies
        from app.studies import studies_for

        studies = studies_for(self.session)
        has_cmrr = studies.cmrr_result() is not None
        identified = studies.compensation_result()
        has_comp = identified is not None and identified.settings is not None
        if not (has_cmrr or has_comp):
            raise ConflictError("no CMRR study and no identified compensation in this project")
        cmrr, compensation = settings_from_studies(
            studies,
            controller=self.controller.value.strip() or None,
            cmrr=has_cmrr,
            compensation=has_comp,
        )
        self.session.set_process_settings(cmrr=cmrr, compensation=compensation)

    def _process_text(self) -> str:
        project = self.session.project()
        cmrr = "none" if project.cmrr is None else project.cmrr.controller.kind
        comp = "none" if project.compensation is None else project.compensation.mode
        return f"Program carries: CMRR **{cmrr}**, deflection compensation **{comp}**"

    def refresh(self) -> None:
        """Show the process settings and the first lines of the RAPID module (or why there is
        none yet)."""
        self.process.content = self._process_text()
        try:
            text = self.session.rapid_module()
        except StaleResultError as exc:
            self.preview.content = f"**{OUT_OF_DATE}**: {exc}"
            return
        except RobomachError as exc:
            self.preview.content = f"*{exc}*"
            return
        lines = text.splitlines()
        shown = "\n".join(lines[:PREVIEW_LINES])
        more = (
            f"\n\n*... {len(lines) - PREVIEW_LINES} more lines in program.mod*"
            if len(lines) > PREVIEW_LINES
            else ""
        )
        self.preview.content = f"**RAPID preview**\n\n```\n{shown}\n```{more}"
