"""Export panel: the RAPID program's preview and downloads of every export file."""

from __future__ import annotations

import viser

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
            self.download = server.gui.add_button_group("Download", FILES)
            self.preview = server.gui.add_markdown("")
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

    def refresh(self) -> None:
        """Show the first lines of the RAPID module (or why there is none yet)."""
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
