"""The open project's programs and tables, read through to the core's writers.

Each function reads one ``Session.view()`` (the project and the cell it runs on, together) and
calls the core's writer the CLI calls too (``project.program_texts``, ``targets_text``,
``settings_document``, ``program_files``), so the workbench and the CLI export the same bytes;
a stale post-processing is refused by the core. Saved exports go to the store and the data
folder (``exports``). ``Programs(session)`` is the session's ``programs``; ``samples_csv``
reads a project alone.
"""

from __future__ import annotations

import json
from typing import TYPE_CHECKING, Any

from robomach_core import project as core
from robomach_core.project import Project

from . import exports
from .records import ConflictError, ExportInfo
from .robot import selection_document

if TYPE_CHECKING:
    from robomach_core.cmrr import CmrrSettings
    from robomach_core.stiffness import CompensationSettings

    from .session import Session


class Programs:
    """The open project's programs, tables and saved exports: the session's ``programs``
    (module docstring)."""

    def __init__(self, session: Session) -> None:
        self._session = session

    def program_languages(self) -> tuple[str, ...]:
        """The languages the cell's arm is offered (``export.languages.languages_for``)."""
        from robomach_core.export.languages import languages_for

        return tuple(lang.name for lang in languages_for(self._session.view().cell.robot))

    def program_texts(
        self,
        language: str,
        *,
        force_control: bool = False,
        module_name: str = core.DEFAULT_MODULE_NAME,
    ) -> dict[str, str]:
        """The project's program in a registered language the arm's controller runs
        (``project.program_texts``): file name -> text."""
        from robomach_core.export.languages import resolve_languages

        view = self._session.view()
        (lang,) = resolve_languages(view.cell.robot, language)
        return core.program_texts(
            view.project,
            view.cell.workpiece,
            view.cell.robot,
            lang.name,
            module_name=module_name,
            force_control=force_control,
        )

    def cad_only_program_texts(self, language: str) -> dict[str, str]:
        """The CAD-only program (the mesh's wall offset by the tool radius: what a CAD/CAM tool
        would make, ``project.cad_only_program_texts``) in a language the arm's controller runs:
        file name -> text. For comparison with the learned program."""
        from robomach_core.export.languages import resolve_languages

        view = self._session.view()
        (lang,) = resolve_languages(view.cell.robot, language)
        return core.cad_only_program_texts(
            view.project, view.cell.workpiece, view.cell.robot, lang.name
        )

    def rapid_module(
        self, *, module_name: str = core.DEFAULT_MODULE_NAME, force_control: bool = False
    ) -> str:
        """The RAPID module of the project (``project._writers.rapid_text``): the FC SpeedChange
        block with a CMRR controller, compensated targets in the offline compensation modes, or
        the FC pressure variant. Refused on an arm whose controller does not run RAPID."""
        files = self.program_texts("rapid", module_name=module_name, force_control=force_control)
        return next(iter(files.values()))

    def targets_csv(self) -> str:
        """The post-processed targets (mm, degrees, mm/s; ``project.targets_text``)."""
        view = self._session.view()
        return core.targets_text(view.project, view.cell.robot)

    def _context(self) -> dict[str, Any]:
        return {
            "project_name": self._session.current_project().name,
            "compliance": selection_document(self._session.robot.selection),
        }

    def settings_json(self) -> str:
        """``project.settings_document`` with the project name and compliance selection."""
        view = self._session.view()
        doc = core.settings_document(view.project, view.cell.workpiece, **self._context())
        return json.dumps(doc, indent=2) + "\n"

    def save(self, name: str) -> ExportInfo:
        """Save ``project.program_files`` (program, samples.csv, targets.csv, settings.json)
        under ``name`` (letters, digits, ``_ . -``; 1-64 characters) in the store and in
        ``<data_dir>/exports/<project id>/<name>/``; the same name replaces the files. A stale
        post-processing is refused."""
        exports.check_export_name(name)
        view = self._session.view()
        files = core.program_files(
            view.project,
            view.cell.workpiece,
            view.cell.robot,
            module_name=exports.rapid_identifier_or(name),
            **self._context(),
        )
        info = exports.save_export(
            self._session.store, self._session.data_dir, view.project_id, name, files
        )
        self._session.notify("exports")
        return info

    def saved(self) -> list[ExportInfo]:
        """The open project's saved exports, newest first."""
        return exports.list_exports(
            self._session.store, self._session.data_dir, self._session.project_id
        )

    def saved_file(self, name: str, filename: str) -> str:
        """The text of one file of a saved export."""
        return exports.export_file(self._session.store, self._session.project_id, name, filename)

    def set_process_settings(
        self,
        *,
        cmrr: CmrrSettings | None = None,
        compensation: CompensationSettings | None = None,
    ) -> Project:
        """Choose the CMRR controller settings (``cmrr.CmrrSettings``) and the compensation
        settings (``stiffness.CompensationSettings``) the exported program carries
        (``project.with_process_settings``; None removes one). Returns the project."""
        change = lambda p: core.with_process_settings(p, cmrr, compensation)  # noqa: E731
        return self._session.commit(change, "post", topics=("postprocess",))


def samples_csv(project: Project) -> str:
    """Every recorded sample with the force filter's verdict (mm, N, degrees); the
    recording is the raw data, so it is given even when it is stale."""
    from robomach_core.export.tables import samples_csv as write_samples

    if project.learned is None:
        raise ConflictError("no recording yet: run path learning first")
    processed, keep = project.processed, None
    if processed is not None and processed.inputs == core.processed_inputs_key(
        project.learned, processed.settings
    ):
        keep = processed.result.keep_mask
    return write_samples(project.learned.recording, keep)
