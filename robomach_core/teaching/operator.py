"""A scripted operator who leads the robot through the guide points by pushing it.

It stands in for the process engineer in ``robomach demo`` and the workbench's "load the
example": a virtual hand applies a push proportional to the distance to where the operator
wants the tool (capped like a real hand), through the admittance controller, so the robot
travels there; nothing is teleported. The operator first jogs the orientation square to the
part, then for each guide point: over the groove, down into it, a gentle push sideways until
the wall pushes back, record, back out and up.

The operator's eye is imperfect: each intended position is off by a seeded random amount.
On a part that may not be where its mesh is, the operator enters each groove in its middle and
lets the push find the real wall (``robust_intents``).
"""

from __future__ import annotations

import math
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field, replace

import numpy as np

from ..cell import (
    AXES,
    CONTROL_PERIOD_S,
    ComplianceSelection,
    GuidePoint,
    LeadThrough,
    LeadThroughState,
    Robot,
)
from ..cell import TOOL_DOWN as TOOL_DOWN
from ..errors import InvalidInputError, NotEnoughGuidePointsError, UnreachableTargetError
from ..learning.thresholds import EXAMPLE_BELOW_TOP_M, OPEN_EDGE_ENTRY_M
from ..learning.walls import walls_near
from ..part import Line, Workpiece
from ..transforms import matrix_from_quaternion, rotation_log
from .pointing import GuideProposal, ProposalSettings, WallPlacer, propose_guide_points

HAND_GAIN_N_M = 2000.0  # push per metre of distance to the goal
HAND_MAX_N = 15.0  # a comfortable one-hand push
HAND_MIN_N = 1.5  # a hand pushes firmly enough to get past the admittance's 1 N deadband
WALL_PUSH_N = 6.0  # the gentle sideways push that finds the wall
EXAMPLE_GAP_M = 0.001  # the example's points stand this far off the wall, ...
EXAMPLE_ALONG_M = 0.0015  # ... off by up to this along it (the operator's eye), ...
EXAMPLE_OFF_M = 0.0005  # ... and up to this farther from it
EXAMPLE_WALL_MATCH_M = 1e-4  # the mesh's wall where the example points is the known one
MAX_JOG_TURN_DEG = 45.0  # the largest rotational jog (leadthrough.LeadThrough.jog)


@dataclass(frozen=True)
class GuideIntent:
    """Where the operator means to put one guide point (base frame, metres).

    Attributes:
        position_m: (3,) intended TCP position.
        wall_normal: (3,) unit vector from the tool towards the wall, or None to record the
            point where it is without feeling for the wall.
        rotation: 3x3 intended tool orientation (default: tool axis straight down).
    """

    position_m: np.ndarray
    wall_normal: np.ndarray | None
    rotation: np.ndarray = field(default_factory=lambda: TOOL_DOWN.copy())


def intents_from_csv(text: str, robot: Robot | None = None) -> list[GuideIntent]:
    """Guide intents from CSV text: x_mm,y_mm,z_mm[,qw,qx,qy,qz[,wall_nx,wall_ny,wall_nz]].

    A header row is allowed. Positions are TCP positions in the robot base frame. The
    orientation is the tool's (default: straight down). The wall direction is where the
    operator pushes to feel the wall: from the tool *into* the wall (the opposite of the wall
    surface's normal); without it the point is recorded where it is, free. With a ``robot``,
    every point is checked for reachability first.

    Raises:
        InvalidInputError: malformed rows or fewer than two points.
        UnreachableTargetError: a point the robot cannot reach (says which).
    """
    rows: list[tuple[int, list[float]]] = []
    for line_no, line in enumerate(text.splitlines(), start=1):
        cells = [c.strip() for c in line.split(",")]
        if not line.strip() or line.lstrip().startswith("#"):
            continue
        try:
            values = [float(c) for c in cells]
        except ValueError:
            if not rows and line_no == 1:
                continue  # header
            raise InvalidInputError(f"guide points line {line_no}: not numbers: {line!r}") from None
        if len(values) not in (3, 7, 10) or not all(math.isfinite(v) for v in values):
            raise InvalidInputError(
                f"guide points line {line_no}: expected 3, 7 or 10 finite numbers "
                "(x,y,z mm [,qw,qx,qy,qz [,wall normal]]), got " + str(len(values))
            )
        rows.append((line_no, values))
    if len(rows) < 2:
        raise NotEnoughGuidePointsError(
            f"path learning needs at least 2 guide points, the file has {len(rows)}"
        )
    intents = []
    for k, (line_no, v) in enumerate(rows):
        rotation = matrix_from_quaternion(np.array(v[3:7])) if len(v) >= 7 else TOOL_DOWN.copy()
        normal = None
        if len(v) == 10:
            n = np.array(v[7:10])
            if np.linalg.norm(n) < 1e-9:
                raise InvalidInputError(f"guide points line {line_no}: the wall normal is zero")
            normal = n / np.linalg.norm(n)
        intent = GuideIntent(np.array(v[:3]) * 1e-3, normal, rotation)
        if robot is not None:
            T = np.eye(4)
            T[:3, :3], T[:3, 3] = rotation, intent.position_m
            try:
                robot.ik(T)
            except UnreachableTargetError as exc:
                raise UnreachableTargetError(
                    f"guide point {k + 1} (line {line_no}): {exc}"
                ) from None
        intents.append(intent)
    return intents


