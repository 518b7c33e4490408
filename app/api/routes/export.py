"""Exports: the RAPID program, CSV tables and settings as downloads; named saved exports."""

from __future__ import annotations

from typing import Annotated

from fastapi import APIRouter, Query, Response, status

from app.api.routes import ERRORS, SessionDep, SettingsDep
from app.api.schemas import ExportCreate, ExportPublic
from robomach_core.export.rapid import rapid_identifier

router = APIRouter(prefix="/api", tags=["export"], responses=ERRORS)

MEDIA_TYPES = {
    ".mod": "text/plain; charset=utf-8",
    ".csv": "text/csv; charset=utf-8",
    ".json": "application/json",
}


def _download(text: str, filename: str) -> Response:
    suffix = filename[filename.rfind(".") :]
    return Response(
        text,
        media_type=MEDIA_TYPES.get(suffix, "text/plain; charset=utf-8"),
        headers={"Content-Disposition": f'attachment; filename="{filename}"'},
    )


@router.get(
    "/export/rapid", response_class=Response, responses={200: {"content": {"text/plain": {}}}}
)
def export_rapid(
    session: SessionDep,
    module_name: Annotated[str, Query(min_length=1, max_length=64)] = "LearnedPath",
    force_control: Annotated[
        bool, Query(description="the Force Control variant (FCPressL at the learning force)")
    ] = False,
) -> Response:
    """The ABB RAPID module of the post-processed targets (text/plain)."""
    name = rapid_identifier(module_name)
    return _download(
        session.rapid_module(module_name=name, force_control=force_control), f"{name}.mod"
    )


@router.get("/export/samples.csv", response_class=Response)
def export_samples(session: SessionDep) -> Response:
    """Every recorded 4 ms sample (mm, N, degrees) with the force filter's verdict."""
    return _download(session.samples_csv(), "samples.csv")


@router.get("/export/targets.csv", response_class=Response)
def export_targets(session: SessionDep) -> Response:
    """The post-processed targets (mm, degrees, mm/s)."""
    return _download(session.targets_csv(), "targets.csv")


@router.get("/export/settings.json", response_class=Response)
def export_settings(session: SessionDep) -> Response:
    """Cell, compliance, path-learning and post-processing settings (mm, N, s)."""
    return _download(session.settings_json(), "settings.json")


@router.post("/exports", status_code=status.HTTP_201_CREATED)
def save_export(body: ExportCreate, session: SessionDep, settings: SettingsDep) -> ExportPublic:
    """Save every export file under a name, in the project and in the data folder
    (``exports/<project id>/<name>/``); the same name replaces them."""
    return ExportPublic.from_info(session.save_export(body.name), session.data_dir)


@router.get("/exports")
def list_exports(session: SessionDep) -> list[ExportPublic]:
    """The open project's saved exports, newest first."""
    return [ExportPublic.from_info(e, session.data_dir) for e in session.exports()]


@router.get("/exports/{name}/{filename}", response_class=Response)
def get_export_file(name: str, filename: str, session: SessionDep) -> Response:
    """One file of a saved export."""
    return _download(session.export_file(name, filename), filename)
