"""The stages: path learning, post-processing and scoring, and the CAD comparison."""

from __future__ import annotations

from collections.abc import Callable, Sequence
from dataclasses import replace
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np

from ..cell import Cell, CellState, ForceEstimator, GuidePoint
from ..errors import InvalidInputError, RouteRefusedError
from ..learning.route import LearningRoute, plan_route
from ..learning.run import learn_path
from ..learning.settings import PathLearningSettings
from ..part import Workpiece, mesh_query
from ..postprocess import PostprocessResult, PostprocessSettings, Targets, loop_ridge_m, postprocess
from ..scoring import PathScore, score_path
from ._value import (
    CellSettings,
    LearnedPath,
    MissingResultError,
    ProcessedPath,
    Project,
    StaleResultError,
    processed_inputs_key,
    recording_inputs_key,
)

if TYPE_CHECKING:
    from ..learning.checks import GuideWarning, TaughtWallCheck


def learn(
    project: Project,
    cell: Cell,
    state: CellState,
    settings: PathLearningSettings,
    estimator: ForceEstimator,
    *,
    progress: Callable[[float], None] | None = None,
    cancelled: Callable[[], bool] | None = None,
    cad: Workpiece | None = None,
    route: LearningRoute | None = None,
) -> tuple[LearnedPath, CellState]:
    """Path learning through the project's guide points (``learning.learn_path``) on the route
    ``learning.plan_route`` plans, before any motion, with the part as the user sees it
    (``cad``, default the cell's part): the wall side decided once, the height, the checks.

    ``cell`` is the project's cell (possibly seen through a proxy that taps each step); returns
    the learned path and the cell state at the end. ``route``: the route already planned
    (``route_of``, or the one ``guide_check`` read), so that what was checked before the job
    is what runs.

    Raises:
        RouteRefusedError: the points cannot be learned as taught (``WallSideError`` when the
            side is "auto" and neither pushes nor the mesh tell it), before any motion.
    """
    guides = list(project.guide_points)
    if route is None:
        route = route_of(project, settings, cad if cad is not None else cell.workpiece.cad())
    recording, end = learn_path(
        cell, state, route, settings, estimator, progress=progress, cancelled=cancelled
    )
    quats = np.array([g.quaternion_wxyz for g in guides]).reshape(-1, 4)
    return LearnedPath(recording, quats, settings, recording_inputs_key(project)), end


def route_of(project: Project, settings: PathLearningSettings, cad: Workpiece) -> LearningRoute:
    """The route path learning runs through the project's guide points
    (``learning.plan_route``), planned with the part as the user sees it (``cad``).

    Raises:
        RouteRefusedError: the points cannot be learned as taught, with the reason.
    """
    with mesh_query.LOCK:  # the mesh's trees answer one thread at a time
        return plan_route(
            project.guide_points,
            settings,
            workpiece=cad,
            tool_radius_m=project.cell.tool_radius_m,
        )


def process(
    learned: LearnedPath,
    settings: PostprocessSettings,
    workpiece: Workpiece,
    tool_radius_m: float,
    *,
    guides: Sequence[GuidePoint] | None = None,
) -> ProcessedPath:
    """Force filter, deviation-height reduction and speeds (``postprocess.postprocess``), arc
    fitting when asked (``settings.arcs``), then the score against the true tool path when
    the workpiece has a known wall, and against its mesh for every part (``mesh_score``:
    signed, and with ``guides``, whether the program follows the wall they were taught on)."""
    rec = learned.recording
    try:
        result = postprocess(
            rec, learned.guide_quaternions_wxyz, settings, closed=learned.settings.closed
        )
    except InvalidInputError as exc:
        if rec.completed:
            raise
        raise InvalidInputError(f"{exc}: path learning ended early ({rec.stop_reason})") from None
    moves = straight = None
    if settings.arcs and len(result.targets) >= 2:
        from ..postprocess import arc_targets

        straight = len(result.targets)
        tol = settings.arc_tolerance_m or settings.tolerance_m
        arc_tg, moves = arc_targets(result.targets, result.surface_m, result.keep_mask, tol)
        result = replace(result, targets=arc_tg)
    with mesh_query.LOCK:  # the scores query the part's trees, one thread at a time
        tolerance = max(settings.tolerance_m, settings.arc_tolerance_m or 0.0)
        score, mesh, taught = _scores(
            learned, result, moves, workpiece, tool_radius_m, guides, tolerance
        )
    comparison = cad_comparison_of(workpiece, result.targets, tool_radius_m, settings, learned)
    return ProcessedPath(
        settings,
        result,
        len(rec),
        score,
        processed_inputs_key(learned, settings),
        moves=moves,
        mesh_score=mesh,
        straight_targets=straight,
        taught_wall=taught,
        completed=rec.completed,
        cad_comparison=comparison,
        loop_ridge_m=(
            loop_ridge_m(result.targets.position_m, tool_radius_m, _mean_tool_axis(result))
            if learned.settings.closed
            else None
        ),
    )


