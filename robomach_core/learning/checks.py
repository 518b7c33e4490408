"""The checks around a run: what the person should know before it, and whether the program is
on the taught wall after it.

PROBLEM   Path learning follows the wall by force from rough guide points (chapter section 3),
          but some things it cannot recover from (refused before any motion), and some it
          recovers from in a way the person should know: a point in heavy contact, a point
          nearer the other wall than the one followed, a point resting on the floor, a leg that
          crosses the part, two points on top of each other, and the first limit the run's
          motion meets (axis 6 wound up, a joint range, the reach, a singularity, a clearance:
          ``motion_check``). After the run, a program must follow the wall the points were
          taught on, on the side the route decided; a side the person set is never overruled.
STRATEGY  Before: the route is planned (``route.plan_route``: the side, the height, the walk on
          the mesh); its refusal is the "refusal" finding, and the findings read the route, so
          every page tells the same story as the run. After: the wall point each guide point
          faces on the route's side (``route.taught_wall_points``) must be touched by the
          program (within ``TAUGHT_WALL_TOLERANCE_M`` across the axis, among the program's
          points at that height), and the program must meet the points in the order taught
          (``walk.met_order``: the wall points come from the route's walk, and a walk round another
          wall, or the other way round, passes its own).
SOLUTION  ``guide_point_warnings(guides, settings, *, workpiece, tool_radius_m, supervisor)``
          -> ``GuideWarning``s (1-based point, rule, severity, one line with the fix);
          ``taught_wall_check(...)`` -> ``TaughtWallCheck``.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from ..cell import GuidePoint, Supervisor
from ..errors import RouteRefusedError, WallSideError
from ..limits import TOLERANCE_MM
from ..part import Workpiece
from ..postprocess import Move, linear_moves, sample_moves
from . import thresholds as th
from .findings import GuideRule, GuideWarning
from .part_walls import PartWalls
from .route import (
    LearningRoute,
    mean_tool_axis,
    plan_route,
    right_of_travel,
    taught_wall_points,
)
from .run import PathLearningSettings
from .walk import met_order


def _point_findings(
    guides: Sequence[GuidePoint],
    settings: PathLearningSettings,
    axis: np.ndarray,
    right: np.ndarray,
) -> list:
    out: list[GuideWarning] = []
    limit = settings.force_limit_N
    set_sign = {"right": 1.0, "left": -1.0}.get(settings.wall_side, 0.0)
    for k, g in enumerate(guides):
        number = k + 1
        force = np.asarray(g.force_N, dtype=float)
        magnitude = float(np.linalg.norm(force))
        across = float(np.linalg.norm(force - axis * float(force @ axis)))
        if magnitude > th.HEAVY_CONTACT_FRACTION * limit:
            out.append(GuideWarning(number, "heavy_contact", (
                f"G{number} was recorded pressing {magnitude:.0f} N into the part (protection "
                f"stops at {limit:.0f} N): back off to a light touch and record it again"
            )))  # fmt: skip
        elif settings.wall_side == "auto" and (
            th.TOUCH_WITHOUT_PUSH_N <= across < th.WALL_FORCE_CLEAR_N
        ):
            out.append(GuideWarning(number, "touching_without_push", (
                f"G{number} touches the wall without a push ({across:.1f} N): a light push "
                f"towards the wall ({th.WALL_FORCE_CLEAR_N:g}-10 N) tells the wall side"
            ), "info"))  # fmt: skip
        pushed_from = -float(force @ right[k])  # > 0: the wall pushed from the right
        if set_sign and abs(pushed_from) >= th.WALL_FORCE_CLEAR_N and pushed_from * set_sign < 0:
            other = "right" if pushed_from > 0 else "left"
            out.append(GuideWarning(number, "against_setting", (
                f"G{number} was pushed by a wall on the {other}, but the wall side is set to "
                f"{settings.wall_side}: the run follows the {settings.wall_side} wall, as set; "
                "check the setting if that is not the wall meant"
            )))  # fmt: skip
        if k > 0 and np.linalg.norm(g.position_m - guides[k - 1].position_m) < th.MIN_SPACING_M:
            out.append(GuideWarning(number, "too_close", (
                f"G{number} is less than {th.MIN_SPACING_M * 1e3:g} mm from G{number - 1}: "
                "delete one of them"
            )))  # fmt: skip
    return out


def _mesh_findings(
    route: LearningRoute | None,
    guides: Sequence[GuidePoint],
    settings: PathLearningSettings,
    workpiece: Workpiece,
    tool_radius_m: float,
    walls: PartWalls,
    right: np.ndarray,
) -> list[GuideWarning]:
    from ..scoring.mesh_score import mesh_deviation

    out: list[GuideWarning] = []
    closed = settings.closed
    axis = walls.axis
    pts = np.array([g.position_m for g in guides])
    right_gap, left_gap = walls.gaps(pts, right)
    for k in range(len(guides)):
        number = k + 1
        nearest = min(right_gap[k], left_gap[k])
        if nearest < -0.5 * tool_radius_m:
            out.append(GuideWarning(number, "in_material", (
                f"G{number} has the cutter {-nearest * 1e3:.1f} mm inside the part: move it out "
                "to touch the wall"
            )))  # fmt: skip
        elif nearest > th.AT_WALL_GAP_M:
            out.append(GuideWarning(number, "far_from_wall", (
                f"G{number} is {nearest * 1e3:.1f} mm from the nearest wall: put it within 1-3 "
                f"mm of the wall (the run searches slowly beyond {th.AT_WALL_GAP_M * 1e3:g} mm)"
            )))  # fmt: skip
        if route is not None:
            side = route.wall_side.side
            own, other = right_gap[k], left_gap[k]
            if side == "left":
                own, other = other, own
            other_side = "left" if side == "right" else "right"
            if other + th.NEARER_MARGIN_M < own and other <= th.AT_WALL_GAP_M:
                chosen = "as set" if route.wall_side.source == "setting" else "as decided"
                out.append(GuideWarning(number, "nearer_other_wall", (
                    f"G{number} is nearer the wall on the {other_side} "
                    f"({max(other, 0.0) * 1e3:.1f} mm) than the one followed on the {side} "
                    f"({own * 1e3:.1f} mm, {chosen}): the run follows the {side} wall; move "
                    f"G{number} towards it, or check the wall side"
                )))  # fmt: skip
            lifted = float(route.lifted_m[k])
            if lifted > 1e-6:
                out.append(GuideWarning(number, "on_floor", (
                    f"G{number} rests on the floor: it is learned {lifted * 1e3:.1f} mm higher, "
                    f"the cutter {settings.floor_clearance_m * 1e3:g} mm above the floor"
                ), "info"))  # fmt: skip
    order = list(range(len(guides))) + ([0] if closed and len(guides) > 2 else [])
    for i0, i1 in zip(order[:-1], order[1:], strict=True):
        a, b = pts[i0], pts[i1]
        length = float(np.linalg.norm(b - a))
        n = max(2, int(length / th.MIN_SPACING_M) + 1)
        line = a + (b - a) * np.linspace(0.0, 1.0, n)[:, None]
        inside = mesh_deviation(workpiece, tool_radius_m, line, axis_base=axis) < -tool_radius_m
        through = float(inside.sum()) * length / (n - 1)
        if through > 0.5 * length:
            out.append(GuideWarning(i0 + 1, "leg_through_part", (
                f"the leg G{i0 + 1} -> G{i1 + 1} runs mostly through the part "
                f"({through * 1e3:.0f} mm): the run follows the wall round it; add a point on the "
                "wall between them if the route is meant another way"
            ), "info"))  # fmt: skip
    return out


def guide_point_warnings(
    guides: Sequence[GuidePoint],
    settings: PathLearningSettings,
    *,
    workpiece: Workpiece | None = None,
    tool_radius_m: float | None = None,
    supervisor: Supervisor | None = None,
    tolerance_m: float | None = None,
    route: LearningRoute | RouteRefusedError | None = None,
) -> tuple[GuideWarning, ...]:
    """What the operator should know before learning (module docstring): the route's refusal,
    if any, first.

    Args:
        guides: The guide points in order.
        settings: The path-learning settings (wall side, force limit, closed, floor clearance).
        workpiece: The part as the user sees it; with ``tool_radius_m``, the mesh checks.
        tool_radius_m: Ball cutter radius.
        supervisor: The cell's ``Supervisor`` (with its arm): the run's motion along the route
            is checked with it (``motion_check``: axis 6's wind-up, the joint ranges, the
            reach, the singularities and the clearances).
        tolerance_m: The post-processing's deviation-height tolerance: beyond
            ``TAUGHT_WALL_TOLERANCE_M`` the program's moves may cut across the wall by that much,
            said before the run (issue 31: a 4 mm tolerance was accepted, then blamed on the
            wall).
        route: The route ``plan_route`` planned for these points, settings, workpiece and
            radius, or its refusal, when the caller has it (the findings only read it);
            planned here when None.
    """
    if not guides:
        return ()
    out: list[GuideWarning] = []
    mesh = workpiece is not None and tool_radius_m is not None
    refusal = route if isinstance(route, RouteRefusedError) else None
    planned = route if isinstance(route, LearningRoute) else None
    if len(guides) >= 2 and route is None:
        try:
            planned = plan_route(
                guides,
                settings,
                workpiece=workpiece if mesh else None,
                tool_radius_m=tool_radius_m,
            )
        except RouteRefusedError as exc:
            refusal = exc
    if refusal is not None:
        rule: GuideRule = "wall_side" if isinstance(refusal, WallSideError) else "route"
        out.append(GuideWarning(0, rule, str(refusal), "refusal"))
    # Each point's side of travel as the route decides it: with the walls the points stand
    # by when the part is known (one PartWalls for every finding here).
    axis = mean_tool_axis(guides)
    walls = None
    if workpiece is not None and tool_radius_m is not None and len(guides) >= 2:
        walls = PartWalls(workpiece, axis, tool_radius_m)
    right = right_of_travel(guides, settings.closed, walls)[1]
    out += _point_findings(guides, settings, axis, right)
    if walls is not None and workpiece is not None and tool_radius_m is not None:
        out += _mesh_findings(planned, guides, settings, workpiece, tool_radius_m, walls, right)
    if supervisor is not None and planned is not None:
        from .motion_check import motion_findings

        out += motion_findings(planned, supervisor)
    if tolerance_m is not None and tolerance_m > th.TAUGHT_WALL_TOLERANCE_M:
        out.append(GuideWarning(0, "tolerance", (
            f"the deviation-height tolerance is {tolerance_m * 1e3:g} mm: the program's straight "
            "moves may cut that far across the wall, more than the "
            f"{th.TAUGHT_WALL_TOLERANCE_M * 1e3:g} mm a program may stray from the taught wall; "
            "lower it (0.2 mm by default) unless that is meant"
        )))  # fmt: skip
    return tuple(out)


# --- after the run -------------------------------------------------------------------------------


@dataclass(frozen=True)
class TaughtWallCheck:
    """Whether the program follows the wall the guide points were taught on.

    Attributes:
        follows: True when the program touches the taught wall at every guide point checked.
        checked: Guide points with a taught wall in the mesh (1-based numbers).
        missed: The guide points whose taught wall the program does not touch (all of them,
            in the order the program meets them, when it meets them out of the order taught).
        worst_gap_m: The farthest the program's cutter stays from a taught wall point.
        message: One line for the user.
    """

    follows: bool
    checked: tuple[int, ...]
    missed: tuple[int, ...]
    worst_gap_m: float
    message: str


def _across_the_end(across: np.ndarray, end: int, foot: np.ndarray, gap: float) -> float:
    """The distance from an open route's end point's wall point ``foot`` to the line of the
    program's first (``end`` 0) or last move, when the program ends short of it by at most
    ``OPEN_END_SHORT_M`` (the force builds over the first mm of a run; the program starts at
    its first sample in the force filter's band): a program that starts late on the taught
    wall is on it, not beside it. ``gap`` otherwise."""
    step = 1 if end == 0 else -1
    p0 = across[end]
    for j in range(end + step, end + step * len(across), step):
        t = across[j] - p0
        n = float(np.linalg.norm(t))
        if n > 1e-6:
            break
    else:
        return gap
    t /= n
    along = float((foot - p0) @ t)
    if along > 0.0 or -along > th.OPEN_END_SHORT_M:  # beside the program, or short by more
        return gap
    return float(np.linalg.norm((foot - p0) - along * t))


def _out_of_order(order: list[int], checked: list[int], worst: float) -> TaughtWallCheck:
    """NOT FIT for a program that meets the points in ``order``, not the order taught."""
    return TaughtWallCheck(False, tuple(checked), tuple(order), worst, (
        f"the program meets the guide points in another order than taught "
        f"({', '.join(f'G{k}' for k in order)}): it went round another wall, or the other "
        "way round; check the wall side, or add a point where the route should go"
    ))  # fmt: skip


def _passing(d_any: np.ndarray, j: int) -> np.ndarray:
    """The program's points where it passes a guide point's wall: within
    ``TAUGHT_WALL_TOLERANCE_M`` along the wall of its nearest approach ``j`` (``d_any``: each
    point's distance from the wall point's foot, across the axis). The program's height must
    be a taught one there, not only somewhere within the tolerance's reach across it: a
    program that passed a point 6.7 mm above its height and its neighbours' (a point 10 mm
    above them 1 mm away, the climb taken late at 20 mm/s) was counted as meeting it, at a
    program point still coming down through their heights 1.7 mm along the wall."""
    return np.flatnonzero(d_any <= math.hypot(float(d_any[j]), th.TAUGHT_WALL_TOLERANCE_M))


def taught_wall_check(
    workpiece: Workpiece,
    tool_radius_m: float,
    guides: Sequence[GuidePoint],
    side: str,
    positions_m: np.ndarray,
    moves: Sequence[Move] | None = None,
    *,
    closed: bool = True,
    lifted_m: Sequence[float] | None = None,
    samples_m: np.ndarray | None = None,
    tolerance_m: float | None = None,
    travel: Sequence[Sequence[float]] | None = None,
) -> TaughtWallCheck:
    """The program (targets and moves) against the wall points the guide points face on
    ``side``, the side the route decided and the run followed, at the heights they were
    learned at (``lifted_m`` off the floor) (module docstring). With the learned ``samples_m``
    (the path the program was reduced from) and the reduction's ``tolerance_m``, a miss the
    learned path does not share is named as the tolerance's (issue 31: a 4 mm tolerance was
    reported as a path learned on another wall). ``travel``: the route's walk past each point
    (``LearningRoute.guide_travel``), which gives the side's direction where it passed."""
    if side not in ("left", "right") or len(guides) < 2:
        return TaughtWallCheck(True, (), (), 0.0, "the taught wall is not known")
    axis = mean_tool_axis(guides)
    walls = PartWalls(workpiece, axis, tool_radius_m)
    if walls.walls is None:
        return TaughtWallCheck(True, (), (), 0.0, "no wall found in the part's mesh")
    points = taught_wall_points(guides, side, closed, walls, lifted_m, travel)
    pts = np.asarray(positions_m, dtype=float)
    moves = linear_moves(len(pts)) if moves is None else tuple(moves)
    path = sample_moves(pts, moves, spacing_m=2.5e-4)
    # Across the tool axis, among the program's points near the wall point's height: the wall
    # is what the check is about; between points taught at different heights the route's
    # height passes through theirs.
    path_height = path @ axis
    across = path - np.outer(path_height, axis)
    heights = np.array([g.position_m @ axis for g in guides])
    n = len(guides)
    checked, missed, worst = [], [], 0.0
    off_height: dict[int, float] = {}  # missed points the program passes at another height
    for k, wall_point in enumerate(points):
        if wall_point is None:
            continue
        around = [j % n for j in (k - 1, k, k + 1) if closed or 0 <= j < n]
        h = float(wall_point @ axis)
        near = np.zeros(len(path_height), dtype=bool)
        for taught in (h, *heights[around]):  # its height or a neighbour's, not between them
            near |= np.abs(path_height - taught) <= th.TAUGHT_WALL_HEIGHT_BAND_M
        if not near.any():
            near[:] = True
        foot = wall_point - axis * h
        d_any = np.linalg.norm(across - foot, axis=1)  # at any height
        d = np.where(near, d_any, np.inf)
        nearest = int(np.argmin(d))
        gap = float(d[nearest])
        if not closed and k in (0, n - 1) and nearest in (0, len(across) - 1):
            gap = _across_the_end(across, nearest, foot, gap)
        gap -= tool_radius_m
        checked.append(k + 1)
        worst = max(worst, gap)
        j = int(np.argmin(d_any))
        if gap > th.TAUGHT_WALL_TOLERANCE_M or not near[_passing(d_any, j)].any():
            missed.append(k + 1)
            if d_any[j] - tool_radius_m <= th.TAUGHT_WALL_TOLERANCE_M:
                off_height[k + 1] = float(h - path_height[j])  # > 0: above (axis into part)
    if not checked:
        return TaughtWallCheck(True, (), (), 0.0, "no taught wall found in the part's mesh")
    places = [g.position_m if p is None else p for p, g in zip(points, guides, strict=True)]
    if (order := met_order(places, across, axis, closed)) is not None:
        return _out_of_order(order, checked, worst)
    if missed and samples_m is not None and tolerance_m is not None and len(samples_m) >= 2:
        learned = taught_wall_check(
            workpiece,
            tool_radius_m,
            guides,
            side,
            samples_m,
            closed=closed,
            lifted_m=lifted_m,
            travel=travel,
        )
        if not set(missed) & set(learned.missed):
            where = ", ".join(f"G{k}" for k in missed)
            message = (
                f"the program does not follow the wall taught at {where} (on the {side}; it "
                f"passes {worst * 1e3:.1f} mm from it), although the learned path does: the "
                f"deviation-height tolerance of {tolerance_m * 1e3:g} mm lets the program's "
                "moves cut that far across the wall; lower the tolerance "
                f"({TOLERANCE_MM.default:g} mm by default; at "
                f"most {th.TAUGHT_WALL_TOLERANCE_M * 1e3:g} mm keeps the program on the taught "
                "wall)"
            )
            return TaughtWallCheck(False, tuple(checked), tuple(missed), worst, message)
    if missed and set(missed) <= set(off_height):
        k = max(missed, key=lambda m: abs(off_height[m]))
        where = ", ".join(f"G{m}" for m in missed)
        up = "above" if off_height[k] > 0 else "below"
        message = (
            f"the program passes the wall taught at {where} (on the {side}) at another height: "
            f"{abs(off_height[k]) * 1e3:.1f} mm {up} the height taught at G{k}; a point "
            "taught much higher or lower than its neighbours close by asks for a climb the run "
            "takes late: teach it nearer their height, or farther from them"
        )
    elif missed:
        where = ", ".join(f"G{k}" for k in missed)
        message = (
            f"the program does not follow the wall taught at {where} (on the {side}; it passes "
            f"{worst * 1e3:.1f} mm from it): it was learned on another wall, the floor or inside "
            "the part"
        )
        message += (
            ", or the part is not where its CAD is placed (calibrate the work object by "
            "touching the part)"
        )
    else:
        message = (
            f"the program follows the taught wall (on the {side}) at all {len(checked)} guide "
            "points"
        )
    return TaughtWallCheck(not missed, tuple(checked), tuple(missed), worst, message)
