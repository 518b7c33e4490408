"""Which wall to follow: the side of travel the wall lies on, never a guess (issue 14).

PROBLEM   Path learning presses the tool sideways against the wall (along Yp, chapter section
          3.2); it must know on which side of the route the wall is. A vote of the force recorded
          at the guide points decides it when the operator pushed the tool against the wall, but
          points recorded free (1-3 mm off the wall, as the rules allow) vote with the sensor's
          noise (+-0.5 N): in a 5 mm groove that learned the other wall three runs in seven.
STRATEGY  The side is a setting ("left", "right" of travel, looking along the tool axis into the
          part). "auto" decides only from evidence that cannot be noise:
            - force: the force across the tool axis at a point, resolved across its leg, is a
              vote when it is at least ``WALL_FORCE_CLEAR_N``; the votes decide when at least
              ``MIN_FORCE_VOTES`` are clear and none points the other way;
            - the part's mesh (the CAD, when known): the nearest wall face to each point lies on
              one side of its leg; a point votes when that wall is within ``MAX_WALL_GAP_M`` and
              nearer than the wall on the other side by ``NEARER_MARGIN_M``; the votes decide when
              at least half the points vote and ``MESH_MAJORITY`` of them agree.
          Evidence that disagrees (forces one way, the mesh the other; or points on opposite
          walls) is refused with the points named, and so is no evidence at all.
SOLUTION  ``resolve_wall_side(guides, setting, *, closed, workpiece, tool_radius_m)`` returns a
          ``WallSideDecision`` (side, source, why) or raises ``WallSideError`` whose message says
          what to do.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass
from typing import Literal, get_args

import numpy as np

from .. import mesh_query
from ..errors import InvalidInputError, WallSideError
from ..leadthrough import GuidePoint
from ..workpiece import Workpiece

WallSide = Literal["left", "right"]
WallSideSetting = Literal["auto", "left", "right"]
WALL_SIDE_CHOICES: tuple[str, ...] = get_args(WallSideSetting)
WALL_FORCE_CLEAR_N = 2.0  # a force across the leg this large is a push, not the sensor's noise
MIN_FORCE_VOTES = 2  # clear pushes needed (all of them when fewer guide points)
MAX_WALL_GAP_M = 0.005  # a wall farther than this from a point is not the one it was taught on
NEARER_MARGIN_M = 0.00025  # the nearer wall must be nearer by this for a point to vote
MESH_MAJORITY = 0.75  # of the voting points on one side, and votes from half the points


@dataclass(frozen=True)
class WallSideDecision:
    """The side of travel the wall is on, and what decided it.

    Attributes:
        side: "left" or "right" of travel, looking along the tool axis into the part.
        source: "setting", "force" or "mesh".
        detail: One line for the operator (what the evidence was).
    """

    side: WallSide
    source: Literal["setting", "force", "mesh"]
    detail: str

    @property
    def sign(self) -> float:
        """+1 for the right, -1 for the left (``Yp = sign * (Zp x Xp)``)."""
        return 1.0 if self.side == "right" else -1.0


def mean_tool_axis(guides: Sequence[GuidePoint]) -> np.ndarray:
    """Unit mean of the guide points' tool axes (the axis the run's height is measured on)."""
    axes = np.array([g.T_base_tcp[:3, 2] for g in guides])
    u = axes.sum(axis=0)
    n = float(np.linalg.norm(u))
    return u / n if n > 1e-9 else axes[0]


def travel_directions(guides: Sequence[GuidePoint], closed: bool, axis: np.ndarray) -> np.ndarray:
    """(n, 3) unit direction of travel at each guide point, across ``axis``: the mean of its
    incoming and outgoing legs (one leg at the ends of an open route). Where the two legs
    nearly reverse (a closed route of points along one side comes back along it), the point
    keeps the leg that arrives at it (the first point, the leg that leaves it): their mean
    would point nowhere."""
    pts = np.array([g.position_m for g in guides])
    n = len(pts)
    out = np.zeros((n, 3))
    for k in range(n):
        legs = []
        if k > 0 or closed:
            legs.append(pts[k] - pts[k - 1])
        if k < n - 1 or closed:
            legs.append(pts[(k + 1) % n] - pts[k])
        units = []
        for leg in legs:
            leg = leg - axis * (leg @ axis)
            norm = float(np.linalg.norm(leg))
            if norm > 1e-9:
                units.append(leg / norm)
        if not units:
            continue
        d = np.sum(units, axis=0)
        if len(units) == 2 and float(units[0] @ units[1]) < -0.5:  # a U-turn at this point
            d = units[1] if k == 0 else units[0]
        out[k] = d / float(np.linalg.norm(d))
    return out


def force_votes(guides: Sequence[GuidePoint], closed: bool) -> np.ndarray:
    """(n,) force across each point's leg towards its right [N]: > 0 when the wall pushed the
    tool from the right (the wall is on the right), < 0 from the left."""
    axis = mean_tool_axis(guides)
    dirs = travel_directions(guides, closed, axis)
    votes = np.zeros(len(guides))
    for k, (g, d) in enumerate(zip(guides, dirs, strict=True)):
        right = np.cross(axis, d)  # Yp of the right side: Zp x Xp
        votes[k] = -float(np.asarray(g.force_N, dtype=float) @ right)
    return votes


def mesh_wall_gaps(
    guides: Sequence[GuidePoint],
    closed: bool,
    workpiece: Workpiece,
    tool_radius_m: float,
) -> tuple[np.ndarray, np.ndarray]:
    """The cutter's gap [m] to the nearest wall on the right and on the left of each point.

    Measured in the part's mesh across the tool axis: the nearest point of a wall face, and a
    ray the other way for the wall across (``inf`` when there is none within reach).

    Returns:
        (n,) gaps on the right and (n,) on the left.
    """
    T = workpiece.T_base_wobj
    R, t = T[:3, :3], T[:3, 3]
    axis = mean_tool_axis(guides)
    axis_w = R.T @ axis
    walls = mesh_query.wall_faces(workpiece.mesh, axis_w)
    n = len(guides)
    right_gap = np.full(n, np.inf)
    left_gap = np.full(n, np.inf)
    if walls is None:
        return right_gap, left_gap
    dirs = travel_directions(guides, closed, axis)
    pts_w = (np.array([g.position_m for g in guides]) - t) @ R
    with np.errstate(divide="ignore", invalid="ignore"):
        closest, dist, _ = mesh_query.closest_point(walls, pts_w)
    for k in range(n):
        right_w = R.T @ np.cross(axis, dirs[k])
        rel = closest[k] - pts_w[k]
        rel = rel - axis_w * (rel @ axis_w)
        gap = float(dist[k]) - tool_radius_m
        on_right = float(rel @ right_w) > 0.0
        (right_gap if on_right else left_gap)[k] = gap
        # The wall across: a ray the other way, at the point's height.
        other = -right_w if on_right else right_w
        hits, _, _ = mesh_query.ray_hits(walls, pts_w[k : k + 1], other[None, :])
        if len(hits):
            d_other = float(np.min(np.linalg.norm(hits - pts_w[k], axis=1))) - tool_radius_m
            (left_gap if on_right else right_gap)[k] = max(d_other, gap)
    return right_gap, left_gap


def _wall_point(
    position_m: np.ndarray,
    travel: np.ndarray,
    side: float,
    workpiece: Workpiece,
    axis: np.ndarray,
    reach_m: float,
) -> np.ndarray | None:
    """The nearest wall point (base frame) on the ``side`` (+1 right, -1 left) of ``travel``
    from ``position_m``, across ``axis``; None when none lies within ``reach_m``."""
    T = workpiece.T_base_wobj
    R, t = T[:3, :3], T[:3, 3]
    axis_w = R.T @ axis
    walls = mesh_query.wall_faces(workpiece.mesh, axis_w)
    if walls is None:
        return None
    p_w = R.T @ (np.asarray(position_m, dtype=float) - t)
    towards_side = R.T @ (np.cross(axis, travel) * side)
    with np.errstate(divide="ignore", invalid="ignore"):
        closest, dist, _ = mesh_query.closest_point(walls, p_w[None, :])
    rel = closest[0] - p_w
    rel = rel - axis_w * (rel @ axis_w)
    if float(np.linalg.norm(rel)) > 1e-9 and float(rel @ towards_side) > 0.0:
        if dist[0] <= reach_m:
            return R @ closest[0] + t
    hits, _, _ = mesh_query.ray_hits(walls, p_w[None, :], towards_side[None, :])
    if len(hits):
        k = int(np.argmin(np.linalg.norm(hits - p_w, axis=1)))
        if float(np.linalg.norm(hits[k] - p_w)) <= reach_m:
            return R @ hits[k] + t
    return None


def wall_direction(
    guide: GuidePoint,
    travel: np.ndarray,
    side: float,
    workpiece: Workpiece,
    axis: np.ndarray,
) -> np.ndarray | None:
    """(3,) unit direction, across ``axis``, from ``guide`` to the nearest wall on the ``side``
    (+1 right, -1 left) of ``travel`` in the part's mesh; None when none is near."""
    point = _wall_point(guide.position_m, travel, side, workpiece, axis, 2 * MAX_WALL_GAP_M)
    if point is None:
        return None
    rel = point - guide.position_m
    rel = rel - axis * float(rel @ axis)
    norm = float(np.linalg.norm(rel))
    return rel / norm if norm > 1e-9 else None