def _mean_tool_axis(result: PostprocessResult) -> np.ndarray | None:
    """The targets' mean tool axis (None without targets)."""
    if not len(result.targets):
        return None
    from ..transforms import matrices_from_quaternions

    return matrices_from_quaternions(result.targets.quaternion_wxyz)[:, :, 2].mean(axis=0)


def _scores(
    learned: LearnedPath,
    result: PostprocessResult,
    moves: tuple | None,
    workpiece: Workpiece,
    tool_radius_m: float,
    guides: Sequence[GuidePoint] | None,
    tolerance_m: float | None = None,
) -> tuple[PathScore | None, PathScore | None, TaughtWallCheck | None]:
    """The program against the true wall (built-in parts), against the mesh, and whether it
    follows the taught wall (with ``guides``)."""
    rec = learned.recording
    score = mesh = taught = None
    if len(result.targets) >= 2:
        from ..learning.checks import taught_wall_check
        from ..scoring import score_mesh, score_moves

        pos = result.targets.position_m
        if workpiece.wall is not None:
            score = (
                score_path(workpiece, tool_radius_m, pos)
                if moves is None
                else score_moves(workpiece, tool_radius_m, pos, moves)
            )
        mesh = score_mesh(workpiece, tool_radius_m, pos, moves, axis_base=_mean_tool_axis(result))
        if guides is not None and rec.wall_side:
            taught = taught_wall_check(
                workpiece.cad(),  # the mesh as the controller knows it (registered, when so)
                tool_radius_m,
                guides,
                rec.wall_side,
                pos,
                moves,
                closed=learned.settings.closed,
                lifted_m=rec.guide_lift_m,
                travel=rec.guide_travel,
                # the path the program was reduced from, every 10th kept sample (0.2 mm apart
                # at 5 mm/s): a miss it does not share is the tolerance's
                samples_m=result.surface_m[result.keep_mask][::10],
                tolerance_m=tolerance_m,
            )
    return score, mesh, taught


def cad_comparison_of(
    workpiece: Workpiece,
    targets: Targets,
    tool_radius_m: float,
    settings: PostprocessSettings,
    learned: LearnedPath,
) -> Any:
    """The CAD-only program beside the learned one, both against the real wall
    (``cad_program.compare_with_cad``); None for fewer than 2 targets or no wall followed."""
    if len(targets) < 2:
        return None
    from ..scoring import compare_with_cad

    return compare_with_cad(
        workpiece,
        targets.position_m,
        targets.quaternion_wxyz,
        tool_radius_m,
        settings.tolerance_m,
        closed=learned.settings.closed,
    )


def require_learned(project: Project) -> LearnedPath:
    """The recording's learned path, or a clear error saying to run path learning."""
    if project.learned is None:
        raise MissingResultError("no recording yet: run path learning, then post-processing")
    return project.learned


def require_processed(project: Project) -> ProcessedPath:
    """The current post-processing result, or a clear error saying which stage to run."""
    require_learned(project)
    if project.processed is None:
        raise MissingResultError("the recording is not post-processed yet: run post-processing")
    reasons = project.stale_reasons()
    if "postprocess" in reasons:
        raise StaleResultError(f"the post-processed path is out of date: {reasons['postprocess']}")
    return project.processed


def guide_findings(
    project: Project,
    cell: Cell,
    settings: PathLearningSettings,
    *,
    route: LearningRoute | RouteRefusedError | None = None,
) -> tuple[GuideWarning, ...]:
    """The check of the project's guide points before a run (``learning.guide_point_warnings``
    against the mesh the user sees, the arm's reach and the cell's supervision, at the
    project's tolerance): what the workbench shows and ``robomach demo`` prints; a refusal
    raises. ``route``: the route ``route_of`` planned for them with ``settings``, or its
    refusal, when the caller has it (planned here when None)."""
    return guide_check(project, cell, settings, route=route)[0]


