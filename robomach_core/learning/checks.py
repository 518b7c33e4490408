"""The operator check: what people do with guide points, caught before path learning.

PROBLEM   Path learning follows the wall by force from rough guide points (chapter section 3),
          but some things it cannot recover from, and some it recovers from in a way the person
          should know about: the wall side cannot be told (points recorded free, or pushed
          against walls on both sides), a point in heavy contact is half-way to the protection
          stop, a point nearer another wall than the one it follows was perhaps meant for that
          wall, a point resting on the floor will be learned higher, a leg that crosses the
          part will be followed round it, two points on top of each other give a leg with no
          direction, and a wrist that must turn further than axis 6 allows cannot run the loop.
STRATEGY  Look at the guide points as the operator left them: the force recorded at each, the
          route's legs, and, when the part's mesh is known (the CAD the user teaches on), the
          walls on both sides of each point, the floor under it and the part along each leg;
          the arm's inverse kinematics along the route for axis 6.
SOLUTION  ``guide_point_warnings(guides, settings, *, workpiece, tool_radius_m, robot)`` returns
          one ``GuideWarning`` per finding (1-based point number, rule, severity, a message with
          the fix in one line). "refusal" findings stop learning (the API answers 422 with the
          message); "warning" and "info" are shown, the run starts.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass
from typing import Literal

import numpy as np

from ..errors import RobomachError, WallSideError
from ..leadthrough import GuidePoint
from ..workpiece import Workpiece
from .run import PathLearningSettings
from .side import (
    MAX_WALL_GAP_M,
    NEARER_MARGIN_M,
    WALL_FORCE_CLEAR_N,
    mean_tool_axis,
    mesh_wall_gaps,
    resolve_wall_side,
)

HEAVY_CONTACT_FRACTION = 0.5  # of the protection limit: already half-way to a stop
TOUCH_WITHOUT_PUSH_N = 0.8  # a force between this and WALL_FORCE_CLEAR_N: touching, not pushing
MIN_SPACING_M = 0.001  # closer guide points give a leg with no direction
LEG_SAMPLE_M = 0.001  # legs are checked against the part every millimetre
LEG_THROUGH_PART_FRACTION = 0.5  # a leg mostly inside the part is reported

GuideRule = Literal[
    "wall_side",
    "heavy_contact",
    "touching_without_push",
    "far_from_wall",
    "in_material",
    "nearer_other_wall",
    "on_floor",
    "leg_through_part",
    "too_close",
    "wrist_turn",
]
Severity = Literal["refusal", "warning", "info"]


@dataclass(frozen=True)
class GuideWarning:
    """One finding about the guide points.

    Attributes:
        point: 1-based guide point number (as the GUIs list them); 0 for the whole route.
        rule: Which rule (``GuideRule``).
        message: What is wrong and what to do, for the operator.
        severity: "refusal" (learning will not start), "warning" or "info".
    """

    point: int
    rule: GuideRule
    message: str
    severity: Severity = "warning"


def _leg_through_part(
    guides: Sequence[GuidePoint], closed: bool, workpiece: Workpiece, tool_radius_m: float
) -> list[tuple[int, int, float]]:
    """(from, to, length [m]) of the legs whose straight line runs mostly inside the part: a
    leg that cuts a corner is usual (the run follows the wall round it), one that is mostly
    inside the part may join points on different walls."""
    from .score import mesh_deviation

    n = len(guides)
    order = list(range(n)) + ([0] if closed and n > 2 else [])
    out = []
    axis = mean_tool_axis(guides)
    for i0, i1 in zip(order[:-1], order[1:], strict=True):
        a, b = guides[i0].position_m, guides[i1].position_m
        length = float(np.linalg.norm(b - a))
        k = max(2, int(length / LEG_SAMPLE_M) + 1)
        pts = a + (b - a) * np.linspace(0.0, 1.0, k)[:, None]
        inside = mesh_deviation(workpiece, tool_radius_m, pts, axis_base=axis) < -tool_radius_m
        through = float(inside.sum()) * length / (k - 1)
        if through > LEG_THROUGH_PART_FRACTION * length:
            out.append((i0 + 1, i1 + 1, through))
    return out


def _wrist_turn(robot, guides: Sequence[GuidePoint], closed: bool) -> tuple[float, float] | None:
    """(turn the route needs on axis 6, the axis's range) [rad], or None when it fits or the
    route cannot be solved (reachability is checked elsewhere)."""
    import math as _m

    q = np.asarray(guides[0].joints_rad, dtype=float)
    values = [q[5]]
    order = list(range(1, len(guides))) + ([0] if closed else [])
    for k in order:
        try:
            q_next = robot.ik(guides[k].T_base_tcp, q)
        except RobomachError:
            return None
        q_next[5] = q[5] + _m.remainder(q_next[5] - q[5], 2 * _m.pi)
        values.append(q_next[5])
        q = q_next
    need = max(values) - min(values)
    span = float(robot.upper_rad[5] - robot.lower_rad[5])
    return (need, span) if need > span - 0.4 else None


def guide_point_warnings(
    guides: Sequence[GuidePoint],
    settings: PathLearningSettings,
    *,
    workpiece: Workpiece | None = None,
    tool_radius_m: float | None = None,
    robot=None,
) -> tuple[GuideWarning, ...]:
    """What the operator should know before learning (module docstring).

    Args:
        guides: The guide points in order.
        settings: The path-learning settings (wall side, force limit, closed, floor clearance).
        workpiece: The part as the user sees it; with ``tool_radius_m``, the mesh checks.
        tool_radius_m: Ball cutter radius.
        robot: The arm (``robot.Robot``); the wrist's turn round the route is checked with it.
    """
    out: list[GuideWarning] = []
    n = len(guides)
    if n == 0:
        return ()
    limit = settings.force_limit_N
    closed = settings.closed
    mesh = workpiece is not None and tool_radius_m is not None
    decision = None
    if n >= 2:
        try:
            decision = resolve_wall_side(
                guides,
                settings.wall_side,
                closed=closed,
                workpiece=workpiece if mesh else None,
                tool_radius_m=tool_radius_m,
            )
        except WallSideError as exc:
            out.append(GuideWarning(0, "wall_side", str(exc), "refusal"))
    axis = mean_tool_axis(guides)
    for k, g in enumerate(guides):
        number = k + 1
        force = np.asarray(g.force_N, dtype=float)
        magnitude = float(np.linalg.norm(force))
        across = float(np.linalg.norm(force - axis * float(force @ axis)))
        if magnitude > HEAVY_CONTACT_FRACTION * limit:
            out.append(
                GuideWarning(
                    number,
                    "heavy_contact",
                    f"G{number} was recorded pressing {magnitude:.0f} N into the part "
                    f"(protection stops at {limit:.0f} N): back off to a light touch and "
                    "record it again",
                )
            )
        elif settings.wall_side == "auto" and (TOUCH_WITHOUT_PUSH_N <= across < WALL_FORCE_CLEAR_N):
            out.append(
                GuideWarning(
                    number,
                    "touching_without_push",
                    f"G{number} touches the wall without a push ({across:.1f} N): a light "
                    f"push towards the wall ({WALL_FORCE_CLEAR_N:g}-10 N) tells the wall side",
                    "info",
                )
            )
        if k > 0 and float(np.linalg.norm(g.position_m - guides[k - 1].position_m)) < MIN_SPACING_M:
            out.append(
                GuideWarning(
                    number,
                    "too_close",
                    f"G{number} is less than {MIN_SPACING_M * 1e3:g} mm from G{number - 1}: "
                    "delete one of them",
                )
            )
    if mesh and n >= 2:
        from .route import floor_clearances

        right_gap, left_gap = mesh_wall_gaps(guides, closed, workpiece, tool_radius_m)
        floor = floor_clearances(guides, workpiece, tool_radius_m)
        for k in range(n):
            number = k + 1
            nearest = min(right_gap[k], left_gap[k])
            if nearest < -0.5 * tool_radius_m:
                out.append(
                    GuideWarning(
                        number,
                        "in_material",
                        f"G{number} has the cutter {-nearest * 1e3:.1f} mm inside the part: "
                        "move it out to touch the wall",
                    )
                )
            elif nearest > MAX_WALL_GAP_M:
                out.append(
                    GuideWarning(
                        number,
                        "far_from_wall",
                        f"G{number} is {nearest * 1e3:.1f} mm from the nearest wall: put it "
                        f"within 1-3 mm of the wall (the run searches slowly beyond "
                        f"{MAX_WALL_GAP_M * 1e3:g} mm)",
                    )
                )
            if decision is not None:
                own, other = (
                    (right_gap[k], left_gap[k])
                    if decision.side == "right"
                    else (left_gap[k], right_gap[k])
                )
                other_side = "left" if decision.side == "right" else "right"
                if other + NEARER_MARGIN_M < own and other <= MAX_WALL_GAP_M:
                    out.append(
                        GuideWarning(
                            number,
                            "nearer_other_wall",
                            f"G{number} is nearer the wall on the {other_side} "
                            f"({max(other, 0.0) * 1e3:.1f} mm) than the one followed on the "
                            f"{decision.side} ({own * 1e3:.1f} mm): move it towards the "
                            f"{decision.side} wall, or check the wall side",
                        )
                    )
            gap = float(floor[k])
            if math.isfinite(gap) and gap < settings.floor_clearance_m:
                out.append(
                    GuideWarning(
                        number,
                        "on_floor",
                        f"G{number} rests on the floor: it is learned "
                        f"{(settings.floor_clearance_m - gap) * 1e3:.1f} mm higher, the cutter "
                        f"{settings.floor_clearance_m * 1e3:g} mm above the floor",
                        "info",
                    )
                )
        for i0, i1, through in _leg_through_part(guides, closed, workpiece, tool_radius_m):
            out.append(
                GuideWarning(
                    i0,
                    "leg_through_part",
                    f"the leg G{i0} -> G{i1} runs mostly through the part ({through * 1e3:.0f} "
                    "mm): the run follows the wall round it; add a point on the wall between "
                    "them if the route is meant another way",
                    "info",
                )
            )
    if robot is not None and n >= 2:
        turn = _wrist_turn(robot, guides, closed)
        if turn is not None:
            need, span = turn
            out.append(
                GuideWarning(
                    0,
                    "wrist_turn",
                    f"the tool turns {math.degrees(need):.0f} deg about its axis along the "
                    f"route, and axis 6 turns {math.degrees(span):.0f} deg at most: keep the "
                    "tool's turn about its axis the same at every point (a spinning cutter "
                    "does not mind)",
                )
            )
    return tuple(out)
