"""Exports: the program in every registered language, CSV tables and settings as downloads;
named saved exports.

``GET /api/export/program/{language}`` serves every language of
``robomach_core.export.languages``; its path parameter is an enum of the languages registered
when the app is created, so the router is built then: ``router`` is made by the module's
``__getattr__`` (``make_router``) each time ``create_app`` includes it, and a language
registered before that shows in the route and the OpenAPI schema. ``/export/rapid`` and
``/export/urscript`` stay as aliases of the program route.
"""

from __future__ import annotations

import enum
import io
import zipfile
from typing import Annotated, Any

from fastapi import APIRouter, Query, Response, status

import robomach_core.export.languages as registry
from app.api.routes import ERRORS, SessionDep, SettingsDep, download
from app.api.schemas import ExportCreate, ExportPublic, ProgramLanguagePublic
from app.session import Session, programs
from robomach_core.export.rapid import rapid_identifier

PROGRAM_ANSWERS: dict[int | str, dict[str, Any]] = {
    200: {
        "content": {"text/plain": {}, "application/zip": {}},
        "description": "the program file, or a zip of the program's files (KRL's .src and "
        ".dat) when it has several and no ``file`` is named",
    }
}
ModuleName = Annotated[
    str,
    Query(
        min_length=1, max_length=64, description="RAPID's MODULE name (other languages: the header)"
    ),  # fmt: skip
]


def program_download(
    session: Session,
    language: str,
    *,
    force_control: bool = False,
    module_name: str = "LearnedPath",
    file: str | None = None,
) -> Response:
    """One program file, or a zip of all of a program's files (the route and its aliases)."""
    from robomach_core.errors import InvalidInputError

    lang = registry.language(language)
    files = session.programs.program_texts(
        lang.name, force_control=force_control, module_name=rapid_identifier(module_name)
    )
    if file is not None:
        if file not in files:
            raise InvalidInputError(
                f"{lang.title} programs have the files {', '.join(files)}, not {file!r}"
            )
        return download(files[file], file, lang.media_type)
    if len(files) == 1:
        name, text = next(iter(files.items()))
        return download(text, name, lang.media_type)
    buffer = io.BytesIO()
    with zipfile.ZipFile(buffer, "w", zipfile.ZIP_DEFLATED) as archive:
        for name, text in files.items():
            archive.writestr(name, text)
    stem = "program_fc" if force_control else "program"
    return download(buffer.getvalue(), f"{stem}_{lang.name}.zip")


def cad_only_download(session: Session, language: str, *, file: str | None = None) -> Response:
    """The CAD-only program's file, or a zip of its files (KRL's .src and .dat)."""
    from robomach_core.errors import InvalidInputError

    lang = registry.language(language)
    files = session.programs.cad_only_program_texts(lang.name)
    if file is not None:
        if file not in files:
            raise InvalidInputError(
                f"{lang.title} programs have the files {', '.join(files)}, not {file!r}"
            )
        return download(files[file], f"cad_only_{file}", lang.media_type)
    if len(files) == 1:
        name, text = next(iter(files.items()))
        return download(text, f"cad_only_{name}", lang.media_type)
    buffer = io.BytesIO()
    with zipfile.ZipFile(buffer, "w", zipfile.ZIP_DEFLATED) as archive:
        for name, text in files.items():
            archive.writestr(name, text)
    return download(buffer.getvalue(), f"cad_only_{lang.name}.zip")


def language_public(lang: registry.ProgramLanguage, offered: bool) -> ProgramLanguagePublic:
    """The schema of one registered language."""
    return ProgramLanguagePublic(
        name=lang.name,
        title=lang.title,
        files=list(lang.file_names()),
        force_control_files=list(lang.file_names(force_control=True))
        if lang.force_control
        else None,
        families=list(lang.families),
        offered=offered,
    )