def guide_check(
    project: Project,
    cell: Cell,
    settings: PathLearningSettings,
    *,
    route: LearningRoute | RouteRefusedError | None = None,
) -> tuple[tuple[GuideWarning, ...], LearningRoute | None]:
    """``guide_findings`` and the route they read, the one ``route_of`` plans (None when it is
    refused; ``route`` itself when given): ``learn`` takes it as its ``route``, so a run right
    after its check plans the route once (the walk on the mesh is the most of the check's
    time). A refusal is planned once too: the check says it as its first finding."""
    from ..cell import cell_supervisor
    from ..learning.checks import guide_point_warnings

    cad = cell.workpiece.cad()
    if route is None and len(project.guide_points) >= 2:  # fewer: no route, as the check has it
        try:
            route = route_of(project, settings, cad)
        except RouteRefusedError as exc:
            route = exc
    with mesh_query.LOCK:  # the mesh's nearest-point tree answers one thread at a time
        findings = guide_point_warnings(
            project.guide_points,
            settings,
            workpiece=cad,
            tool_radius_m=project.cell.tool_radius_m,
            supervisor=cell_supervisor(cell),
            tolerance_m=project.post_settings.tolerance_m,
            route=route,
        )
    return findings, route if isinstance(route, LearningRoute) else None


# --- the cell and workpiece of a project -----------------------------------------------------


def build_cell(
    settings: CellSettings, mesh: tuple[str, bytes] | None, *, parsed: Workpiece | None = None
) -> Cell:
    """The simulated cell of ``settings``, the one the workbench and ``robomach demo`` run:
    the arm holding the cell's tool at the part its contact meets (``build_cell_workpiece``),
    its sensor seeded by the cell's seed; ``parsed`` is ``mesh`` already read."""
    from ..cell import ROBOT_URDFS, CellConfig

    if settings.robot not in ROBOT_URDFS:  # an uploaded arm is in once registered
        raise InvalidInputError(
            f"unknown robot {settings.robot!r}; choose one of {', '.join(sorted(ROBOT_URDFS))}"
        )
    workpiece = build_cell_workpiece(settings, mesh, parsed=parsed)
    tool = Project(cell=settings).tool()
    return Cell(CellConfig(settings.robot, tool, workpiece, seed=settings.seed))


def wobj_transform(values: Sequence[float]) -> np.ndarray:
    """4x4 work-object frame from (x, y, z [mm]), (x, y, z [mm], rz [deg]) or
    (x, y, z [mm], rx, ry, rz [deg]); three angles are rotations about the fixed base axes x,
    then y, then z (R = Rz Ry Rx, scipy's extrinsic ``"xyz"``)."""
    from scipy.spatial.transform import Rotation

    from ..transforms import make_transform, rotation_about
    from ._file_check import check_wobj

    v = check_wobj(list(values))  # limits.WOBJ_POSITION_MM and WOBJ_ROTATION_DEG
    if len(v) == 6:
        R = Rotation.from_euler("xyz", v[3:], degrees=True).as_matrix()
    else:
        R = rotation_about("z", np.radians(v[3]) if len(v) == 4 else 0.0)
    return make_transform(R, np.array(v[:3]) * 1e-3)


def build_cell_workpiece(
    cell: CellSettings,
    mesh: tuple[str, bytes] | None,
    *,
    max_triangles: int | None = None,
    parsed: Workpiece | None = None,
) -> Workpiece:
    """The part the cell's contact meets: ``build_workpiece``'s, made real by the cell's
    ``part_deviation`` (``real_part.real_workpiece``; its ``cad()`` is the mesh the user sees),
    its CAD placed where the cell's ``registration`` measured it when there is one."""
    from ..part import real_workpiece
    from ..teaching import registered_workpiece

    cad = build_workpiece(cell, mesh, max_triangles=max_triangles, parsed=parsed)
    part = real_workpiece(cad, cell.part_deviation)
    if cell.registration is not None:
        part = registered_workpiece(part, cell.registration.T_base_wobj)
    return part


def build_workpiece(
    cell: CellSettings,
    mesh: tuple[str, bytes] | None,
    *,
    max_triangles: int | None = None,
    parsed: Workpiece | None = None,
) -> Workpiece:
    """The project's workpiece: built-in by name, or its mesh bytes (``parsed``: those bytes
    already read by ``workpiece.mesh_from_bytes``); placed where the cell's robot reaches it
    (``workpiece.default_T_base_wobj``), or at ``wobj_mm_deg``. The one placement of a part:
    the same while the workbench runs, after a reopen and in the CLI."""
    from ..part import MAX_MESH_TRIANGLES, builtin_workpiece, default_T_base_wobj, mesh_from_bytes

    if mesh is not None and not cell.workpiece_builtin:
        filename, data = mesh
        T = default_T_base_wobj(cell.robot)
        workpiece = (
            parsed.placed(T)
            if parsed is not None
            else mesh_from_bytes(
                data,
                Path(filename).suffix.lower(),
                name=Path(filename).stem,
                T_base_wobj=T,
                max_triangles=max_triangles or MAX_MESH_TRIANGLES,
            )
        )
    else:
        workpiece = builtin_workpiece(cell.workpiece, robot=cell.robot)
    if cell.wobj_mm_deg is not None:
        workpiece = workpiece.placed(wobj_transform(cell.wobj_mm_deg))
    return workpiece
