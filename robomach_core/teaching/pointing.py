"""Guide points from a point on the wall: one for click-to-teach, or a whole wall's worth.

PROBLEM   Teaching is the one step a person does, and with the part's mesh at hand it need not
          be blind: pointing at the wall says which wall to follow. The guide points must then
          be where path learning (chapter section 3.2) works from them: beside the wall with
          the cutter free, off the floor, bracketing every corner, with a point of its own at
          each outside corner (docs/guide_points.md), the wall side stated, and every point
          reachable by the arm. The example operator (``operator.guide_plan``) places its
          points by the same rules: this is the one planner.
STRATEGY  The picked wall at the machining height, in the floor's frame (``walls.pick_wall``: the
          section parallel to the floor beside the pick, at the pick's height above it) is a loop
          with the material on its right. Along it, corners are where the wall turns faster than
          ``CORNER_RADIUS_M``; corners closer than ``MIN_RUN_M`` merge into a group, and a group
          that turns back round the free side (``SLOT_END_DEG``, a slot's end) ends the wall there,
          so the wall to follow is open. Each straight run between groups gets one point (two,
          ``LONG_RUN_END_SHARE`` from its ends, from ``LONG_RUN_M``), each group turning round the
          material by ``OUTSIDE_CORNER_DEG`` or more a point at its middle. Then every leg is
          checked against the wall: where its chord comes within ``tool radius + LEG_CLEARANCE_M``
          of the material, or the wall recedes more than ``MAX_LEG_GAP_M`` from it, a point is added
          at the worst place. Each point stands ``gap`` off the wall on the free side (centred in a
          groove too narrow for that), at the pick's height above the floor under it, with the job's
          tool orientation. Every number is in ``thresholds.py``.
SOLUTION  ``propose_guide_points(workpiece, robot, point, normal, ...) -> GuideProposal`` and
          ``teach_point(...) -> ProposedPoint`` (one point: click to teach); both say per point
          whether the arm reaches it (inverse kinematics from the previous point, and the
          supervisor's margins) and ``wall_side`` is always ``"right"`` (the loop's direction).
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass, field, replace
from typing import Literal

import numpy as np
from scipy.spatial.transform import Rotation

from ..cell import TOOL_DOWN, Robot
from ..errors import InvalidInputError, RobomachError
from ..learning.thresholds import (
    CORNER_RADIUS_M,
    CORNER_TURN_MIN_DEG,
    EQUAL_STRETCH_M,
    JOINT_JUMP_DEG,
    LONG_RUN_END_SHARE,
    LONG_RUN_M,
    MIN_RUN_M,
    MIN_SPACING_M,
    OUTSIDE_CORNER_DEG,
    ROUND_LOOP_POINTS,
    SLOT_END_DEG,
    SLOT_END_MAX_M,
    UNEVEN_FLOOR_NOTE_M,
    WALL_END_MARGIN_M,
)
from ..learning.walls import WallLoop, WallPick, pick_wall
from ..limits import MACHINING_HEIGHT_MM, WALL_GAP_MM
from ..part import Workpiece
from ._legs import TURN_WINDOW_M, PointKind, WallPlacer, _add_points, _leg_problem

SAMPLE_M = 2e-4  # the wall is looked at every this much for corners

Reach = Literal["ok", "near", "unreachable"]


@dataclass(frozen=True)
class ProposalSettings:
    """Where a proposed guide point stands (SI units).

    Attributes:
        gap_m: Gap between the cutter and the wall (default 1 mm; a narrow groove centres it).
        height_above_floor_m: TCP height above the floor where the picked point's own height
            cannot be kept (the cutter would touch the floor, the spindle the part, or the
            cutter miss the wall; ``walls.pick_wall``).
    """

    gap_m: float = WALL_GAP_MM.default_value() * 1e-3
    height_above_floor_m: float = MACHINING_HEIGHT_MM.default_value() * 1e-3

    def __post_init__(self) -> None:
        WALL_GAP_MM.check(self.gap_m * 1e3)
        MACHINING_HEIGHT_MM.check(self.height_above_floor_m * 1e3)


@dataclass(frozen=True)
class ProposedPoint:
    """One proposed guide point.

    Attributes:
        T_base_tcp: 4x4 TCP pose in the robot base frame [m].
        position_wobj_m: (3,) TCP position in the work-object frame [m].
        s_m: Arc length along the wall of the point's foot.
        kind: Why it is there (``PointKind``).
        reach: ``"ok"``, ``"near"`` (inside a slow zone of the supervisor) or ``"unreachable"``.
        message: What is wrong, near or changed, for people ("" when ok).
        joints_rad: (6,) the arm's joints there, None when unreachable or not checked.
        position_floor_m: (3,) TCP position in the floor frame (``WallPick``), where the wall
            is.
    """

    T_base_tcp: np.ndarray
    position_wobj_m: np.ndarray
    s_m: float
    kind: PointKind
    reach: Reach = "ok"
    message: str = ""
    joints_rad: np.ndarray | None = None
    position_floor_m: np.ndarray | None = None


@dataclass(frozen=True)
class GuideProposal:
    """Guide points for a whole wall, in the order to learn them.

    Attributes:
        points: The points.
        wall: The wall they follow (the floor frame's x-y), open or closed.
        closed: Learn a closed contour (back to the first point).
        wall_side: Side of the wall for path learning: always ``"right"`` (the wall's
            direction puts the material on the right).
        pick: The picked wall, its floor frame and the machining height.
        notes: What was adjusted or cannot be helped, for people.
    """

    points: tuple[ProposedPoint, ...]
    wall: WallLoop
    closed: bool
    wall_side: Literal["left", "right"]
    pick: WallPick
    notes: tuple[str, ...] = field(default=())
    T_base_wobj: np.ndarray = field(default_factory=lambda: np.eye(4))

    @property
    def z_m(self) -> float:
        """The machining height at the pick (floor frame)."""
        return self.pick.z_m

    @property
    def height_above_floor_m(self) -> float:
        return self.pick.z_m - self.pick.floor_z_m

    def wall_wobj_m(self) -> np.ndarray:
        """(n, 3) the wall at the machining height, work-object frame (for drawing)."""
        w = self.wall.points_m
        return self.pick.to_wobj(np.column_stack([w, np.full(len(w), self.wall.z_m)]))


# --- orientation ------------------------------------------------------------------------------


def job_tool_rotation(T_base_wobj: np.ndarray, R_tool: np.ndarray | None = None) -> np.ndarray:
    """The job's tool orientation (base frame): ``R_tool`` re-aimed so its axis (tool z) is
    -z of the work object, by the smallest rotation; default the example operator's, tool
    axis straight down and tool x along -y of the base."""
    R = TOOL_DOWN if R_tool is None else np.asarray(R_tool, dtype=float)
    down = -np.asarray(T_base_wobj, dtype=float)[:3, 2]
    align, _ = Rotation.align_vectors(down[None], R[:, 2][None])
    return align.as_matrix() @ R


# --- corners ----------------------------------------------------------------------------------


@dataclass(frozen=True)
class _Group:
    start_m: float  # arc length (in the loop's own coordinates, may exceed its length)
    end_m: float
    turn_rad: float  # net turn, left (towards the free side) positive
    apex_m: float  # where the wall has turned half its sharpest corner: a sharp corner's tip

    @property
    def slot_end(self) -> bool:
        """Turns back round the free side within a slot's width: the wall ends here."""
        return (
            self.turn_rad >= math.radians(SLOT_END_DEG)
            and self.end_m - self.start_m <= SLOT_END_MAX_M
        )


def _corner_groups(loop: WallLoop, shift_m: float = 0.0) -> list[_Group]:
    """Corner groups of ``loop`` in arc lengths counted from ``shift_m`` (module docstring)."""
    n = max(8, int(math.ceil(loop.length_m / SAMPLE_M)))
    s = np.linspace(0.0, loop.length_m, n, endpoint=not loop.closed)
    d = loop.point_at(s + shift_m + TURN_WINDOW_M) - loop.point_at(s + shift_m - TURN_WINDOW_M)
    theta = np.unwrap(np.arctan2(d[:, 1], d[:, 0]))
    corner = np.abs(np.gradient(theta, s)) > 1.0 / CORNER_RADIUS_M
    groups: list[_Group] = []
    i = 0
    while i < n:
        if not corner[i]:
            i += 1
            continue
        j = i
        while j + 1 < n and corner[j + 1]:
            j += 1
        a, b = max(i - 1, 0), min(j + 1, n - 1)
        turn = float(theta[b] - theta[a])
        if abs(turn) >= math.radians(CORNER_TURN_MIN_DEG):
            half = np.sign(turn) * (theta[a : b + 1] - theta[a] - 0.5 * turn)
            apex = float(np.interp(0.0, half, s[a : b + 1]))  # theta is monotonic here
            last = groups[-1] if groups else None
            if last is not None and s[i] - last.end_m < MIN_RUN_M:  # one group with the last
                apex = apex if abs(turn) > abs(last.turn_rad) else last.apex_m
                groups[-1] = _Group(last.start_m, float(s[j]), last.turn_rad + turn, apex)
            else:
                groups.append(_Group(float(s[i]), float(s[j]), turn, apex))
        i = j + 1
    L = loop.length_m
    if loop.closed and len(groups) >= 2 and groups[0].start_m + L - groups[-1].end_m < MIN_RUN_M:
        first, last = groups.pop(0), groups.pop()  # one group round the start
        sharper = first if abs(first.turn_rad) > abs(last.turn_rad) else last
        apex = sharper.apex_m + (L if sharper is first else 0.0)
        groups.append(_Group(last.start_m, first.end_m + L, last.turn_rad + first.turn_rad, apex))
    return groups


def _straightest_start(loop: WallLoop, pick_s: float) -> float:
    """Arc length of the middle of the loop's longest stretch without corners (a closed
    loop is counted from there, so no corner straddles its start). Stretches as long within
    ``EQUAL_STRETCH_M`` (a block's two long sides) are told apart by the pick: the one whose
    middle is nearest it along the loop, and of those as near (a pick midway between them), the
    one whose middle comes first by x, then y; so that the proposal never depends on the
    vertex a section's loop happens to start at."""
    groups = _corner_groups(loop)
    if not groups:
        return 0.0
    L = loop.length_m
    stretches = [
        (a, (groups[(k + 1) % len(groups)].start_m - a) % L)
        for k, a in ((k, g.end_m) for k, g in enumerate(groups))
    ]
    longest = max(length for _, length in stretches)
    middles = [a + 0.5 * length for a, length in stretches if length > longest - EQUAL_STRETCH_M]

    def from_pick(m: float) -> float:
        d = (m - pick_s) % L
        return min(d, L - d)

    nearest = min(from_pick(m) for m in middles)
    tied = [m for m in middles if from_pick(m) <= nearest + EQUAL_STRETCH_M]
    xy = loop.point_at(np.array(tied))
    for axis in (0, 1):  # the least x (within EQUAL_STRETCH_M: the sampling), then y
        keep = xy[:, axis] <= xy[:, axis].min() + EQUAL_STRETCH_M
        tied, xy = [m for m, k in zip(tied, keep, strict=True) if k], xy[keep]
    return float(loop.wrap(np.array([tied[0]]))[0])


# --- the wall to follow -----------------------------------------------------------------------


def _wall_extent(
    loop: WallLoop, pick_s: float
) -> tuple[WallLoop, bool, list[_Group], float, list[str]]:
    """(wall, closed, groups on it, pick's arc length on it, notes): the picked loop, or the
    piece of it between the slot ends round the pick."""
    L = loop.length_m
    shift = _straightest_start(loop, pick_s) if loop.closed else 0.0
    groups = _corner_groups(loop, shift)
    ends = [g for g in groups if g.slot_end]
    pick = float(loop.wrap(np.array([pick_s - shift]))[0])
    if loop.closed and not ends:
        wall = WallLoop(loop.piece(shift, shift + L).points_m[:-1], loop.z_m, closed=True)
        return (wall if shift else loop), True, groups, pick, []
    if any(g.start_m - 1e-9 <= pick <= g.end_m + 1e-9 for g in ends):
        raise InvalidInputError(
            "the picked point is at the end of a slot; pick one of its side walls"
        )
    before = [g.end_m for g in ends if g.end_m <= pick]
    after = [g.start_m for g in ends if g.start_m >= pick]
    if loop.closed:  # from the slot end before the pick to the one after, maybe over the start
        a = before[-1] if before else ends[-1].end_m
        b = after[0] if after else ends[0].start_m
        b = b + L if b <= a else b
    else:
        a, b = (before[-1] if before else 0.0), (after[0] if after else L)
    wall = loop.piece(shift + a, shift + b)
    kept = [g for g in _corner_groups(wall) if not g.slot_end]
    length = f"{wall.length_m * 1e3:.0f} mm"
    note = f"the wall is open: {length} between the ends of the slot" if ends else (
        f"the wall is open ({length})"
    )  # fmt: skip
    pick_on = float(np.clip((pick - a) % L if loop.closed else pick - a, 0.0, wall.length_m))
    return wall, False, kept, pick_on, [note]


def _initial_points(
    wall: WallLoop, closed: bool, groups: list[_Group], end_margin_m: float
) -> list[tuple[float, PointKind]]:
    """Arc lengths and kinds of the first points: runs, outside corners and wall ends."""
    out: list[tuple[float, PointKind]] = []
    if closed and not groups:
        return [(wall.length_m * k / ROUND_LOOP_POINTS, "run") for k in range(ROUND_LOOP_POINTS)]
    bounds = [(g.start_m, g.end_m) for g in groups]
    if closed:
        runs = [
            (bounds[k][1], bounds[(k + 1) % len(bounds)][0] + (wall.length_m if k + 1 ==
                                                              len(bounds) else 0.0))
            for k in range(len(bounds))
        ]  # fmt: skip
    else:
        edges = [0.0, *[v for ab in bounds for v in ab], wall.length_m]
        runs = list(zip(edges[0::2], edges[1::2], strict=True))
        out.append((min(end_margin_m, 0.5 * wall.length_m), "wall end"))
    for a, b in runs:
        length = b - a
        if length >= LONG_RUN_M:
            f = LONG_RUN_END_SHARE
            out += [(a + f * length, "run"), (b - f * length, "run")]
        elif length >= MIN_RUN_M:
            out.append((a + 0.5 * length, "run"))
    for g in groups:
        if g.turn_rad <= -math.radians(OUTSIDE_CORNER_DEG):
            out.append((g.apex_m, "outside corner"))
    if not closed:
        out.append((max(wall.length_m - end_margin_m, 0.5 * wall.length_m), "wall end"))
    out = [(float(wall.wrap(np.array([s]))[0]) if closed else s, k) for s, k in out]
    out.sort(key=lambda item: item[0])
    merged: list[tuple[float, PointKind]] = []
    for s, kind in out:  # two points on top of each other: keep the corner or end
        if merged and s - merged[-1][0] < MIN_SPACING_M:
            if kind != "run":
                merged[-1] = (s, kind)
            continue
        merged.append((s, kind))
    return merged


# --- reachability -----------------------------------------------------------------------------


def reach_points(
    robot: Robot,
    Ts_base_tcp: Sequence[np.ndarray],
    *,
    q_seed: np.ndarray | None = None,
    supervisor: object | None = None,
) -> list[tuple[Reach, str, np.ndarray | None]]:
    """(reach, message, joints) per pose: the inverse kinematics from the previous pose's
    joints (the first from ``q_seed``), then the supervisor's margins when given."""
    out: list[tuple[Reach, str, np.ndarray | None]] = []
    q_prev = None if q_seed is None else np.asarray(q_seed, dtype=float)
    for k, T in enumerate(Ts_base_tcp):
        try:
            q = robot.ik(T, q_prev)
        except RobomachError as exc:
            out.append(("unreachable", str(exc), None))
            continue
        reach: Reach = "ok"
        message = ""
        if q_prev is not None and k > 0 and out and out[-1][2] is not None:
            jump = np.abs(q - q_prev)
            if float(jump.max()) > math.radians(JOINT_JUMP_DEG):
                axis = int(np.argmax(jump)) + 1
                reach, message = (
                    "near",
                    f"the arm turns axis {axis} by {math.degrees(jump.max()):.0f} deg from the "
                    "point before (a change of configuration)",
                )
        if supervisor is not None:
            reach, message = _margins(supervisor, q, reach, message)
        out.append((reach, message, q))
        q_prev = q
    return out


def _margins(supervisor: object, q: np.ndarray, reach: Reach, message: str) -> tuple[Reach, str]:
    """The supervisor's verdict at ``q``: inside a stop value is unreachable, inside a slow
    zone near (the motion there would crawl or stop)."""
    lim = supervisor.limits  # type: ignore[attr-defined]
    m = supervisor.describe(q)  # type: ignore[attr-defined]
    checks = (
        ("joint_limit_deg", "a joint limit", lim.joint_stop_rad, lim.joint_slow_rad, True),
        ("wrist_axis5_deg", "the wrist singularity", lim.wrist_stop_rad, lim.wrist_slow_rad, True),
        ("elbow_axis3_deg", "the elbow singularity", lim.elbow_stop_rad, lim.elbow_slow_rad, True),
        ("shoulder_mm", "the shoulder singularity", lim.shoulder_stop_m, lim.shoulder_slow_m,
         False),
        # The tool works beside the part: its clearance is only checked against the stop.
        ("clearance_mm", "an obstacle", lim.tool_stop_m, 0.0, False),
    )  # fmt: skip
    for key, what, stop, slow, angle in checks:
        value = m[key]
        v = math.radians(value) if angle else value * 1e-3
        shown = f"{value:.1f} {'deg' if angle else 'mm'}"
        if v <= stop:
            return "unreachable", f"at {what} ({shown})"
        if v <= slow and reach == "ok":
            reach, message = "near", f"near {what} ({shown})"
    return reach, message


# --- the public functions ---------------------------------------------------------------------


def _pick(workpiece: Workpiece, point_wobj_m: np.ndarray, normal: np.ndarray | None,
          tool_radius_m: float, settings: ProposalSettings,
          tool_reach_m: float | None) -> WallPick:  # fmt: skip
    return pick_wall(
        workpiece.cad().mesh,
        point_wobj_m,
        normal,
        tool_radius_m=tool_radius_m,
        gap_m=settings.gap_m,
        height_above_floor_m=settings.height_above_floor_m,
        tool_reach_m=tool_reach_m,
    )


def _pose(T_base_wobj: np.ndarray, p_wobj: np.ndarray, R_base: np.ndarray) -> np.ndarray:
    T = np.eye(4)
    T[:3, :3] = R_base
    T[:3, 3] = T_base_wobj[:3, :3] @ p_wobj + T_base_wobj[:3, 3]
    return T


def _placed(
    pick: WallPick, xys: Sequence[np.ndarray], T_base_wobj: np.ndarray, R_base: np.ndarray
) -> tuple[np.ndarray, np.ndarray, list[np.ndarray]]:
    """(floor-frame positions, work-object positions, base poses) of TCPs at floor-frame
    ``xys``, each at the pick's height above the floor under it."""
    xy = np.atleast_2d(np.asarray(xys, dtype=float))
    floor = np.column_stack([xy, pick.heights(xy)])
    wobj = pick.to_wobj(floor)
    return floor, wobj, [_pose(T_base_wobj, p, R_base) for p in wobj]


def tool_reach(tool: object) -> float:
    """How deep the tool reaches below its spindle body: cutter and shank [m]."""
    from ..cell import SHANK_LENGTH_M

    return float(tool.flute_length_m) + SHANK_LENGTH_M  # type: ignore[attr-defined]


def _reach(robot: Robot | None, Ts: Sequence[np.ndarray], **kw: object) -> list:
    if robot is None:  # not checked (the example operator's plan: the cell checks the motion)
        return [("ok", "", None)] * len(Ts)
    return reach_points(robot, Ts, **kw)  # type: ignore[arg-type]


def _verdict(note: str, reach: Reach, message: str) -> tuple[Reach, str]:
    """A placement's note (a groove too narrow: unreachable) with the arm's verdict."""
    if note and "too narrow" in note:
        return "unreachable", note
    return reach, message or note


def propose_guide_points(
    workpiece: Workpiece,
    robot: Robot | None,
    point_wobj_m: np.ndarray,
    normal: np.ndarray | None = None,
    *,
    tool_radius_m: float,
    settings: ProposalSettings | None = None,
    tool_rotation: np.ndarray | None = None,
    q_seed: np.ndarray | None = None,
    supervisor: object | None = None,
    tool_reach_m: float | None = 0.020,
) -> GuideProposal:
    """Guide points for the whole wall through a picked point (module docstring).

    Args:
        workpiece: The part (its CAD is used: what the user sees).
        robot: The arm, for reachability (None: not checked).
        point_wobj_m: (3,) a point on the wall, work-object frame [m]; its height above the
            floor is the points' (``walls.pick_wall`` says when it cannot be, and why).
        normal: (3,) its surface normal (out of the material); default the nearest face's.
        tool_radius_m: Ball cutter radius.
        settings: Gap, and the height where the point's own cannot be kept.
        tool_rotation: 3x3 tool orientation (base frame) whose axis is re-aimed at -z of the
            work object (``job_tool_rotation``); default the example operator's.
        q_seed: Joints to start the inverse kinematics from (the robot's now).
        supervisor: The cell's ``Supervisor`` for the margins (None: the IK alone).
        tool_reach_m: How deep the tool reaches below its body (``tool_reach``).
    """
    settings = settings or ProposalSettings()
    pick = _pick(workpiece, point_wobj_m, normal, tool_radius_m, settings, tool_reach_m)
    wall, closed, groups, pick_s, notes = _wall_extent(pick.loop, pick.s_m)
    notes = [*pick.notes, *notes]
    place = WallPlacer(wall, (pick.loop, *pick.others), tool_radius_m, settings.gap_m)
    end_margin = tool_radius_m + settings.gap_m + WALL_END_MARGIN_M
    points = _initial_points(wall, closed, groups, end_margin)
    points, added = _add_points(wall, closed, points, place, tool_radius_m)
    notes += added
    if closed:  # start at the point nearest the click: learning begins where the user pointed
        gaps = [min(abs(s - pick_s), wall.length_m - abs(s - pick_s)) for s, _ in points]
        first = int(np.argmin(gaps))
        points = points[first:] + points[:first]
    T_base_wobj = workpiece.cad().T_base_wobj
    R = job_tool_rotation(T_base_wobj, tool_rotation)
    placed = [place(s) for s, _ in points]
    floor, wobj, Ts = _placed(pick, [xy for xy, _ in placed], T_base_wobj, R)
    if np.ptp(floor[:, 2]) > UNEVEN_FLOOR_NOTE_M:
        notes.append(
            f"the floor is not level along the wall: each point stands "
            f"{(pick.z_m - pick.floor_z_m) * 1e3:.1f} mm above the floor under it"
        )
    reach = _reach(robot, Ts, q_seed=q_seed, supervisor=supervisor)
    out = []
    for k, ((s, kind), (_, note), (r, message, q)) in enumerate(
        zip(points, placed, reach, strict=True)
    ):
        r, message = _verdict(note, r, message)
        out.append(ProposedPoint(Ts[k], wobj[k], s, kind, r, message, q, floor[k]))
    proposal = GuideProposal(
        tuple(out), wall, closed, "right", pick, tuple(dict.fromkeys(notes)), T_base_wobj.copy()
    )
    return _with_leg_notes(proposal, tool_radius_m)


def teach_point(
    workpiece: Workpiece,
    robot: Robot,
    point_wobj_m: np.ndarray,
    normal: np.ndarray | None = None,
    *,
    tool_radius_m: float,
    settings: ProposalSettings | None = None,
    tool_rotation: np.ndarray | None = None,
    q_seed: np.ndarray | None = None,
    supervisor: object | None = None,
    tool_reach_m: float | None = 0.020,
) -> tuple[ProposedPoint, WallPick]:
    """The tool's place for one picked point (click to teach): beside the wall at the pick,
    ``gap`` off it on the free side, at the pick's height (or the one ``walls.pick_wall``
    changes it to, its note in the point's message), in the job's orientation."""
    settings = settings or ProposalSettings()
    pick = _pick(workpiece, point_wobj_m, normal, tool_radius_m, settings, tool_reach_m)
    place = WallPlacer(pick.loop, (pick.loop, *pick.others), tool_radius_m, settings.gap_m)
    xy, note = place(pick.s_m)
    T_base_wobj = workpiece.cad().T_base_wobj
    R = job_tool_rotation(T_base_wobj, tool_rotation)
    floor = np.array([xy[0], xy[1], pick.z_m])
    wobj = pick.to_wobj(floor)[0]
    T = _pose(T_base_wobj, wobj, R)
    ((r, message, q),) = reach_points(robot, [T], q_seed=q_seed, supervisor=supervisor)
    r, message = _verdict(note, r, message)
    message = "; ".join(m for m in (*pick.notes, message) if m)
    return ProposedPoint(T, wobj, pick.s_m, "taught", r, message, q, floor), pick


def refuse_unreachable(proposal: GuideProposal) -> None:
    """Raise ``InvalidInputError`` naming the points the arm cannot reach (none: nothing)."""
    bad = [(k + 1, p) for k, p in enumerate(proposal.points) if p.reach == "unreachable"]
    if bad:
        listed = "; ".join(f"G{k} ({p.message})" for k, p in bad[:4])
        raise InvalidInputError(
            f"{len(bad)} of the {len(proposal.points)} proposed guide points cannot be reached: "
            f"{listed}"
        )


def _counts(values: Sequence[str]) -> dict[str, int]:
    return {v: list(values).count(v) for v in dict.fromkeys(values)}


def proposal_summary(proposal: GuideProposal) -> dict:
    """The proposal in mm, for summary.json and the API."""
    return {
        "points": len(proposal.points),
        "closed": proposal.closed,
        "wall_side": proposal.wall_side,
        "wall_length_mm": round(proposal.wall.length_m * 1e3, 2),
        "height_above_floor_mm": round(proposal.height_above_floor_m * 1e3, 3),
        "height_wobj_mm": round(float(proposal.points[0].position_wobj_m[2]) * 1e3, 3),
        "floor_tilt_deg": round(math.degrees(math.acos(
            min(1.0, float(proposal.pick.T_wobj_floor[2, 2])))), 2),
        "kinds": _counts([p.kind for p in proposal.points]),
        "reach": _counts([p.reach for p in proposal.points]),
        "notes": list(proposal.notes),
    }  # fmt: skip


def move_point(
    proposal: GuideProposal,
    index: int,
    point_wobj_m: np.ndarray,
    robot: Robot,
    *,
    tool_radius_m: float,
    gap_m: float,
    supervisor: object | None = None,
) -> GuideProposal:
    """The proposal with point ``index`` moved to where ``point_wobj_m`` (any point, work-object
    frame) projects on the wall: dragged along it, it stays ``gap_m`` off the wall, at the
    machining height above the floor under it."""
    if not 0 <= index < len(proposal.points):
        raise InvalidInputError(f"no proposed point G{index + 1}; there are {len(proposal.points)}")
    pick, wall = proposal.pick, proposal.wall
    xy = pick.to_floor(np.asarray(point_wobj_m, dtype=float).reshape(3))[0, :2]
    s = float(wall.project(xy[None])[0])
    place = WallPlacer(wall, (pick.loop, *pick.others), tool_radius_m, gap_m)
    foot_xy, note = place(s)
    old = proposal.points[index]
    floor, wobj, (T,) = _placed(pick, [foot_xy], proposal.T_base_wobj, old.T_base_tcp[:3, :3])
    seed = next(
        (p.joints_rad for p in proposal.points[:index][::-1] if p.joints_rad is not None),
        old.joints_rad,
    )
    ((r, message, q),) = reach_points(robot, [T], q_seed=seed, supervisor=supervisor)
    r, message = _verdict(note, r, message)
    moved = ProposedPoint(T, wobj[0], s, old.kind, r, message, q, floor[0])
    points = list(proposal.points)
    points[index] = moved
    return _with_leg_notes(
        replace(proposal, points=_in_wall_order(points, proposal)), tool_radius_m
    )


def _in_wall_order(points: list[ProposedPoint], proposal: GuideProposal) -> tuple:
    """The points in order along the wall (a point dragged past its neighbours takes its place
    among them); a closed wall keeps its first point first."""
    if not proposal.closed:
        return tuple(sorted(points, key=lambda p: p.s_m))
    s0, length = points[0].s_m, proposal.wall.length_m
    return tuple(sorted(points, key=lambda p: (p.s_m - s0) % length))


def delete_point(proposal: GuideProposal, index: int, *, tool_radius_m: float) -> GuideProposal:
    """The proposal without point ``index`` (its notes say which legs now need a point)."""
    if not 0 <= index < len(proposal.points):
        raise InvalidInputError(f"no proposed point G{index + 1}; there are {len(proposal.points)}")
    if len(proposal.points) <= 2:
        raise InvalidInputError("a proposal keeps at least 2 points; discard it instead")
    fewer = replace(proposal, points=proposal.points[:index] + proposal.points[index + 1 :])
    return _with_leg_notes(fewer, tool_radius_m)


def leg_problems(proposal: GuideProposal, tool_radius_m: float) -> list[str]:
    """A sentence per leg whose cutter would cut into the wall or that leaves it too far
    (``MAX_LEG_GAP_M``): after edits, or where the planner had no room for a point."""
    wall, pts = proposal.wall, proposal.points
    out = []
    legs = len(pts) if proposal.closed else len(pts) - 1
    for k in range(legs):
        j = (k + 1) % len(pts)
        a, b = pts[k], pts[j]
        pa, pb = a.position_floor_m, b.position_floor_m
        assert pa is not None and pb is not None  # the planner places every point it proposes
        at = _leg_problem(wall, tool_radius_m, pa[:2], pb[:2], a.s_m, b.s_m, 0.0)
        if at is not None:
            x, y, _ = (
                proposal.pick.to_wobj(np.array([*wall.point_at(np.array([at]))[0], wall.z_m]))[0]
                * 1e3
            )
            out.append(
                f"the leg G{k + 1}-G{j + 1} leaves the wall near ({x:.1f}, {y:.1f}) mm: add a "
                "point there (or undo the edit)"
            )
    return out


def _with_leg_notes(proposal: GuideProposal, tool_radius_m: float) -> GuideProposal:
    kept = [n for n in proposal.notes if not n.startswith("the leg G")]
    return replace(proposal, notes=tuple(kept + leg_problems(proposal, tool_radius_m)))