def guide_intents(proposal: GuideProposal, *, touch: bool = True) -> list:
    """The proposal as the scripted operator's intents (``GuideIntent``): it
    leads the robot to each point by pushes and, with ``touch``, pushes gently towards the
    wall until it pushes back (as a person touching the wall does), except at outside corners
    (docs/guide_points.md: no wall push there). Touching makes the points the real wall's
    when the part is not where its CAD is."""
    R = proposal.T_base_wobj[:3, :3] @ proposal.pick.T_wobj_floor[:3, :3]
    out = []
    for p in proposal.points:
        normal = None
        if touch and p.kind != "outside corner":
            n = proposal.wall.free_normal_at(np.array([p.s_m]))[0]
            normal = -(R @ np.array([n[0], n[1], 0.0]))
        out.append(GuideIntent(p.T_base_tcp[:3, 3].copy(), normal, p.T_base_tcp[:3, :3].copy()))
    return out


def guide_plan(
    workpiece: Workpiece,
    tool_radius_m: float,
    rng: np.random.Generator,
    *,
    robot: Robot | None = None,
) -> list[GuideIntent]:
    """The example operator's guide points for a built-in workpiece: the planner's proposal
    (``pointing.propose_guide_points``) for its known wall, pointed at
    ``EXAMPLE_BELOW_TOP_M`` below the wall's top in the middle of its first straight run, as
    the operator's imprecise hand places them: each off by up to ``EXAMPLE_ALONG_M`` along
    the wall and up to ``EXAMPLE_OFF_M`` farther from it (seeded by ``rng``), a push towards
    the wall at each but the outside corners (``guide_intents``).
    """
    wall = workpiece.wall
    if wall is None:
        raise InvalidInputError(
            f"the example lead-through needs a built-in workpiece, not {workpiece.name!r}"
        )
    run = next((p for p in wall.pieces if isinstance(p, Line)), wall.pieces[0])
    a, b = run.point_at(np.array([0.0, run.length]))
    left = np.array([a[1] - b[1], b[0] - a[0]]) / run.length  # the free side
    click = np.array([*(0.5 * (a + b)), workpiece.wall_z_m[1] - EXAMPLE_BELOW_TOP_M])
    proposal = propose_guide_points(
        workpiece, robot, click, np.array([left[0], left[1], 0.0]),
        tool_radius_m=tool_radius_m, settings=ProposalSettings(gap_m=EXAMPLE_GAP_M),
    )  # fmt: skip
    if wall.distance(proposal.wall.points_m).max() > EXAMPLE_WALL_MATCH_M:
        raise InvalidInputError(f"{workpiece.name}: its mesh's wall is not its known wall")
    R = workpiece.T_base_wobj[:3, :3] @ proposal.pick.T_wobj_floor[:3, :3]
    intents = guide_intents(proposal)
    for k, (p, intent) in enumerate(zip(proposal.points, intents, strict=True)):
        if p.kind == "outside corner":  # placed with care: the corner is what it is there for
            continue
        s = np.array([p.s_m])
        along = proposal.wall.point_at(s + 1e-4)[0] - proposal.wall.point_at(s - 1e-4)[0]
        off = proposal.wall.free_normal_at(s)[0]
        shift = along / np.linalg.norm(along) * rng.uniform(-EXAMPLE_ALONG_M, EXAMPLE_ALONG_M)
        shift = shift + off * rng.uniform(0.0, EXAMPLE_OFF_M)
        intents[k] = replace(intent, position_m=intent.position_m + R @ [*shift, 0.0])
    return intents


def robust_intents(intents: Sequence, workpiece: Workpiece, tool_radius_m: float) -> list:
    """Intents for a part that may not be where its mesh is: each point with a wall push is
    entered in the middle of the free space beside its wall (a groove's middle;
    ``OPEN_EDGE_ENTRY_M`` off an open edge), so that the cutter comes down clear of the real
    walls, and the push finds the wall from there (a careful operator does the same when the
    part may be off its drawing). Points without a push (outside corners) stay where they
    are."""
    cad = workpiece.cad()
    T = cad.T_base_wobj
    out = []
    for intent in intents:
        if intent.wall_normal is None:
            out.append(intent)
            continue
        p = (np.asarray(intent.position_m) - T[:3, 3]) @ T[:3, :3]
        T_floor, (pf,), loops = walls_near(cad.mesh, p)
        if not loops:
            out.append(intent)
            continue
        loop = min(loops, key=lambda lp: abs(lp.signed_distance(pf[None, :2])[0]))
        xy, note = WallPlacer(loop, loops, tool_radius_m, OPEN_EDGE_ENTRY_M)(
            float(loop.project(pf[None, :2])[0])
        )
        if "too narrow" in note:
            out.append(intent)
            continue
        entry = T[:3, :3] @ T_floor[:3, :3] @ np.array([xy[0], xy[1], pf[2]]) + T[:3, 3]
        out.append(replace(intent, position_m=entry))
    return out