def make_router() -> APIRouter:
    """The export router, its program route's language enum from the registry as it is now."""
    router = APIRouter(prefix="/api", tags=["export"], responses=ERRORS)
    # The members are the registry's at runtime; mypy only reads literal member lists.
    Language = enum.Enum("Language", {n: n for n in registry.language_names()}, type=str)  # type: ignore[misc]

    @router.get("/export/languages")
    def list_languages(session: SessionDep) -> list[ProgramLanguagePublic]:
        """Every program language, and whether the cell's arm is offered it (its controller
        runs it): the menus of the workbench and the pendant."""
        offered = set(session.programs.program_languages())
        return [language_public(lang, lang.name in offered) for lang in registry.languages()]

    def export_program(
        language: str,
        session: SessionDep,
        force_control: Annotated[
            bool, Query(description="the force-controlled variant, where the language has one")
        ] = False,
        module_name: ModuleName = "LearnedPath",
        file: Annotated[
            str | None,
            Query(max_length=64, description="one of the program's files (default: all)"),
        ] = None,
    ) -> Response:
        """The post-processed program in one language (GET /api/export/languages lists them):
        the arm's controller must run it (else 422). RAPID carries the FC SpeedChange block
        with a CMRR controller; in the offline compensation modes the targets are corrected."""
        return program_download(
            session,
            getattr(language, "value", language),
            force_control=force_control,
            module_name=module_name,
            file=file,
        )

    # The path parameter's type is the enum built above: set it on the function itself (this
    # module's annotations are strings, resolved in its globals, where no ``Language`` is).
    export_program.__annotations__["language"] = Language
    router.get("/export/program/{language}", response_class=Response, responses=PROGRAM_ANSWERS)(
        export_program
    )

    def export_cad_only(
        language: str,
        session: SessionDep,
        file: Annotated[
            str | None,
            Query(max_length=64, description="one of the program's files (default: all)"),
        ] = None,
    ) -> Response:
        """The CAD-only program in one language the arm's controller runs: what a CAD/CAM tool
        would make from the mesh alone (its wall offset by the tool radius, reduced with the
        same tolerance; robomach_core.scoring.cad_program), straight moves at the learned feeds, its
        header saying how far it and the learned program are from the (real) wall. The files
        are named ``cad_only_<file>``. 409 before post-processing or when the learned path
        follows no wall of the mesh."""
        return cad_only_download(session, getattr(language, "value", language), file=file)

    export_cad_only.__annotations__["language"] = Language
    router.get("/export/cad-only/{language}", response_class=Response, responses=PROGRAM_ANSWERS)(
        export_cad_only
    )

    @router.get(
        "/export/rapid", response_class=Response, responses={200: {"content": {"text/plain": {}}}}
    )
    def export_rapid(
        session: SessionDep,
        module_name: ModuleName = "LearnedPath",
        force_control: Annotated[
            bool, Query(description="the Force Control variant (FCPressL at the learning force)")
        ] = False,
    ) -> Response:
        """The ABB RAPID module (alias of GET /api/export/program/rapid; text/plain)."""
        name = rapid_identifier(module_name)
        return download(
            session.programs.rapid_module(module_name=name, force_control=force_control),
            f"{name}.mod",
        )

    @router.get("/export/samples.csv", response_class=Response)
    def export_samples(session: SessionDep) -> Response:
        """Every recorded 4 ms sample (mm, N, degrees) with the force filter's verdict."""
        return download(programs.samples_csv(session.project()), "samples.csv")

    @router.get("/export/targets.csv", response_class=Response)
    def export_targets(session: SessionDep) -> Response:
        """The post-processed targets (mm, degrees, mm/s)."""
        return download(session.programs.targets_csv(), "targets.csv")

    @router.get("/export/settings.json", response_class=Response)
    def export_settings(session: SessionDep) -> Response:
        """Cell, compliance, path-learning and post-processing settings (mm, N, s)."""
        return download(session.programs.settings_json(), "settings.json")

    @router.post("/exports", status_code=status.HTTP_201_CREATED)
    def save_export(body: ExportCreate, session: SessionDep, settings: SettingsDep) -> ExportPublic:
        """Save every export file under a name, in the project and in the data folder
        (``exports/<project id>/<name>/``); the same name replaces them."""
        return ExportPublic.from_info(session.programs.save(body.name), session.data_dir)

    @router.get("/exports")
    def list_exports(session: SessionDep) -> list[ExportPublic]:
        """The open project's saved exports, newest first."""
        return [ExportPublic.from_info(e, session.data_dir) for e in session.programs.saved()]

    @router.get("/exports/{name}/{filename}", response_class=Response)
    def get_export_file(name: str, filename: str, session: SessionDep) -> Response:
        """One file of a saved export."""
        return download(session.programs.saved_file(name, filename), filename)

    return router


def __getattr__(name: str) -> APIRouter:
    """``router``: a fresh ``make_router()`` for each app (see the module docstring)."""
    if name == "router":
        return make_router()
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")
