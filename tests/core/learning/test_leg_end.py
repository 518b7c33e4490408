"""Where a closed route's last leg ends (``walk.LegEnd``): past its start, not at the first
step away from it. At slow feeds the wall's direction wiggles, so the distance to the start
does not fall monotonically; a loop that ended at its first rise stopped 1.7 mm short of its
start and left a 0.46 mm ridge (a good program condemned, issue 28). Properties over generated
approaches, a fresh seed each run (``ROBOMACH_SEED`` replays it)."""

from __future__ import annotations

import numpy as np

from robomach_core.learning import thresholds as th
from robomach_core.learning.route import Leg
from robomach_core.learning.walk import LegEnd
from tests.envelope import replay, run_seed

SEED = run_seed()
AXIS = np.array([0.0, 0.0, -1.0])


def _closing_leg(length_m: float) -> Leg:
    a, b = np.array([0.0, 0.0, 0.0]), np.array([length_m, 0.0, 0.0])
    return Leg(a, b, length_m, np.array([1.0, 0.0, 0.0]), np.eye(3), np.zeros(3), 3, 0)


def test_a_loop_ends_past_its_start_through_the_walls_wiggles():
    rng = np.random.default_rng(SEED)
    for case in range(200):
        radius = float(rng.uniform(0.001, 0.006))
        length = float(rng.uniform(0.02, 0.2))
        end = LegEnd(_closing_leg(length), AXIS, last=True, closed=True, tool_radius_m=radius)
        start = np.array([length + rng.uniform(-0.002, 0.002), rng.uniform(-0.5, 0.5) * radius, 0])
        step = float(rng.uniform(2e-5, 2e-4))  # 0.5-20 mm/s at 4 ms, and the walk's steps
        wiggle = float(rng.uniform(0.0, 0.4)) * th.CLOSE_PASSED_M  # across the travel
        s = 0.5 * length
        ended_at = None
        while s < length + th.CLOSE_LOOP_OVERRUN_M:
            p = np.array([s, start[1] + wiggle * np.sin(s / 3e-4), 0.0])
            if end.reached(p, s, start):
                ended_at = s
                break
            s += step
        where = (
            f"{replay(SEED)}, case {case}: radius {radius * 1e3:.2f} mm, step {step * 1e6:.0f} um"
        )
        assert ended_at is not None, f"{where}: the loop never closed"
        assert ended_at >= start[0], (
            f"{where}: the loop ended {(start[0] - ended_at) * 1e3:.2f} mm short of its start"
        )
        # receding CLOSE_PASSED_M from a nearest approach b across the travel takes this much
        b = abs(float(start[1]))
        beyond = np.sqrt((b + th.CLOSE_PASSED_M + 2 * wiggle) ** 2 - max(b - wiggle, 0.0) ** 2)
        # + a step for where the sampled nearest approach falls, and one for seeing it recede
        assert ended_at <= start[0] + beyond + 2 * step, (
            f"{where}: the loop ran {(ended_at - start[0]) * 1e3:.2f} mm past its start"
        )


def test_a_leg_across_the_wall_ends_as_the_tool_passes_its_point():
    """Two points at one station of the wall, one on it and one a gap off it: the leg's chord
    runs across the wall, so the tool following the wall makes no progress along it (a little
    backwards, even). The leg ends as the tool passes its end point's station, within
    ``NEAR_END_M`` of it (where the distance to the point has grown ``END_PASSED_M`` past its
    least); it ran past the next points, round a slot's end and back
    along the other wall before (issue 28, a wrong program that passed)."""
    rng = np.random.default_rng(SEED + 1)
    for case in range(200):
        # the off point's distance: up to the farthest a point is left (half ``NEAR_END_M``)
        gap = float(rng.uniform(0.0005, 0.5 * th.NEAR_END_M))
        lean = float(rng.uniform(-0.3, 0.3)) * gap  # ... and how far along the wall it stands
        a, b = np.zeros(3), np.array([lean, gap, 0.0])
        length = float(np.hypot(lean, gap))
        leg = Leg(a, b, length, b / length, np.eye(3), np.zeros(3), 7, 8)
        end = LegEnd(leg, AXIS, last=bool(rng.random() < 0.5), closed=False, tool_radius_m=1e-3)
        y = float(rng.uniform(-0.3e-3, 0.1e-3))  # the tool's centre on the wall, by point a
        step = float(rng.uniform(2e-5, 2e-4))
        x = -float(rng.uniform(0.5e-3, 2e-3))  # where the previous leg handed over
        ended_at = None
        while x < 0.05:
            p = np.array([x, y, 0.0])
            s = float((p - a) @ leg.xp)
            if s >= end.watch_from_m and end.reached(p, s, None):
                ended_at = x
                break
            x += step
        where = f"{replay(SEED)}, case {case}: gap {gap * 1e3:.2f} mm, lean {lean * 1e3:.2f} mm"
        assert ended_at is not None, f"{where}: the leg never ended"
        # the nearest approach |gap - y|, then receding END_PASSED_M: under NEAR_END_M on
        assert ended_at - lean <= th.NEAR_END_M, (
            f"{where}: ended {(ended_at - lean) * 1e3:.2f} mm past the point's station"
        )


def test_a_leg_ends_at_its_point_not_where_a_detour_crosses_its_plane():
    """A sparse leg round an outside wall (a T-boss's bar, a block's end) whose chord cuts
    through the part: the wall crosses the end point's plane far from the point first, on the
    far side of the part, and only later comes back past the point. The leg ends by the point
    (within ``PLANE_END_WITHIN_M`` + the radius of it), not at the first crossing; it ended
    there before, the next leg started on the wrong face and a good set was refused, "the wall
    ... does not lead to G4" (issue 28). A crossing near the point still ends it."""
    rng = np.random.default_rng(SEED + 2)
    for case in range(200):
        radius = float(rng.uniform(0.0005, 0.005))
        length = float(rng.uniform(0.02, 0.2))
        leg = _closing_leg(length)
        end = LegEnd(leg, AXIS, last=False, closed=True, tool_radius_m=radius)
        # the detour: along y = off past the plane, far from the point, then back down to it
        off = radius + th.PLANE_END_WITHIN_M + float(rng.uniform(0.001, 0.05))
        gap = radius + float(rng.uniform(0.0, th.AT_WALL_GAP_M))  # the wall by the point
        past = length + float(rng.uniform(0.003, 0.02))
        step = float(rng.uniform(2e-5, 2e-4))
        path = [np.array([x, off, 0.0]) for x in np.arange(0.5 * length, past, step)]
        path += [np.array([past, y, 0.0]) for y in np.arange(off, gap, -step)]
        path += [np.array([x, gap, 0.0]) for x in np.arange(past, 0.5 * length, -step)]
        ended = next((p for p in path if end.reached(p, float(p @ leg.xp), None)), None)
        where = (
            f"{replay(SEED)}, case {case}: detour {off * 1e3:.1f} mm off, wall {gap * 1e3:.1f} mm"
        )
        assert ended is not None, f"{where}: the leg never ended"
        within = radius + th.PLANE_END_WITHIN_M + step
        assert float(np.hypot(ended[0] - length, ended[1])) <= within, (
            f"{where}: ended {float(np.hypot(ended[0] - length, ended[1])) * 1e3:.1f} mm off "
            f"the point (at {np.round(ended * 1e3, 1)} mm)"
        )
