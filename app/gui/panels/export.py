"""Export panel: the program in the arm's languages (a preview and downloads), the CSVs and the
settings. The menus come from the language registry (``robomach_core.export.languages``): an
arm is offered only the languages its controller runs, and a registered language shows up
here without a change to this panel."""

from __future__ import annotations

import viser

import robomach_core.export.languages as registry
from app.session import ConflictError, Session, programs
from app.studies import StudyService
from robomach_core.errors import RobomachError
from robomach_core.project import StaleResultError, machining_setup_of

from .feedback import client_of, guarded
from .inputs import set_value
from .postprocess import OUT_OF_DATE

PREVIEW_LINES = 60
TABLE_FILES = ("samples.csv", "targets.csv", "settings.json")
FC_MODULE_NAME = "LearnedPathFC"


def program_file_names(language_names: tuple[str, ...]) -> tuple[str, ...]:
    """The files of the programs in these languages: each one's program, then its
    force-controlled variant where it has one."""
    names: list[str] = []
    for name in language_names:
        lang = registry.language(name)
        names += lang.file_names()
        if lang.force_control:
            names += lang.file_names(force_control=True)
    return tuple(names)


def program_file_names_plain(language_names: tuple[str, ...]) -> tuple[str, ...]:
    """The files of the position-controlled programs in these languages."""
    return tuple(name for lang in language_names for name in registry.language(lang).file_names())


def language_of(filename: str) -> tuple[registry.ProgramLanguage, bool]:
    """The registered language writing ``filename`` and whether it is the force variant."""
    for lang in registry.languages():
        if filename in lang.file_names():
            return lang, False
        if lang.force_control and filename in lang.file_names(force_control=True):
            return lang, True
    raise RobomachError(f"no program language writes {filename!r}")


class ExportPanel:
    """Preview the program in one of the arm's languages and download every program file, the
    CSVs and the settings JSON (each straight from the session, so it always matches the last
    result)."""

    def __init__(self, server: viser.ViserServer, session: Session, studies: StudyService) -> None:
        self.session = session
        self.studies = studies  # the session's StudyService
        languages = session.programs.program_languages()
        with server.gui.add_folder("Export", expand_by_default=False):
            self.process = server.gui.add_markdown("")
            self.controller = server.gui.add_text(
                "CMRR controller",
                "",
                hint="After a CMRR study that compared controllers: the one to use",
            )
            self.adopt = server.gui.add_button_group("Studies' settings", ("Use", "Remove"))
            self.language = server.gui.add_dropdown(
                "Language",
                languages or ("none",),
                hint="The languages the arm's controller runs (the preview below)",
            )
            self.program = server.gui.add_button_group(
                "Program", program_file_names(languages) or ("none",)
            )
            self.cad_only = server.gui.add_button_group(
                "CAD-only program",
                program_file_names_plain(languages) or ("none",),
                hint="What a CAD/CAM tool would make from the mesh alone, in the language "
                "above: the baseline learning is measured against (What learning buys)",
            )
            self.tables = server.gui.add_button_group("Tables", TABLE_FILES)
            self.preview = server.gui.add_markdown("")
        self.adopt.on_click(guarded("Export", lambda e: self.use_studies(e.target.value == "Use")))
        self.language.on_update(guarded("Export", lambda _: self.refresh()))
        self.cad_only.on_click(
            guarded(
                "CAD-only program",
                lambda e: client_of(e).send_file_download(
                    f"cad_only_{e.target.value}",
                    self.cad_only_text(e.target.value).encode("utf-8"),
                    save_immediately=True,
                ),
            )
        )
        for group in (self.program, self.tables):
            group.on_click(
                guarded(
                    "Export",
                    lambda e: client_of(e).send_file_download(
                        e.target.value,
                        self.file_text(e.target.value).encode("utf-8"),
                        save_immediately=True,
                    ),
                )
            )
        self.refresh()

    def file_text(self, name: str) -> str:
        """The text of one export file."""
        if name == "samples.csv":
            return programs.samples_csv(self.session.project())
        if name == "targets.csv":
            return self.session.programs.targets_csv()
        if name == "settings.json":
            return self.session.programs.settings_json()
        lang, force = language_of(name)
        kwargs = {"module_name": FC_MODULE_NAME} if force else {}
        return self.session.programs.program_texts(lang.name, force_control=force, **kwargs)[name]

    def cad_only_text(self, name: str) -> str:
        """One file of the CAD-only program (``programs.cad_only_program_texts``)."""
        lang, _ = language_of(name)
        return self.session.programs.cad_only_program_texts(lang.name)[name]

    def use_studies(self, use: bool) -> None:
        """Carry the last CMRR study's controller and the identified compensation in the
        program (those that have run), or remove both."""
        if not use:
            self.session.programs.set_process_settings(cmrr=None, compensation=None)
            return
        from app.session.process_settings import settings_from_studies

        studies = self.studies
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
        self.session.programs.set_process_settings(cmrr=cmrr, compensation=compensation)

    def _process_text(self) -> str:
        """What the program carries, in the Machining panel's words (its controller and
        compensation names: one name for one thing on every page)."""
        project = self.session.project()
        s = machining_setup_of(project).settings
        comp = project.compensation
        # Nothing chosen: the files carry a constant feed and no compensation (the setup's
        # defaults are what the Machining panel would compare, not what is written).
        controller = "constant" if project.cmrr is None else s.controller
        compensation = "off" if comp is None else s.compensation
        model = ""
        if comp is not None and comp.mode == "offline":
            model = f" ({comp.offline_model} joint-stiffness model)"
        return (
            f"Program carries: feed control **{controller}**, compensation "
            f"**{compensation}**{model} (the Machining panel's choice)"
        )

    def _sync_menus(self) -> tuple[str, ...]:
        """The language and file menus for the cell's arm (it may have changed)."""
        languages = self.session.programs.program_languages()
        options = languages or ("none",)
        if tuple(self.language.options) != options:
            self.language.options = options
        if self.language.value not in options:
            set_value(self.language, options[0])
        files = program_file_names(languages) or ("none",)
        if tuple(self.program.options) != files:
            self.program.options = files
        plain = program_file_names_plain(languages) or ("none",)
        if tuple(self.cad_only.options) != plain:
            self.cad_only.options = plain
        return languages

    def refresh(self) -> None:
        """Show the process settings and the first lines of the program in the chosen language
        (or why there is none yet)."""
        self.process.content = self._process_text()
        if not self._sync_menus():
            self.preview.content = "*This arm's controller runs none of the languages.*"
            return
        lang = registry.language(self.language.value)
        main = lang.file_names()[0]
        try:
            text = self.session.programs.program_texts(lang.name)[main]
        except StaleResultError as exc:
            self.preview.content = f"**{OUT_OF_DATE}**: {exc}"
            return
        except RobomachError as exc:
            self.preview.content = f"*{exc}*"
            return
        lines = text.splitlines()
        shown = "\n".join(lines[:PREVIEW_LINES])
        more = (
            f"\n\n*... {len(lines) - PREVIEW_LINES} more lines in {main}*"
            if len(lines) > PREVIEW_LINES
            else ""
        )
        title = lang.title.split()[-1]  # "RAPID", "URScript", "KRL"
        self.preview.content = f"**{title} preview** ({main})\n\n```\n{shown}\n```{more}"