def _hand(goal: np.ndarray, p: np.ndarray, limit: float = HAND_MAX_N) -> np.ndarray:
    """Push towards ``goal``: HAND_MIN_N + gain * distance, capped at ``limit``."""
    d = goal - p
    dist = float(np.linalg.norm(d))
    if dist < 1e-9:
        return np.zeros(3)
    return d / dist * min(limit, HAND_MIN_N + HAND_GAIN_N_M * dist)


def push_to(
    lt: LeadThrough,
    state: LeadThroughState,
    goal: np.ndarray,
    selection: ComplianceSelection,
    *,
    tolerance_m: float = 0.0003,
    timeout_s: float = 20.0,
) -> LeadThroughState:
    """Push the tool towards ``goal`` until it is within ``tolerance_m`` and nearly still."""
    for _ in range(int(timeout_s / CONTROL_PERIOD_S)):
        p = state.cell.T_base_tcp[:3, 3]
        if np.linalg.norm(goal - p) < tolerance_m:
            break
        wrench = np.concatenate([_hand(goal, p), np.zeros(3)])
        state = lt.step(state, wrench, selection)
    return state


def square_up(
    lt: LeadThrough,
    state: LeadThroughState,
    selection: ComplianceSelection,
    *,
    step_deg: float = 0.5,
    rotation: np.ndarray | None = None,
) -> LeadThroughState:
    """Jog the orientation about the tool axes until it matches ``rotation`` (within a step).

    The default ``rotation`` is square to the part: the tool axis straight down. A turn larger
    than a jog allows (45 deg) is made in several jogs (the example failed from wherever a
    person left the tool: "a rotational jog step is at most 45 degrees").
    """
    max_steps = max(1, int(MAX_JOG_TURN_DEG / step_deg))
    goal = TOOL_DOWN if rotation is None else rotation
    for _ in range(3):
        R = state.cell.T_base_tcp[:3, :3]
        err_tool = R.T @ rotation_log(goal @ R.T)  # rotation to do, in tool axes
        moved = False
        for i, axis in enumerate(AXES[3:]):  # rx, ry, rz
            steps = round(math.degrees(err_tool[i]) / step_deg)
            while steps:  # a jog turns at most MAX_JOG_TURN_DEG, as the pendant's joystick
                now = max(-max_steps, min(max_steps, steps))
                state = lt.jog(state, axis, math.radians(now * step_deg), selection)
                steps -= now
                moved = True
        if not moved:
            break
    return state


def scripted_leadthrough(
    lt: LeadThrough,
    state: LeadThroughState,
    workpiece: Workpiece,
    rng: np.random.Generator,
    *,
    intents: list[GuideIntent] | None = None,
    progress: Callable[[float], None] | None = None,
) -> tuple[LeadThroughState, list[GuidePoint]]:
    """Lead the robot to every guide point by pushes and record each one.

    Args:
        intents: Where to put the guide points; default: ``guide_plan`` for the workpiece.
    """
    free = ComplianceSelection(frozenset({"x", "y", "z"}), "base")
    planar = ComplianceSelection(frozenset({"x", "y"}), "base")
    stiff = ComplianceSelection(frozenset(), "tool")
    if intents is None:
        intents = guide_plan(workpiece, lt.cell.tool.radius_m, rng)
    state = square_up(lt, state, stiff, rotation=intents[0].rotation)
    surface_z = (workpiece.T_base_wobj @ np.array([0, 0, workpiece.surface_z_m, 1.0]))[2]
    safe_z = surface_z + 0.008
    start = state.cell.T_base_tcp[:3, 3]
    if start[2] < safe_z:  # beside the part (after a touch of its side): straight up first
        state = push_to(lt, state, np.array([start[0], start[1], safe_z]), free, tolerance_m=0.0005)
    guides: list[GuidePoint] = []
    for k, intent in enumerate(intents):
        over = intent.position_m.copy()
        over[2] = max(safe_z, over[2])
        state = push_to(lt, state, over, free, tolerance_m=0.0005)
        if not np.allclose(intent.rotation, state.cell.T_base_tcp[:3, :3], atol=0.01):
            state = square_up(lt, state, stiff, rotation=intent.rotation)
        state = push_to(lt, state, intent.position_m, free)
        if intent.wall_normal is not None:
            # Sideways until the wall pushes back: the hand keeps pushing, the wall balances it.
            wall_push = np.concatenate([intent.wall_normal * WALL_PUSH_N, np.zeros(3)])
            for _ in range(int(1.5 / CONTROL_PERIOD_S)):
                state = lt.step(state, wall_push, planar)
        guides.append(lt.record(state))
        state = push_to(lt, state, intent.position_m, planar)
        up = state.cell.T_base_tcp[:3, 3].copy()
        up[2] = safe_z
        state = push_to(lt, state, up, free, tolerance_m=0.0005)
        if progress is not None:
            progress((k + 1) / len(intents))
    return state, guides
