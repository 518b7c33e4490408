"""Compensation studies: stiffness identification, gravity compensation, milling with deflection
compensation and ILC (a job); the last study's summary, plots and compensation settings."""

from __future__ import annotations

from pathlib import Path
from typing import Any

from fastapi import APIRouter, Response, status
from pydantic import BaseModel, ConfigDict, Field, model_validator

from app.api.routes import ERRORS, JSON_FILE, PNG, StudiesDep, download, relative_folder
from app.api.schemas import JobCreated
from app.studies import SEED_MAX, CompensationOutcome, CompensationStudy
from robomach_core.errors import InvalidInputError
from robomach_core.stiffness import (
    COMPENSATIONS,
    Compensation,
    OfflineModel,
    StudyOptions,
    read_compensation,
)

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
    mode: Compensation = Field(
        StudyOptions.mode,
        description="compensation written to the settings: off, offline (targets corrected "
        "before the run) or online (corrected from the measured force). The old spellings "
        "offline_linear and offline_nonlinear are read as offline with that offline_model",
    )
    offline_model: OfflineModel | None = Field(
        None,
        description="how offline compensation corrects the targets: linear (t0 - C W) or "
        "nonlinear (the compliance paper's eq. 32); default linear, or the old spelling's",
    )

    @model_validator(mode="before")
    @classmethod
    def _old_spellings(cls, data: Any) -> Any:
        """``mode`` in an old spelling (``stiffness.modes.read_compensation``'s rule): offline
        with its model; a model given beside it that contradicts it is refused (422)."""
        if isinstance(data, dict) and isinstance(data.get("mode"), str):
            mode = data["mode"]
            if mode not in COMPENSATIONS:
                try:
                    compensation, model = read_compensation(
                        mode, data.get("offline_model"), name="mode"
                    )
                except InvalidInputError as exc:
                    raise ValueError(str(exc)) from None
                data = {**data, "mode": compensation, "offline_model": model}
        return data


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
        body.study,
        quick=body.quick,
        seed=body.seed,
        mode=body.mode,
        offline_model=body.offline_model,
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
