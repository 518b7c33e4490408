"""Where the tool stands beside the wall, and the points a leg between two of them needs: the
planner's (``pointing``) and the example operator's placing of guide points.

PROBLEM   A guide point stands its gap off the wall on the free side, centred where the free
          space is narrower; a leg between two points must keep the cutter off the wall, and
          not wander far from it, or path learning's route leaves the wall (chapter section
          3.2, docs/guide_points.md).
STRATEGY  ``WallPlacer`` places the tool at an arc length (the gap off the nearest wall, on the
          arc round a sharp outside corner's tip). ``_leg_problem`` finds where a leg needs a
          point of its own; ``_add_points`` adds one there (``_split``: where both halves can
          still be bracketed), each new leg checked again, up to ``MAX_ADDED_POINTS``.
SOLUTION  ``WallPlacer(wall, everything, radius_m, gap_m)(s)`` -> (place, note);
          ``_add_points(...)``; ``_leg_problem(...)``.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from typing import Literal

import numpy as np
import shapely
import shapely.ops

from ..learning.thresholds import (
    CUTTER_FIT_M,
    LEG_CLEARANCE_M,
    MAX_ADDED_POINTS,
    MAX_LEG_GAP_M,
    MIN_SPACING_M,
)
from ..learning.walls import WallLoop

TURN_WINDOW_M = 5e-4  # the wall's direction is measured over this much of it
ROOM_STEPS = 3  # an added point may move this many windows off the worst place to find room
ROOM_SAMPLES = 32  # a split that leaves a dead end: this many places tried along the leg
CHORD_SAMPLE_M = 2.5e-4  # a leg's chord is checked every this much
WALL_SAMPLE_M = 5e-4  # the wall beside a leg is checked every this much

PointKind = Literal["run", "outside corner", "wall end", "added", "taught"]


class WallPlacer:
    """Where the tool stands beside the wall at an arc length (gap off it, on the free side,
    centred where the free space is narrower than the cutter and two gaps)."""

    def __init__(
        self, wall: WallLoop, everything: Sequence[WallLoop], radius_m: float, gap_m: float
    ) -> None:
        self.wall, self.radius, self.gap = wall, radius_m, gap_m
        self._placed: dict[float, tuple[np.ndarray, str]] = {}
        self._all = shapely.MultiLineString(
            [
                np.vstack([lp.points_m, lp.points_m[:1]]) if lp.closed else lp.points_m
                for lp in everything
            ]  # fmt: skip
        )

    def __call__(self, s: float) -> tuple[np.ndarray, str]:
        if s not in self._placed:
            self._placed[s] = self._place(s)
        return self._placed[s]

    def _place(self, s: float) -> tuple[np.ndarray, str]:
        foot = self.wall.point_at(np.array([s]))[0]
        n = self.wall.free_normal_at(np.array([s]))[0]
        reach = 3.0 * (self.radius + self.gap) + 0.01
        ray = shapely.LineString([foot + n * 2e-5, foot + n * reach])
        hit = ray.intersection(self._all)
        width = reach
        if not hit.is_empty:
            width = float(shapely.distance(shapely.Point(foot), hit))
        offset = self.radius + self.gap
        note = ""
        if width < 2 * offset:
            offset = 0.5 * width
            note = f"the free space is {width * 1e3:.1f} mm wide here: the tool is centred in it"
        if width < 2 * self.radius + CUTTER_FIT_M:
            note = (
                f"the free space is {width * 1e3:.1f} mm wide here, too narrow for the "
                f"{2 * self.radius * 1e3:g} mm cutter"
            )
        place = foot + n * offset
        if not note:
            # the gap off the nearest wall, not off the foot: round a sharp outside corner the
            # normal turns over the wall's normal window either side of the tip, and the places
            # there stood nearer the wall than the gap; they stand on the arc round the tip
            tip = shapely.ops.nearest_points(self._all, shapely.Point(place))[0]
            nearest = np.array(tip.coords[0])
            away = place - nearest
            size = float(np.linalg.norm(away))
            if size > 1e-9:
                place = nearest + away * (offset / size)
        return place, note


def _leg_problem(
    wall: WallLoop,
    radius_m: float,
    pa: np.ndarray,
    pb: np.ndarray,
    sa: float,
    sb: float,
    clearance_m: float = LEG_CLEARANCE_M,
) -> float | None:
    """Arc length where the leg pa -> pb needs a point of its own (its cutter comes within
    ``clearance_m`` of the material, or the wall between sa and sb recedes too far from it),
    or None. The clearance asked is at most half the gap the leg's own points keep: points
    left 0.2 mm off the wall (a 4 mm cutter in a 5 mm groove) would fail any larger one along
    a straight wall, and every point added would too."""
    length = float(np.linalg.norm(pb - pa))
    n = max(2, int(math.ceil(length / CHORD_SAMPLE_M)))
    chord = pa + np.linspace(0.0, 1.0, n)[:, None] * (pb - pa)
    signed = wall.signed_distance(chord)
    own_gap = min(float(signed[0]), float(signed[-1])) - radius_m
    clearance_m = min(clearance_m, 0.5 * max(own_gap, 0.0))
    worst = int(np.argmin(signed))
    if signed[worst] < radius_m + clearance_m:
        return float(wall.project(chord[worst : worst + 1])[0])
    if sb <= sa:
        sb += wall.length_m
    m = max(2, int(math.ceil((sb - sa) / WALL_SAMPLE_M)))
    s = np.linspace(sa, sb, m)
    pts = wall.point_at(s)
    d = pb - pa
    u = np.clip(((pts - pa) @ d) / max(d @ d, 1e-18), 0.0, 1.0)
    gap = np.linalg.norm(pts - (pa + u[:, None] * d), axis=1)
    k = int(np.argmax(gap))
    if gap[k] > MAX_LEG_GAP_M:
        return float(s[k])
    return None


def _split(
    wall: WallLoop,
    place: WallPlacer,
    radius_m: float,
    sa: float,
    span: float,
    pa: np.ndarray,
    pb: np.ndarray,
    worst: float | None,
) -> float | None:
    """Where a point splits the leg from ``sa`` (``span`` of wall): the worst place ``worst``
    (None: no room there) unless a half it leaves would still need a point and is too short
    to take one (under ``2 * MIN_SPACING_M``: a dead end); then the place of ``ROOM_SAMPLES``
    tried along the leg, with ``MIN_SPACING_M`` of room, that leaves no dead end and keeps the
    cutter farthest off the wall. Round a tight outside corner beside a narrow groove the worst
    place put the point 2 mm from the corner's, and the half between them cut under the
    cutter with no room for another point."""
    sb = sa + span

    def judged(offset: float) -> tuple[bool, float]:
        sc = sa + offset
        pc = place(float(wall.wrap(np.array([sc]))[0]))[0]
        if min(float(np.linalg.norm(pc - pa)), float(np.linalg.norm(pc - pb))) < MIN_SPACING_M:
            return False, -math.inf
        for p0, p1, s0, s1 in ((pa, pc, sa, sc), (pc, pb, sc, sb)):
            short = float(np.linalg.norm(p1 - p0)) < 2 * MIN_SPACING_M
            if short and _leg_problem(wall, radius_m, p0, p1, s0, s1) is not None:
                return False, -math.inf
        chords = [
            p0 + np.linspace(0.0, 1.0, 16)[:, None] * (p1 - p0) for p0, p1 in ((pa, pc), (pc, pb))
        ]
        return True, float(wall.signed_distance(np.vstack(chords)).min())

    if worst is not None and judged(worst)[0]:
        return worst
    best, best_clear = worst, -math.inf
    for offset in np.linspace(0.0, span, ROOM_SAMPLES + 2)[1:-1]:
        ok, clear = judged(float(offset))
        if ok and clear > best_clear:
            best, best_clear = float(offset), clear
    return best


def _add_points(
    wall: WallLoop,
    closed: bool,
    points: list[tuple[float, PointKind]],
    place: WallPlacer,
    radius_m: float,
) -> tuple[list[tuple[float, PointKind]], list[str]]:
    """Points added where a leg comes near the wall or leaves it too far (module docstring).
    A leg is checked once; an added point puts its two new legs on the list."""
    notes: list[str] = []
    points = list(points)
    todo = list(range(len(points) if closed else len(points) - 1))  # leg k: point k -> k + 1
    added = 0
    while todo and added < MAX_ADDED_POINTS:
        k = todo.pop()
        j = (k + 1) % len(points)
        (sa, _), (sb, _) = points[k], points[j]
        pa, pb = place(sa)[0], place(sb)[0]
        at = _leg_problem(wall, radius_m, pa, pb, sa, sb)
        if at is None:
            continue
        L = wall.length_m
        span = (sb - sa) % L if closed else sb - sa
        offset = float(np.clip((at - sa) % L if closed else at - sa, 0.0, span))
        offset = 0.0 if closed and (at - sa) % L > 0.5 * (span + L) else offset  # just before sa
        # Room is counted between the tool's places, not the wall's feet (round an outside
        # corner they stand farther apart); at a corner's tip, the place just past it, where
        # the wall's own side gives the direction, brackets it.
        for step in range(ROOM_STEPS + 1):
            shift = step * TURN_WINDOW_M * (1.0 if offset < 0.5 * span else -1.0)
            pc = place(float(wall.wrap(np.array([sa + offset + shift]))[0]))[0]
            if (
                0.0 < offset + shift < span
                and min(np.linalg.norm(pc - pa), np.linalg.norm(pc - pb)) >= MIN_SPACING_M
            ):
                break
        else:
            shift = math.nan  # no room by the worst place
        worst = _split(
            wall, place, radius_m, sa, span, pa, pb, None if math.isnan(shift) else offset + shift
        )
        if worst is None:
            continue  # no room: ``leg_problems`` says so if the leg cuts into the wall
        at = float(wall.wrap(np.array([sa + worst]))[0]) if closed else sa + worst
        points.insert(k + 1, (at, "added"))
        added += 1
        todo = [t + 1 if t > k else t for t in todo] + [k, k + 1]
    if todo:
        notes.append(f"stopped adding points after {MAX_ADDED_POINTS}")
    if closed:  # the points stay in order along the wall, from the first
        points.sort(key=lambda item: item[0])
    return points, notes
