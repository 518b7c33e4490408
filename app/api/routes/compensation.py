"""Compensation studies: stiffness identification, gravity compensation, milling with deflection
compensation and ILC (a job); the last study's summary, plots and compensation settings."""

from __future__ import annotations

from pathlib import Path
from typing import Any

from fastapi import APIRouter, Response, status
from pydantic import BaseModel, ConfigDict, Field

from app.api.routes import ERRORS, JSON_FILE, PNG, StudiesDep, download, relative_folder
from app.api.schemas import JobCreated
from app.studies import SEED_MAX, CompensationOutcome, CompensationStudy
from robomach_core.stiffness.settings import CompensationSetting

router = APIRouter(prefix="/api/compensation", tags=["compensation"], responses=ERRORS)


# --- schemas ---------------------------------------------------------------------------------


class CompensationStudyCreate(BaseModel):
    """A compensation study to run (unknown fields are refused)."""

    model_config = ConfigDict(extra="forbid")

    study: CompensationStudy = Field(
        "all",
        description="identify (stiffness from CMM measurements), gravity (F/T sensor), milling "
        "(with and without compensation), ilc (iterative learning control) or all",
    )
    quick: bool = Field(False, description="shorter cuts and fewer poses: a preview in seconds")
    seed: int = Field(0, ge=0, le=SEED_MAX, description="seed of every random element")
    mode: CompensationSetting = Field(
        "online", description="compensation mode written to the settings"
    )


class CompensationStudyPublic(BaseModel):
    """The last compensation study of the open project."""

    study: str
    quick: bool
    seed: int
    finished_s: float = Field(description="Unix time the study ended")
    summary: dict[str, Any] = Field(
        description="compensation_summary.json: e.g. stiffness_rel_error_max, "
        "prediction_error_max_mm, error_max_uncompensated_um, ilc_arm_error_per_iteration "
        "(units in the key names), and the papers' figures under paper_references"
    )
    plots: list[str] = Field(description="plot names, at .../studies/last/plots/{name}.png")
    settings_available: bool = Field(
        description="compensation settings exist (an identify or all study has run)"
    )
    folder: str | None = Field(
        description="where the study's CSV and PNG files are, relative to the data folder"
    )

    @classmethod
    def from_outcome(cls, o: CompensationOutcome, data_dir: Path | None) -> CompensationStudyPublic:
        return cls(
            study=o.study,
            quick=o.quick,
            seed=o.seed,
            finished_s=o.finished_s,
            summary=o.summary,
            plots=sorted(o.plots),
            settings_available=o.settings is not None,
            folder=relative_folder(o.folder, data_dir),
        )


# --- routes ----------------------------------------------------------------------------------


@router.post(
    "/studies",
    status_code=status.HTTP_202_ACCEPTED,
    responses={429: {"description": "too many studies queued or running"}},
)
def start_study(body: CompensationStudyCreate, studies: StudiesDep) -> JobCreated:
    """Job: run the study. Follow it at /api/jobs/{job_id}; when done it is the last study and
    is saved to the project. 429 when two studies are already queued or running."""
    job_id = studies.start_compensation(
        body.study, quick=body.quick, seed=body.seed, mode=body.mode
    )
    return JobCreated(job_id=job_id)


@router.get("/studies/last")
def get_last_study(studies: StudiesDep) -> CompensationStudyPublic:
    """The open project's last compensation study: its figures next to the papers'."""
    return CompensationStudyPublic.from_outcome(
        studies.require_compensation(), studies.session.data_dir
    )


@router.get("/studies/last/plots")
def list_plots(studies: StudiesDep) -> list[str]:
    """The names of the last study's plots."""
    return sorted(studies.require_compensation().plots)


@router.get("/studies/last/plots/{name}.png", response_class=Response, responses=PNG)
def get_plot(name: str, studies: StudiesDep) -> Response:
    """One plot of the last study (PNG)."""
    return Response(studies.compensation_plot(name), media_type="image/png")


@router.get("/settings", response_class=Response, responses=JSON_FILE)
def get_settings(studies: StudiesDep) -> Response:
    """compensation_settings.json as a download: the identified joint stiffness, the tool's
    gravity parameters and the compensation mode (from the last identify or all study)."""
    return download(studies.compensation_settings_json(), "compensation_settings.json")