def taught_wall_points(
    guides: Sequence[GuidePoint],
    side: str,
    *,
    closed: bool,
    workpiece: Workpiece,
    tool_radius_m: float,
) -> list[np.ndarray | None]:
    """The wall point each guide point was taught on (base frame): the nearest wall on its side
    of travel in the part's mesh, within ``MAX_WALL_GAP_M`` of the cutter; None where none is.
    What the scene highlights before a run, and what the score checks the program touches."""
    axis = mean_tool_axis(guides)
    dirs = travel_directions(guides, closed, axis)
    sign = 1.0 if side == "right" else -1.0
    reach = MAX_WALL_GAP_M + tool_radius_m
    return [
        _wall_point(g.position_m, d, sign, workpiece, axis, reach)
        for g, d in zip(guides, dirs, strict=True)
    ]


def _points(numbers: Sequence[int]) -> str:
    return ", ".join(f"G{k + 1}" for k in numbers)


def resolve_wall_side(
    guides: Sequence[GuidePoint],
    setting: str,
    *,
    closed: bool = True,
    workpiece: Workpiece | None = None,
    tool_radius_m: float | None = None,
) -> WallSideDecision:
    """The side of the wall to follow (module docstring).

    Args:
        guides: The guide points in order.
        setting: "left", "right" or "auto".
        closed: The route returns to the first point.
        workpiece: The part's mesh as the user sees it (the CAD), or None.
        tool_radius_m: Ball cutter radius (with ``workpiece``).

    Raises:
        WallSideError: "auto" and no clear, consistent evidence.
    """
    if setting in ("left", "right"):
        return WallSideDecision(setting, "setting", f"the wall is on the {setting} (as set)")
    if setting != "auto":
        raise InvalidInputError(f"wall side must be one of {', '.join(WALL_SIDE_CHOICES)}")
    if len(guides) < 2:
        raise WallSideError("the wall side needs at least 2 guide points")
    votes = force_votes(guides, closed)
    clear = np.abs(votes) >= WALL_FORCE_CLEAR_N
    right_pushes = np.flatnonzero(clear & (votes > 0))
    left_pushes = np.flatnonzero(clear & (votes < 0))
    force_side: WallSide | None = None
    if len(right_pushes) and len(left_pushes):
        raise WallSideError(
            f"the guide points were pushed against walls on both sides of the route "
            f"({_points(right_pushes)} on the right, {_points(left_pushes)} on the left): "
            "set the wall side, or record them again pushing towards the one wall to follow"
        )
    needed = min(MIN_FORCE_VOTES, len(guides))
    if len(right_pushes) >= needed:
        force_side = "right"
    elif len(left_pushes) >= needed:
        force_side = "left"
    mesh_side: WallSide | None = None
    mesh_detail = ""
    if workpiece is not None and tool_radius_m is not None:
        right_gap, left_gap = mesh_wall_gaps(guides, closed, workpiece, tool_radius_m)
        votes_right = (right_gap <= MAX_WALL_GAP_M) & (right_gap + NEARER_MARGIN_M < left_gap)
        votes_left = (left_gap <= MAX_WALL_GAP_M) & (left_gap + NEARER_MARGIN_M < right_gap)
        n_r, n_l = int(votes_right.sum()), int(votes_left.sum())
        decided = max(n_r, n_l) >= MESH_MAJORITY * (n_r + n_l)
        if n_r + n_l >= math.ceil(len(guides) / 2) and decided:
            mesh_side = "right" if n_r > n_l else "left"
            mesh_detail = (
                f"{max(n_r, n_l)} of {len(guides)} points are nearer the wall on the {mesh_side}"
            )
        elif n_r and n_l and force_side is None:
            raise WallSideError(
                f"the guide points sit nearer walls on both sides of the route "
                f"({_points(np.flatnonzero(votes_right))} nearer the right, "
                f"{_points(np.flatnonzero(votes_left))} nearer the left): set the wall side, "
                "or move them nearer the one wall to follow"
            )
    if force_side is not None:
        if mesh_side is not None and mesh_side != force_side:
            raise WallSideError(
                f"the guide points were pushed by a wall on the {force_side}, but the part's "
                f"mesh puts the nearest wall on the {mesh_side}: set the wall side"
            )
        pushes = right_pushes if force_side == "right" else left_pushes
        return WallSideDecision(
            force_side,
            "force",
            f"the wall pushed back from the {force_side} at {_points(pushes)}",
        )
    if mesh_side is not None:
        return WallSideDecision(mesh_side, "mesh", mesh_detail)
    raise WallSideError(
        "cannot tell which wall to follow: the guide points were not pushed against a wall "
        f"(at least {WALL_FORCE_CLEAR_N:g} N at {needed} points)"
        + (" and they are not clearly nearer one wall of the part" if workpiece is not None else "")
        + ": set the wall side (left or right of travel, looking along the tool into the "
        "part), or record the points with a light push towards the wall"
    )
