"""CMRR studies: feed control at a force reference simulated on the papers' cuts (a job), the
last study's summary, plot and controller settings, and the scenario and controller names."""

from __future__ import annotations

import functools
from pathlib import Path
from typing import Annotated, Any, Literal

from fastapi import APIRouter, Query, Response, status
from pydantic import BaseModel, ConfigDict, Field, ValidationInfo, field_validator

from app.api.routes import ERRORS, JSON_FILE, PNG, StudiesDep, download, relative_folder
from app.api.schemas import JobCreated
from app.session import NotFoundError
from app.studies import (
    CMRR_CONTROLLER_CHOICES,
    SEED_MAX,
    CmrrOutcome,
)
from robomach_core.cmrr import CONTROLLER_NAMES, SCENARIO_NAMES
from robomach_core.cmrr.scenarios import ScenarioName
from robomach_core.limits import CMRR_COMMAND_SPEED_MM_S, CMRR_REFERENCE_FORCE_N, Range

router = APIRouter(prefix="/api/cmrr", tags=["cmrr"], responses=ERRORS)

ControllerChoice = Literal[(*CONTROLLER_NAMES, "all", "default")]  # type: ignore[valid-type]
RANGES = {
    "reference_force_N": CMRR_REFERENCE_FORCE_N,
    "command_speed_mm_s": CMRR_COMMAND_SPEED_MM_S,
}


def within(rng: Range, description: str) -> Any:
    """A pydantic field bounded by ``rng`` (None: the scenario's value), its range in the
    description and the schema."""
    return Field(
        None,
        ge=rng.min,
        le=rng.max,
        allow_inf_nan=False,
        description=f"{description}, {rng.text()}",
    )


# --- schemas ---------------------------------------------------------------------------------


class CmrrStudyCreate(BaseModel):
    """A CMRR study to run (unknown fields are refused)."""

    model_config = ConfigDict(extra="forbid")

    scenario: ScenarioName = Field(description="the cut to simulate")
    controller: ControllerChoice = Field(
        "default",
        description="feed controller, all to compare them, or default for the scenario's own",
    )
    seed: int = Field(0, ge=0, le=SEED_MAX, description="seed of the sensor noise")
    reference_force_N: float | None = within(
        CMRR_REFERENCE_FORCE_N, "force reference [N]; the scenario's when left out"
    )
    command_speed_mm_s: float | None = within(
        CMRR_COMMAND_SPEED_MM_S,
        "programmed (greatest) feed [mm/s]; the scenario's when left out. A study simulates "
        "at most 3,000,000 control samples (all controllers together), else 422",
    )

    @field_validator("reference_force_N", "command_speed_mm_s", mode="before")
    @classmethod
    def _in_range(cls, value: Any, info: ValidationInfo) -> Any:
        """The message names the whole range (``ge``/``le`` alone name one end)."""
        name = info.field_name
        assert name is not None  # a field validator runs for one of its fields
        rng = RANGES[name]
        if isinstance(value, (int, float)) and not isinstance(value, bool):
            rng.check(value, name)
        return value


class CmrrStudyPublic(BaseModel):
    """The last CMRR study of the open project."""

    scenario: str
    controller: str = Field(description="the controller, or all for a comparison")
    controllers: list[str] = Field(description="the controllers the study ran")
    seed: int
    finished_s: float = Field(description="Unix time the study ended")
    summary: dict[str, Any] = Field(
        description="cmrr_summary.json: peak_force_N, force_rms_error_N, cycle_time_s, stable, "
        "... (with all: one entry per controller under results)"
    )
    plot_url: str | None = Field(description="the figure (PNG), when it is on disk")
    settings_url: str = Field(description="the controller settings (JSON download)")
    folder: str | None = Field(
        description="where cmrr.csv and the other files are, relative to the data folder"
    )

    @classmethod
    def from_outcome(cls, o: CmrrOutcome, data_dir: Path | None) -> CmrrStudyPublic:
        return cls(
            scenario=o.scenario,
            controller=o.controller,
            controllers=o.controllers,
            seed=o.seed,
            finished_s=o.finished_s,
            summary=o.summary,
            plot_url=f"{router.prefix}/studies/last/plot.png" if o.plot_png else None,
            settings_url=f"{router.prefix}/settings",
            folder=relative_folder(o.folder, data_dir),
        )


class CmrrOptionsPublic(BaseModel):
    """What a CMRR study can be asked for."""

    scenarios: list[str]
    controllers: list[str] = Field(description="controller names, and all to compare them")
    default_controllers: dict[str, str] = Field(description="scenario -> the paper's controller")


# --- routes ----------------------------------------------------------------------------------


@router.get("/options")
def get_options() -> CmrrOptionsPublic:
    """The scenario and controller names, and each scenario's own controller."""
    return _options()


@functools.cache
def _options() -> CmrrOptionsPublic:
    from robomach_core.cmrr import build_scenario

    return CmrrOptionsPublic(
        scenarios=list(SCENARIO_NAMES),
        controllers=list(CMRR_CONTROLLER_CHOICES),
        default_controllers={s: build_scenario(s).default_controller for s in SCENARIO_NAMES},
    )


@router.post(
    "/studies",
    status_code=status.HTTP_202_ACCEPTED,
    responses={429: {"description": "too many studies queued or running"}},
)
def start_study(body: CmrrStudyCreate, studies: StudiesDep) -> JobCreated:
    """Job: simulate the cut under the controller (or all of them). Follow it at
    /api/jobs/{job_id}; when done it is the last study and is saved to the project. 422 when
    the study would simulate too many samples, 429 when two studies are already queued or
    running."""
    job_id = studies.start_cmrr(
        body.scenario,
        body.controller,
        seed=body.seed,
        reference_force_N=body.reference_force_N,
        command_speed_mm_s=body.command_speed_mm_s,
    )
    return JobCreated(job_id=job_id)


@router.get("/studies/last")
def get_last_study(studies: StudiesDep) -> CmrrStudyPublic:
    """The open project's last CMRR study: its summary figures (units in the key names)."""
    return CmrrStudyPublic.from_outcome(studies.require_cmrr(), studies.session.data_dir)


@router.get("/studies/last/plot.png", response_class=Response, responses=PNG)
def get_last_plot(studies: StudiesDep) -> Response:
    """The last study's figure: force, feed, speed ratio and the adaptive estimates."""
    png = studies.require_cmrr().plot_png
    if png is None:
        raise NotFoundError("the last CMRR study's plot is no longer on disk; run it again")
    return Response(png, media_type="image/png")


@router.get("/settings", response_class=Response, responses=JSON_FILE)
def get_settings(
    studies: StudiesDep,
    controller: Annotated[
        str | None,
        Query(description="with a comparison (all): only this controller's settings"),
    ] = None,
) -> Response:
    """The last study's controller settings (cmrr_settings.json), as a download: replay them
    with ``robomach cmrr --settings`` or export them with the RAPID program."""
    text = studies.cmrr_settings_json(controller)
    filename = "cmrr_settings.json" if controller is None else f"cmrr_settings_{controller}.json"
    return download(text, filename)
