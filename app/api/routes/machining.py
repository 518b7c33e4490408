"""The machining run of the project's program: settings, run and comparison jobs, the result
and its plots, the table, the choice the exports carry, and the stock (issue 8)."""

from __future__ import annotations

from typing import Annotated, Any, Literal

from fastapi import APIRouter, HTTPException, UploadFile, status
from pydantic import BaseModel, ConfigDict, Field
from starlette.concurrency import run_in_threadpool

from app.api.routes import ERRORS, MachiningDep
from app.api.routes.cmrr import within
from app.api.schemas import JobCreated
from app.session.machining import MAX_STOCK_BYTES, PLOT_POINTS, markdown_table
from robomach_core.limits import (
    MACHINING_DEPTH_EXPONENT,
    MACHINING_FEED_EXPONENT,
    MACHINING_FORCE_LIMIT_N,
    MACHINING_PROCESS_GAIN_N,
    MACHINING_VARIATIONS,
)
from robomach_core.machining import MACHINING_CONTROLLERS, STAGE_PLANS
from robomach_core.machining.choice import OPTION_NAMES
from robomach_core.machining.stock import MAX_ALLOWANCE_M, MAX_PROFILE_POINTS, MAX_PROFILE_S_MM
from robomach_core.project import STOCK_SOURCES, StageStatus
from robomach_core.stiffness import Compensation

router = APIRouter(prefix="/api/machining", tags=["machining"], responses=ERRORS)

# The choices of the core (``robomach_core.choices``), never typed again here.
Controller = Literal[MACHINING_CONTROLLERS]  # type: ignore[valid-type]
StockSource = Literal[STOCK_SOURCES]  # type: ignore[valid-type]
Stages = Literal[STAGE_PLANS]  # type: ignore[valid-type]
CellOption = Literal[OPTION_NAMES]  # type: ignore[valid-type]
UPLOAD_CHUNK_BYTES = 1024 * 1024


class MachiningSettingsPublic(BaseModel):
    """The project's machining settings and its chosen configuration."""

    process_gain_N: float = Field(description="K of F = K d^alpha f^beta (d mm, f mm/s)")
    depth_exponent: float = Field(description="alpha")
    feed_exponent: float = Field(description="beta")
    force_limit_N: float = Field(description="the force the cut must not exceed")
    reference_force_N: float = Field(description="Fr the CMRR controllers hold (0.7 x limit)")
    controller: Controller = Field(description="the chosen feed control")
    compensation: Compensation = Field(description="the chosen deflection compensation")
    stages: Stages = Field(
        description="under offline compensation, how fuzzy and two-stage pick their stage: "
        "online (switching in the cell by the force) or planned (the program's speeds, no feed "
        "control in the cell; docs/machining.md)"
    )
    stock_source: StockSource
    stock_profile_mm: list[list[float]] | None = Field(description="(s_mm, allowance_mm) pairs")
    stock_mesh: str | None = Field(description="file name of the uploaded stock mesh")
    status: StageStatus = Field(description="of the machining result")
    cell_options: list[CellOption] = Field(
        description="the cell's controller options: only configurations it can run are chosen"
    )
    cell_options_default: bool = Field(
        description="the options are the defaults of the arm's program language"
    )
    variations: int = Field(description="stocks drawn from the part's variation (0: one stock)")
    choice_reason: str | None = Field(description="why the rule picked its configuration")
    stale_settings: dict[str, str] = Field(
        description="settings identified on another arm, re-derived for this one at export"
    )
    program_needs: str | None = Field(
        description="what the chosen configuration needs from the cell (the program header's line)"
    )


