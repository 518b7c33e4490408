"""The route path learning runs, planned from the guide points and the part as the user sees it.

PROBLEM   The guide points give the route and the tool's orientation; the wall gives the
          position by force (chapter section 3.1). Two things about the route cannot come from
          force alone before the run starts: which side of the route the wall is on when the
          points were recorded free of it, and how high to run where a point rests on the floor
          of a groove (a touch-off along -Z leaves it there, and dragged along the floor the
          cutter presses on two faces at once).
STRATEGY  With the part's mesh (the CAD the user teaches on, when known): the wall side from
          ``wall_side.resolve_wall_side``; under each point, the floor found by a ray along the
          tool axis, and the point lifted until the cutter clears it by the machining height
          (``PathLearningSettings.floor_clearance_m``). Without a mesh: the side from the pushes
          alone, and the run's own floor guard (a force along the axis lifts it).
          And per leg, how far the taught wall between its two points runs from the straight
          leg (the section at the points' height, followed on the wall's side): the run's
          protection lets the tool that far off the leg (a leg through the part, whose wall
          runs round a corner far from it, is not a point on another wall).
SOLUTION  ``plan_route(guides, settings, *, workpiece, tool_radius_m) -> LearningRoute``: the
          guide points as learned (lifted where needed), the side and why, what was lifted,
          and the legs' wander allowances.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from .. import mesh_query
from ..leadthrough import GuidePoint
from ..workpiece import Workpiece
from .run import LEG_DETOUR_EXTRA_M, LEG_DETOUR_FACTOR, PathLearningSettings
from .side import (
    WallSideDecision,
    mean_tool_axis,
    resolve_wall_side,
    travel_directions,
    wall_direction,
)

FLOOR_SEARCH_M = 0.01  # a floor farther than this below a point is not the one it rests on
WANDER_MARGIN_M = 0.01  # a leg's wall may lead the tool this much farther off it than the mesh's
WALL_MATCH_M = 0.006  # a point is on a section's wall within this (its gap, the cutter's radius)


@dataclass(frozen=True)
class LearningRoute:
    """The route a run follows.

    Attributes:
        guides: The guide points as learned: positions lifted off the floor where they rested
            on it; orientations, joints and forces as recorded.
        wall_side: The side of the wall and what decided it.
        lifted_m: (n,) how far each point was lifted [m] (0 where it was clear of the floor).
        start_towards_wall: (3,) from the first point towards the wall it was taught on (the
            mesh's nearest wall face on the wall's side), or None without a mesh.
        leg_wander_m: {(i, j): m}: how far the wall from guide point i to j (0-based) runs
            from the leg between them, plus ``WANDER_MARGIN_M``, where the mesh tells it.
    """

    guides: tuple[GuidePoint, ...]
    wall_side: WallSideDecision
    lifted_m: np.ndarray
    start_towards_wall: np.ndarray | None = None
    leg_wander_m: dict[tuple[int, int], float] | None = None


def floor_clearances(
    guides: Sequence[GuidePoint], workpiece: Workpiece, tool_radius_m: float
) -> np.ndarray:
    """(n,) gap [m] between the cutter and the floor below each point, along the mean tool
    axis (``inf`` where no floor lies within ``FLOOR_SEARCH_M``; negative: into the floor)."""
    T = workpiece.T_base_wobj
    R, t = T[:3, :3], T[:3, 3]
    axis_w = R.T @ mean_tool_axis(guides)
    pts_w = (np.array([g.position_m for g in guides]) - t) @ R
    # From 2 r above the point, along the axis (into the part): the first face met below.
    origins = pts_w - axis_w * 2.0 * tool_radius_m
    directions = np.repeat(axis_w[None, :], len(pts_w), axis=0)
    out = np.full(len(pts_w), np.inf)
    hits, rays, _ = mesh_query.ray_hits(workpiece.mesh, origins, directions)
    for p, k in zip(hits, rays, strict=True):
        along = float((p - origins[k]) @ axis_w) - 2.0 * tool_radius_m  # below the centre
        gap = along - tool_radius_m
        if along > -tool_radius_m and gap < FLOOR_SEARCH_M:
            out[k] = min(out[k], gap)
    return out


def plan_route(
    guides: Sequence[GuidePoint],
    settings: PathLearningSettings,
    *,
    workpiece: Workpiece | None = None,
    tool_radius_m: float | None = None,
) -> LearningRoute:
    """The route for ``guides`` (module docstring).

    Raises:
        WallSideError: the side is "auto" and neither the pushes nor the mesh tell it.
    """
    guides = tuple(guides)
    decision = resolve_wall_side(
        guides,
        settings.wall_side,
        closed=settings.closed,
        workpiece=workpiece,
        tool_radius_m=tool_radius_m,
    )
    lifted = np.zeros(len(guides))
    if workpiece is None or tool_radius_m is None or not guides:
        return LearningRoute(guides, decision, lifted)
    gaps = floor_clearances(guides, workpiece, tool_radius_m)
    axis = mean_tool_axis(guides)
    out = []
    for k, g in enumerate(guides):
        need = settings.floor_clearance_m - float(gaps[k])
        if np.isfinite(gaps[k]) and need > 1e-6:
            T = g.T_base_tcp.copy()
            T[:3, 3] = T[:3, 3] - axis * need
            g = GuidePoint(T, g.joints_rad, g.time_s, g.force_N)
            lifted[k] = need
        out.append(g)
    travel = travel_directions(out, settings.closed, axis)[0]
    start = wall_direction(out[0], travel, decision.sign, workpiece, axis)
    wander = leg_wander(out, settings.closed, decision.side, workpiece, axis)
    return LearningRoute(tuple(out), decision, lifted, start, wander)


def leg_wander(
    guides: Sequence[GuidePoint],
    closed: bool,
    side: str,
    workpiece: Workpiece,
    axis: np.ndarray,
) -> dict[tuple[int, int], float]:
    """For each leg whose two points stand by the same wall of the part's section at their
    mean height: the farthest that wall, followed from one to the other on ``side`` (the
    section's loops run with the material on their right), comes from the leg's line, plus
    ``WANDER_MARGIN_M``. Empty when the tool axis is not the part's z axis."""
    from .walls import section_loops

    T = workpiece.T_base_wobj
    R, t = T[:3, :3], T[:3, 3]
    if abs(float((R.T @ axis)[2])) < 0.99:
        return {}
    p = (np.array([g.position_m for g in guides]) - t) @ R
    loops = [lp for lp in section_loops(workpiece.mesh, float(np.mean(p[:, 2]))) if lp.closed]
    if not loops:
        return {}
    gaps = np.array([np.abs(lp.signed_distance(p[:, :2])) for lp in loops])
    nearest = np.argmin(gaps, axis=0)
    out: dict[tuple[int, int], float] = {}
    order = list(range(len(guides))) + ([0] if closed else [])
    for i, j in zip(order[:-1], order[1:], strict=True):
        k = int(nearest[i])
        if k != nearest[j] or max(gaps[k, i], gaps[k, j]) > WALL_MATCH_M:
            continue
        loop = loops[k]
        s_i, s_j = loop.project(p[[i, j], :2])
        wall = loop.piece(s_i, s_j) if side == "right" else loop.piece(s_j, s_i)
        chord = p[j, :2] - p[i, :2]
        length = float(np.linalg.norm(chord))
        if length < 1e-4 or wall.length_m > LEG_DETOUR_FACTOR * length + LEG_DETOUR_EXTRA_M:
            continue  # a wall the run's detour protection stops on anyway: no allowance
        rel = wall.points_m - p[i, :2]
        off = np.abs(rel[:, 0] * chord[1] - rel[:, 1] * chord[0]) / length
        out[(i, j)] = float(off.max()) + WANDER_MARGIN_M
    return out
