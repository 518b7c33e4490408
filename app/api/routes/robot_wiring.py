"""The user's own arm (a URDF upload), the URScript export and the guide-point rules check."""

from __future__ import annotations

from typing import Annotated, Literal

from fastapi import APIRouter, HTTPException, Query, Response, UploadFile, status
from starlette.concurrency import run_in_threadpool

from app.api.routes import ERRORS, SessionDep
from app.api.routes.cell import UPLOAD_CHUNK_BYTES, _public
from app.api.routes.export import program_download
from app.api.schemas import CellPublic, FindingPublic, GuideCheckPublic
from robomach_core import limits
from robomach_core.learning.settings import PathLearningSettings, WallSideSetting
from robomach_core.robots import ARM_FAMILIES
from robomach_core.robots.custom import MAX_ROBOT_FILE_BYTES

# The controller families an uploaded arm may be given (``robots.builtin.ARM_FAMILIES``).
FamilyChoice = Literal[("auto", *ARM_FAMILIES)]  # type: ignore[valid-type]

router = APIRouter(prefix="/api", tags=["cell"], responses=ERRORS)

# The learning settings the guide-point checks are asked with (both routes below).
LearningForceQuery = Annotated[
    float,
    Query(
        ge=limits.LEARNING_FORCE_N.min,
        le=limits.LEARNING_FORCE_N.max,
        description="contact force [N]",
    ),
]
ClosedQuery = Annotated[bool, Query(description="closed contour")]
WallSideQuery = Annotated[WallSideSetting, Query(description="the wall side to learn with")]


@router.post(
    "/cell/robot",
    max_body_size=MAX_ROBOT_FILE_BYTES + 1024 * 1024,
    responses={413: {"description": "the file is larger than the upload limit"}},
)
async def upload_robot(
    file: UploadFile,
    session: SessionDep,
    family: Annotated[
        FamilyChoice,
        Query(
            description="the arm's controller: auto (a built-in arm's kinematics, e.g. a UR5, "
            "make it that arm; else ABB's), ur, abb or kuka; it decides the program language"
        ),
    ] = "auto",
) -> CellPublic:
    """Upload your own serial 6-axis arm (multipart field ``file``): a ``.urdf``, or a ``.zip``
    holding one URDF and its meshes. It must be a chain of six revolute joints with limits
    (else 422 naming what is wrong). The arm goes home above the part; the guide points are
    cleared like PUT /api/cell."""
    chunks, size = [], 0
    while chunk := await file.read(UPLOAD_CHUNK_BYTES):
        size += len(chunk)
        if size > MAX_ROBOT_FILE_BYTES:
            raise HTTPException(
                status.HTTP_413_REQUEST_ENTITY_TOO_LARGE,
                f"{file.filename}: the upload exceeds the {MAX_ROBOT_FILE_BYTES / 1e6:g} MB limit",
            )
        chunks.append(chunk)
    data = b"".join(chunks)
    if not data:
        raise HTTPException(status.HTTP_422_UNPROCESSABLE_ENTITY, "the uploaded file is empty")
    await run_in_threadpool(
        session.upload_robot, data, file.filename or "robot.urdf", family=family
    )
    return _public(session)


@router.get(
    "/export/urscript", response_class=Response, responses={200: {"content": {"text/plain": {}}}}
)
def export_urscript(
    session: SessionDep,
    force_control: Annotated[
        bool, Query(description="the force variant (force_mode along tool y at the learning force)")
    ] = False,
) -> Response:
    """The program as a URScript ``.script`` (poses in the base frame: m, rotation vectors);
    alias of GET /api/export/program/urscript (UR arms only)."""
    return program_download(session, "urscript", force_control=force_control)


@router.get("/path-learning/warnings")
def guide_point_warnings(
    session: SessionDep,
    force_N: LearningForceQuery = PathLearningSettings.force_N,
    closed: ClosedQuery = True,
    wall_side: WallSideQuery = "auto",
) -> list[str]:
    """What the operator check finds in the guide points (docs/guide_points.md): the wall side
    that cannot be told, heavy contact, a point nearer another wall, on the floor, a leg
    through the part, a wrist turn axis 6 cannot make; POST /api/path-learning returns the same
    with its job."""
    return session.learning.guide_warnings(force_N, closed=closed, wall_side=wall_side)


@router.get("/path-learning/check")
def guide_point_check(
    session: SessionDep,
    force_N: LearningForceQuery = PathLearningSettings.force_N,
    closed: ClosedQuery = True,
    wall_side: WallSideQuery = "auto",
) -> GuideCheckPublic:
    """The check before a run, as every page shows it: one finding per rule with its rule,
    severity and the other points where it holds (refusals first: learning will not start),
    and the wall the run will follow with what decided it (on "auto": a push at the points
    or the part's mesh)."""
    from app.findings import grouped_findings

    found = session.learning.guide_findings(force_N, closed=closed, wall_side=wall_side)
    _, side = session.learning.taught_wall_preview(wall_side, closed=closed)
    return GuideCheckPublic(
        findings=[FindingPublic.from_group(g) for g in grouped_findings(found)], wall_side=side
    )