class MachiningSettingsUpdate(BaseModel):
    """Settings to change (omitted ones stay; unknown fields are refused)."""

    model_config = ConfigDict(extra="forbid")

    process_gain_N: float | None = within(MACHINING_PROCESS_GAIN_N, "process gain K [N]")
    depth_exponent: float | None = within(MACHINING_DEPTH_EXPONENT, "depth exponent alpha")
    feed_exponent: float | None = within(MACHINING_FEED_EXPONENT, "feed exponent beta")
    force_limit_N: float | None = within(MACHINING_FORCE_LIMIT_N, "force limit [N]")
    controller: Controller | None = None
    compensation: Compensation | None = None
    stages: Stages | None = Field(
        None, description="online or planned (a change dates the result: run it again)"
    )
    stock_source: StockSource | None = Field(
        None, description="builtin, or profile / mesh once given (PUT stock/profile, POST stock)"
    )
    cell_options: list[CellOption] | None = Field(
        None, max_length=3, description="the cell's controller options (an empty list: none)"
    )
    cell_options_default: bool | None = Field(
        None, description="true: back to the defaults of the arm's program language"
    )
    variations: int | None = Field(
        None,
        ge=MACHINING_VARIATIONS.min,
        le=MACHINING_VARIATIONS.max,
        description="stocks drawn from the part's variation per configuration (0: one stock)",
    )


class MachiningChoice(BaseModel):
    """The configuration the exported program carries."""

    model_config = ConfigDict(extra="forbid")

    controller: Controller
    compensation: Compensation


class StockProfile(BaseModel):
    """An allowance profile along the program's path."""

    model_config = ConfigDict(extra="forbid")

    profile_mm: list[
        tuple[
            Annotated[float, Field(ge=0.0, le=MAX_PROFILE_S_MM, allow_inf_nan=False)],
            Annotated[float, Field(ge=0.0, le=MAX_ALLOWANCE_M * 1e3, allow_inf_nan=False)],
        ]
    ] = Field(
        min_length=1,
        max_length=MAX_PROFILE_POINTS,
        description="(s_mm, allowance_mm) pairs, s increasing along the path, allowance 0-20 mm",
    )


class MachiningResultPublic(BaseModel):
    """The last machining result: one summary row per run, the choice, the plotted trace."""

    status: StageStatus
    stale_reason: str | None
    runs: list[dict[str, Any]] = Field(
        description="figures per run, units in the keys; ``runnable`` false (and ``needs``) "
        "where the cell lacks an option; p50 / p95 figures with variations"
    )
    chosen_by_rule: dict[str, str] | None = Field(
        description="the configuration the rule picks (none when the cell can run nothing "
        "that completed)"
    )
    choice_rule: str
    choice_reason: str = Field(description="why the rule picked it, in words")
    notes: list[str] = Field(
        description="the sentences under the table: rows whose feed is a stage schedule, what "
        "the other stage plan cuts, what the cell lacks"
    )
    cell_options: list[str] = Field(description="the cell options the rows were marked for")
    variation: dict[str, Any] | None = Field(description="the variation sweep, or null")
    trace: dict[str, Any] | None = Field(
        description="the chosen (or first) run decimated along the path: mean, min and max of "
        "force and feed per bucket, reference and limit, and the finished-wall error"
    )


class ComparisonPublic(BaseModel):
    """The side-by-side table of the last result."""

    status: StageStatus
    rows: list[dict[str, Any]]
    table_text: str
    table_markdown: str


def _settings(service: MachiningDep) -> MachiningSettingsPublic:
    return MachiningSettingsPublic(**service.settings_document(), status=service.status())


@router.get("/settings")
def get_settings(service: MachiningDep) -> MachiningSettingsPublic:
    """The machining settings, the stock source and the chosen configuration."""
    return _settings(service)


@router.put("/settings")
def put_settings(body: MachiningSettingsUpdate, service: MachiningDep) -> MachiningSettingsPublic:
    """Change the process, force limit, controller, compensation or stock source. Process and
    limit changes make the result stale; controller and compensation are the choice."""
    service.set_settings(**body.model_dump(exclude_none=True))
    return _settings(service)


