"""The walk: the ideal run on the mesh before any motion, and where a leg ends for the walk
and the run alike.

PROBLEM   Before the robot moves, the route must be shown to be one the wall can give (a slot
          taught as a loop comes back along the slot's other wall), each leg's protection must
          know how far its wall leads the tool off the leg, and each guide point's side of
          travel and the height's progress must follow the wall, not the chord between points
          (docs/learning_model.md, "the route").
STRATEGY  A ball of the cutter's radius rolled along the mesh's wall on the route's side at the
          route's heights, leg by leg, each ending where the run's would (``LegEnd``); the
          walk's point beside each guide point gives its travel and the legs' height chords.
SOLUTION  ``walk_route(...) -> [LegWalk]``, ``open_wall_return``, ``unreached_sentence``,
          ``walk_beside``, ``walk_travel``, ``walked_legs``, ``LegEnd``.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass, replace
from typing import TYPE_CHECKING

import numpy as np

from ..transforms import arc_length_m
from . import thresholds as th
from .law import route_height
from .part_walls import PartWalls

if TYPE_CHECKING:
    from ..cell import GuidePoint
    from .route import HeightReference, Leg


class LegEnd:
    """Where a leg ends, the same for the run and the walk: at ``LEG_END_MARGIN_M`` before its
    guide point's plane within ``PLANE_END_WITHIN_M`` + the cutter's radius of the point, or at
    the nearest approach to its point (within ``NEAR_END_M``, receding ``END_PASSED_M``); the
    last leg of a closed route at the nearest approach to where the contact first held the set
    force (the force filter keeps the recording from about there, so the loop's end overlaps
    its program's start), within the cutter's radius + ``CLOSE_LOOP_M`` (a contact on a corner
    is anywhere on the cutter's arc round it, up to a radius off the faces' path), receding
    ``CLOSE_PASSED_M``; of an open one at the nearest approach to its last point; either
    ``CLOSE_LOOP_OVERRUN_M`` past the plane at the latest (a loop's, once it has come within
    ``NEAR_END_M`` of its start). The nearest approach is watched over the leg's last
    ``NEAR_END_M`` (half of it at least), and over the whole of a leg shorter than that, but
    not where the tool has gone back along the leg by more than ``END_PASSED_M`` (and more than
    sideways) from where it started it."""

    def __init__(
        self, leg: Leg, axis: np.ndarray, *, last: bool, closed: bool, tool_radius_m: float
    ) -> None:
        self.leg, self.axis, self.last, self.closed = leg, axis, last, closed
        self.close_within_m = tool_radius_m + th.CLOSE_LOOP_M
        self.plane_within_m = tool_radius_m + th.PLANE_END_WITHIN_M
        self.end_best = math.inf
        self.close_best = math.inf
        L = leg.length
        # the progress from which the nearest approach to the end point is watched: on a leg
        # shorter than NEAR_END_M from its start (its chord may run across the wall, a point
        # taught off it beside a neighbour on it, and progress along it never comes)
        self.near_from_m = max(L - th.NEAR_END_M, 0.5 * L) if L > th.NEAR_END_M else -math.inf
        self.first_s: float | None = None  # the progress where the leg's end was first asked
        self.first_p: np.ndarray | None = None  # ... and the tool's place there
        #: the progress along the leg before which ``reached`` is False (the run skips it)
        self.watch_from_m = 0.5 * L if last and closed else self.near_from_m

    def _across(self, v: np.ndarray) -> float:
        along = float(v @ self.axis)
        return math.sqrt(max(float(v @ v) - along * along, 0.0))

    def reached(self, p: np.ndarray, s: float, start: np.ndarray | None) -> bool:
        """True when the leg ends at ``p`` (progress ``s`` along it); ``start``: where the
        contact first held the set force (a closed route's last leg closes there), None before."""
        L = self.leg.length
        if self.last and self.closed and start is not None:
            if s >= 0.5 * L:
                gap = self._across(p - start)
                near = self.close_best < self.close_within_m
                if near and gap > self.close_best + th.CLOSE_PASSED_M:
                    return True
                self.close_best = min(self.close_best, gap)
            # past the plane only once it has come near the start: a closing chord across a
            # sparse loop has its plane well before the start where the wall bulges past it
            return s >= L + th.CLOSE_LOOP_OVERRUN_M and self.close_best < th.NEAR_END_M
        passed = False
        if self.first_s is None or self.first_p is None:
            self.first_s, self.first_p = s, p.copy()
        # the nearest approach counts only while the tool has not gone back along the leg,
        # more back than sideways: a short leg's is watched from its start, and a walk that set
        # off the wrong way (round a slot's end from a first point by its other wall) "passed"
        # its end within 1.5 mm; a leg across the wall (a point a gap off it, leaning back
        # along it) is walked sideways to it, and ends as the tool passes its point
        back_m = self.first_s - s
        back = back_m > th.END_PASSED_M and back_m > math.sqrt(
            max(self._across(p - self.first_p) ** 2 - back_m * back_m, 0.0)
        )
        if s >= self.near_from_m and not back:
            d_end = self._across(p - self.leg.b)
            passed = self.end_best < th.NEAR_END_M and d_end > self.end_best + th.END_PASSED_M
            self.end_best = min(self.end_best, d_end)
        if self.last:
            return passed or s >= L + th.CLOSE_LOOP_OVERRUN_M
        at_plane = s >= L - min(th.LEG_END_MARGIN_M, 0.25 * L)
        return passed or (at_plane and self._across(p - self.leg.b) <= self.plane_within_m)


# --- the walk: the ideal run on the mesh ---------------------------------------------------------


@dataclass(frozen=True)
class LegWalk:
    """The walk of one leg: its tool-centre points, how far they run from the leg's line, and
    whether it reached its end."""

    points_m: np.ndarray
    towards_m: np.ndarray  # (k, 3) unit, across the axis, from each point towards its wall
    wander_m: float
    length_m: float
    reached: bool
    over_top_m: float = 0.0  # walked with the cutter's centre over the wall's top edge
    off_floor_m: float = 0.0  # walked with no floor under the tool (floor mode only)


def walk_route(
    legs: Sequence[Leg],
    heights: HeightReference,
    offsets: Sequence[tuple[float, float]],
    sign: float,
    walls: PartWalls,
    start: np.ndarray,
    *,
    closed: bool,
) -> list[LegWalk]:
    """A ball of the cutter's radius rolled along the mesh's wall on the side ``sign`` from
    ``start`` (the first point's wall point's foot), at the route's heights, leg after leg,
    ending each where the run would (``LegEnd``); a leg whose wall runs past the run's detour
    protection ends there, not reached."""
    axis, r = walls.axis, walls.radius
    p = start.copy()
    out: list[LegWalk] = []
    c, _ = walls.nearest(p[None])
    w0 = c[0] - p - axis * float((c[0] - p) @ axis)
    t0 = sign * cross3(w0 / max(float(np.linalg.norm(w0)), 1e-12), axis)
    ref = heights.at(p, t0, w0 / max(float(np.linalg.norm(w0)), 1e-12))
    since_ref = 0.0
    measured_at, measured = [p.copy()], [ref]
    for k, leg in enumerate(legs):
        row = leg.row(offsets[k])
        end = LegEnd(leg, axis, last=k == len(legs) - 1, closed=closed, tool_radius_m=r)
        limit = th.LEG_DETOUR_FACTOR * leg.length + th.LEG_DETOUR_EXTRA_M
        pts: list[np.ndarray] = []
        towards: list[np.ndarray] = []
        walked, reached, over_top, off_floor = 0.0, False, 0.0, 0.0
        while walked <= limit:
            for _ in range(2):  # onto the wall, then to the route's height
                c, d = walls.nearest(p[None])
                if not math.isfinite(d[0]) or d[0] > th.AT_WALL_GAP_M + r:
                    lost = LegWalk(np.array(pts or [p]), np.array(towards or [np.zeros(3)]),
                                   math.inf, walked, False)  # fmt: skip
                    return [*out, lost]
                n = (c[0] - p) / max(float(d[0]), 1e-12)
                p = c[0] - n * r
                p = p + axis * (route_height(row, ref, p, axis) - float(p @ axis))
            if float(n @ axis) > th.OVER_TOP_SIN:  # the wall's nearest point well below the centre
                over_top += th.WALK_STEP_M
            w = n - axis * float(n @ axis)
            w /= max(float(np.linalg.norm(w)), 1e-12)
            pts.append(p.copy())
            towards.append(w)
            t = sign * cross3(w, axis)
            if len(pts) > 1 and float(np.linalg.norm(pts[-1] - pts[-2])) < 0.25 * th.WALK_STEP_M:
                # held in an inside corner: the wall ahead along t is the one to follow now
                c, d = walls.nearest((p + t * th.WALK_STEP_M)[None])
                ahead = c[0] - p - axis * float((c[0] - p) @ axis)
                if float(np.linalg.norm(ahead)) > 1e-12 and float(ahead @ t) > 0.0:
                    w = ahead / float(np.linalg.norm(ahead))
                    t = sign * cross3(w, axis)
            if end.reached(p, float((p - leg.a) @ leg.xp), start):
                reached = True
                break
            p = p + t * th.WALK_STEP_M
            walked += th.WALK_STEP_M
            since_ref += th.WALK_STEP_M
            if since_ref >= th.REFERENCE_SPACING_M:
                ref, since_ref = heights.at(p, t, w), 0.0
                if heights.mode == "floor" and not heights.found:
                    off_floor += th.REFERENCE_SPACING_M
                else:
                    measured_at.append(p.copy())
                    measured.append(ref)
        arr = np.array(pts)
        rel = arr - leg.a
        along = rel @ leg.xp
        off = np.sqrt(np.maximum(np.einsum("ij,ij->i", rel, rel) - along**2, 0.0))
        out.append(
            LegWalk(arr, np.array(towards), float(off.max()), walked, reached, over_top, off_floor)
        )
        if not reached:
            break
    heights.remember(np.array(measured_at), np.array(measured))
    return out


def walk_beside(
    guides: Sequence[GuidePoint], legs: Sequence[Leg], walks: Sequence[LegWalk], axis: np.ndarray
) -> list[tuple[np.ndarray, np.ndarray] | None]:
    """For each guide point, the walk's point nearest it across the axis and the walk's wall
    direction there, on the legs to and from it (else on any leg), where that is within
    ``AT_WALL_GAP_M``; None elsewhere and without a walk."""
    out: list[tuple[np.ndarray, np.ndarray] | None] = [None] * len(guides)
    every = [w for w in walks if len(w.points_m)]
    for k, g in enumerate(guides):
        adjacent = [w for leg, w in zip(legs, walks, strict=False)
                    if k in (leg.first, leg.last) and len(w.points_m)]  # fmt: skip
        for near in (adjacent, every):  # a leg's walk may end before its point: then any leg's
            if not near:
                continue
            pts = np.vstack([w.points_m for w in near])
            towards = np.vstack([w.towards_m for w in near])
            rel = pts - g.position_m
            across = np.linalg.norm(rel - np.outer(rel @ axis, axis), axis=1)
            j = int(np.argmin(across))
            if across[j] <= th.AT_WALL_GAP_M and np.any(towards[j]):
                out[k] = (pts[j], towards[j])
                break
    return out


def walked_legs(
    legs: Sequence[Leg], beside: Sequence[tuple[np.ndarray, np.ndarray] | None], axis: np.ndarray
) -> tuple[Leg, ...]:
    """The legs with the walk's points beside their guide points (``Leg.height_chord``), the
    second at the first's height: the chord runs across the axis, as the legs do."""
    out = []
    for leg in legs:
        a, b = beside[leg.first], beside[leg.last]
        if a is None or b is None:
            out.append(leg)
            continue
        b_across = b[0] - axis * float((b[0] - a[0]) @ axis)
        out.append(replace(leg, beside=(a[0], b_across)))
    return tuple(out)


def pushed_against_walk(
    guides: Sequence[GuidePoint], legs: Sequence[Leg], walks: Sequence[LegWalk], axis: np.ndarray
) -> list[int]:
    """The guide points (0-based) that pushed a wall clearly (``WALL_FORCE_CLEAR_N`` across
    the axis, as the side's vote counts a push) where the walk passes them with its wall the
    other way: the walk follows another wall than the one the person pressed there."""
    out = []
    for k, near in enumerate(walk_beside(guides, legs, walks, axis)):
        f = -np.asarray(guides[k].force_N, dtype=float)  # towards the wall that pushed
        f -= axis * float(f @ axis)
        if near is not None and np.linalg.norm(f) >= th.WALL_FORCE_CLEAR_N and f @ near[1] < 0:
            out.append(k)
    return out


def met_order(
    places_m: Sequence[np.ndarray], path_m: np.ndarray, axis: np.ndarray, closed: bool
) -> list[int] | None:
    """The guide points (1-based) in the order the program's points ``path_m`` meet their
    places ``places_m`` (each point's wall point, else the point), across the axis, when that
    is not the order taught, else None: a loop that went round another wall, or the other way,
    meets its points out of order and can still pass every wall point it reads off its own
    walk. Each point is met at the program's point nearest its place across the axis (places
    farther than twice ``AT_WALL_GAP_M`` are left out: a wall point, not the point, so that a
    point inside a narrow bay is met on its own wall's pass); on a loop the
    steps from each point to the next add up to one lap when in order; a step back of up to
    ``NEAR_END_M`` is a point met in place (two points at one station)."""
    if len(path_m) < 2:
        return None
    across = path_m - np.outer(path_m @ axis, axis)
    along = arc_length_m(across)
    length = float(along[-1])
    met: list[tuple[int, float]] = []
    for k, place in enumerate(places_m):
        p = place - axis * float(place @ axis)
        d = np.linalg.norm(across - p, axis=1)
        j = int(np.argmin(d))
        if d[j] <= 2 * th.AT_WALL_GAP_M:
            met.append((k + 1, float(along[j])))
    if len(met) < 3 or length <= 0.0:
        return None
    s = np.array([v for _, v in met])
    tol = th.NEAR_END_M
    if closed:
        steps = (np.roll(s, -1) - s + tol) % length - tol
        in_order = round(float(steps.sum()) / length) <= 1
        start = s[0]
        seen = sorted(met, key=lambda m: (m[1] - start + tol) % length)
    else:
        in_order = bool(np.all(np.diff(s) >= -tol))
        seen = sorted(met, key=lambda m: m[1])
    return None if in_order else [k for k, _ in seen]


def walk_travel(
    guides: Sequence[GuidePoint],
    legs: Sequence[Leg],
    walks: Sequence[LegWalk],
    axis: np.ndarray,
    sign: float,
) -> np.ndarray:
    """(n, 3) the way the walk travels past each guide point (``walk_beside``): along the
    wall there, on the route's side; zero where the walk does not pass it."""
    out = np.zeros((len(guides), 3))
    for k, near in enumerate(walk_beside(guides, legs, walks, axis)):
        if near is not None:
            out[k] = sign * cross3(near[1], axis)
    return out


def cross3(u: np.ndarray, v: np.ndarray) -> np.ndarray:
    """u x v for (3,) vectors, without numpy's dispatch (the walk's step)."""
    return np.array(
        [u[1] * v[2] - u[2] * v[1], u[2] * v[0] - u[0] * v[2], u[0] * v[1] - u[1] * v[0]]
    )


def open_wall_return(walks: Sequence[LegWalk], legs: Sequence[Leg], radius_m: float) -> str:
    """A sentence when a leg's walk comes back along the other wall of the free space an
    earlier stretch went along, for ``OPEN_RETURN_M`` or more strictly inside the leg (no
    guide point there): an open wall (a slot) taught as a loop. "" when none does."""
    from scipy.spatial import cKDTree

    reach = 2 * radius_m + 2 * th.AT_WALL_GAP_M
    for k, walk in enumerate(walks):
        earlier = [j for j, w in enumerate(walks) if j != k and len(w.points_m)]
        if not earlier or len(walk.points_m) < 3:
            continue
        other = np.vstack([walks[j].points_m for j in earlier])
        other_w = np.vstack([walks[j].towards_m for j in earlier])
        pts, towards = walk.points_m, walk.towards_m
        opposite = np.zeros(len(pts), dtype=bool)
        for i, near in enumerate(cKDTree(other).query_ball_point(pts, reach)):
            if near:
                near = np.asarray(near)
                rel = other[near] - pts[i]
                # the other wall of the same free space: facing this one, free space between
                facing = other_w[near] @ towards[i] < -0.5
                opposite[i] = bool(np.any((rel @ towards[i] < 0) & facing))
        if not opposite.any():
            continue
        idx = np.flatnonzero(opposite)
        runs = np.split(idx, np.flatnonzero(np.diff(idx) > 1) + 1)
        for run in runs:
            if run[0] == 0 or run[-1] == len(pts) - 1:
                continue  # the stretch holds a guide point of the leg: taught there
            length = len(run) * th.WALK_STEP_M
            if length >= th.OPEN_RETURN_M:
                leg = legs[k]
                return (
                    f"the leg G{leg.first + 1} -> G{leg.last + 1} would come back along the "
                    f"other wall of the same groove or slot for {length * 1e3:.0f} mm, where no "
                    "point was taught: the wall is open. Learn it open (--open, or untick "
                    "'closed'), or teach points on that wall too"
                )
    return ""


def unreached_sentence(
    walks: Sequence[LegWalk], legs: Sequence[Leg], side: str, closed: bool
) -> str:
    """The sentence for a walk that could not follow the wall to the end of a leg: the run
    would leave the taught wall or stop there."""
    leg = legs[len(walks) - 1]
    walk = walks[-1]
    a, b = leg.first + 1, leg.last + 1
    if math.isinf(walk.wander_m):
        how = f"loses the wall {walk.length_m * 1e3:.0f} mm after G{a}"
    else:
        how = (
            f"runs {walk.length_m * 1e3:.0f} mm without coming back to G{b} "
            f"({leg.length * 1e3:.0f} mm away)"
        )
    closing = closed and leg is legs[-1]
    fix = "the wall may be open: learn it open (--open, or untick 'closed'), or " if closing else ""
    return (
        f"the wall on the {side} of the leg G{a} -> G{b} does not lead to G{b}: followed in the "
        f"part's mesh it {how}. G{b} may be on another wall or on the other side; {fix}"
        f"put G{b} beside the wall G{a} is on, or check the wall side"
    )