@router.put("/choice")
def put_choice(body: MachiningChoice, service: MachiningDep) -> MachiningSettingsPublic:
    """Save the configuration the exports carry: the FC SpeedChange block for a CMRR
    controller, the corrected targets for offline compensation, and both in settings.json."""
    service.choose(body.controller, body.compensation)
    return _settings(service)


@router.put("/stock/profile")
def put_stock_profile(body: StockProfile, service: MachiningDep) -> MachiningSettingsPublic:
    """Use an allowance profile as the stock."""
    service.set_stock_profile(body.profile_mm)
    return _settings(service)


@router.post(
    "/stock",
    max_body_size=MAX_STOCK_BYTES + 1024 * 1024,
    responses={413: {"description": "the file is larger than the upload limit"}},
)
async def upload_stock(file: UploadFile, service: MachiningDep) -> MachiningSettingsPublic:
    """Upload a stock mesh (STL, OBJ or PLY in mm, in the workpiece's frame; multipart field
    ``file``): the part before machining, paired with the nominal one."""
    chunks, size = [], 0
    while chunk := await file.read(UPLOAD_CHUNK_BYTES):
        size += len(chunk)
        if size > MAX_STOCK_BYTES:
            raise HTTPException(
                status.HTTP_413_REQUEST_ENTITY_TOO_LARGE,
                f"{file.filename}: the upload exceeds the {MAX_STOCK_BYTES / 1e6:g} MB limit",
            )
        chunks.append(chunk)
    data = b"".join(chunks)
    if not data:
        raise HTTPException(status.HTTP_422_UNPROCESSABLE_ENTITY, "the uploaded file is empty")
    await run_in_threadpool(service.upload_stock, data, file.filename or "stock.stl")
    return _settings(service)


@router.post("/run", status_code=status.HTTP_202_ACCEPTED)
def start_run(service: MachiningDep) -> JobCreated:
    """Job: cut the program with the chosen configuration. Follow and cancel it at
    /api/jobs/{job_id}; 409 without a current post-processed program."""
    return JobCreated(job_id=service.start("run"))


@router.post("/compare", status_code=status.HTTP_202_ACCEPTED)
def start_compare(service: MachiningDep) -> JobCreated:
    """Job: the matrix, the greatest safe constant feed and each CMRR controller with
    compensation off, offline and online (18 runs), on the stock and ``variations`` more
    stocks drawn from the part's variation, on every local core (or the Dask cluster the
    server was started with, ``ROBOMACH_CLUSTER``; a request cannot point the server at
    another address)."""
    return JobCreated(job_id=service.start("compare"))


@router.get("/result")
def get_result(service: MachiningDep, points: int = PLOT_POINTS) -> MachiningResultPublic:
    """The last result (409 without one); ``status`` says whether it is still current. The
    trace has at most ``points`` buckets, and at most 2000: the server keeps each run's trace
    as 2000 buckets (mean, and min/max of force and feed), not every control period."""
    result = service.require_result()
    summary = result.summary()
    trace = None
    if result.runs:
        trace = service.plot_data(max_points=max(10, min(points, 20_000)))
    return MachiningResultPublic(
        status=service.status(),
        stale_reason=service.session.project().stale_reasons().get("machining"),
        runs=summary["runs"],
        chosen_by_rule=summary["chosen"],
        choice_rule=summary["choice_rule"],
        choice_reason=summary["choice_reason"],
        notes=summary["notes"],
        cell_options=summary["cell_options"],
        variation=summary["variation"],
        trace=trace,
    )


@router.get("/comparison")
def get_comparison(service: MachiningDep) -> ComparisonPublic:
    """The side-by-side table of the last result (text and markdown)."""
    result = service.require_result()
    return ComparisonPublic(
        status=service.status(),
        rows=list(result.rows),
        table_text=result.table_text,
        table_markdown=markdown_table(result.table_text),
    )
